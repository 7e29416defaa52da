"""NUTS in seconds (issue 18 §2): wall time per fit of M1, M2 and M4 (hierarchical) with
the shared runner (calib/nuts.py: nutpie on the compiled model, compiled entry points
cached), warm — after one fit of the same model and data in this run, which fills the
cache — idle and with two busy loops; compile and sampling seconds apart (from the
fit's sample_stats attrs), with the diagnostics of the same fit.

Goals, as wall seconds per fit: M1 and M2 ≤ 10 s, M4 hierarchical ≤ 20 s; recorded as
median(wall) / goal (≤ 1), with the spread of the fits. A fit takes seconds to tens of
seconds, so ``make bench`` times them idle only (two warm fits each); ``make bench-load``
times them with the whole run under two busy loops.
"""
import tempfile
import time
import warnings

import numpy as np
import pytest

from _ratios import LOADS, Timed, busy_loops, record_median_ratio

GOALS_S = {"M1": 10.0, "M2": 10.0, "M4 hierarchical": 20.0}
ROUNDS = 2


def _m1():
    from feeler.calib.matrix import CalibrationData, MatrixPrior, fit_matrix
    from feeler.scene import load_scene
    from feeler.simulate.calibration import draw_campaign

    scene = load_scene("datasets-synthetic/sensor-calibration.toml")
    prior = MatrixPrior(c0_mm_per_n=scene.prior.c0_mm_per_n, rel_sd=scene.prior.rel_sd,
                        sigma_f_scale_n=scene.prior.sigma_f_scale_n)
    u, _, f = draw_campaign(scene, np.random.default_rng(scene.scene.seed))
    data = CalibrationData(u, f, np.arange(len(u)))
    return lambda: fit_matrix(data, prior, backend="nuts", rng=np.random.default_rng(7))


def _m2():
    from feeler.calib.neuron import fit_neuron
    from feeler.calib.neuron.synth import scene_scans

    data = scene_scans()[2]
    return lambda: fit_neuron(data, backend="nuts", seed=1)


def _m4():
    from feeler.calib.psychometric.fit import fit_psychometric
    from feeler.psydata import read_trials
    from feeler.scene import load_scene
    from feeler.simulate.psychophysics import simulate_psychophysics

    with tempfile.TemporaryDirectory() as tmp:
        trials = read_trials(simulate_psychophysics(load_scene("datasets-synthetic/psychophysics-2afc.toml"),
                                                    tmp)["trials"])
    return lambda: fit_psychometric(trials, rng=np.random.default_rng(0), backend="nuts")


@pytest.mark.parametrize("model, make", [("M1", _m1), ("M2", _m2), ("M4 hierarchical", _m4)])
def test_nuts_wall_time(benchmark, model, make):
    fit = make()

    def quiet():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return fit()

    res = benchmark.pedantic(quiet, rounds=1, iterations=1)      # first fit: fills the compiled-model cache
    first = dict(res.posterior["sample_stats"].attrs)
    benchmark.extra_info.update({"first fit: compile s": first.get("compile_seconds"),
                                 "first fit: compile cache": first.get("compile_cache"),
                                 "sampler": first.get("sampler")})
    s = res.summary
    benchmark.extra_info.update({"verdict_ok": res.verdict.ok, "max_r_hat": float(s["r_hat"].max()),
                                 "min_ess_bulk": float(s["ess_bulk"].min()),
                                 "divergences": int(np.asarray(res.posterior["sample_stats"]["diverging"]).sum())})
    for load, n in list(LOADS.items())[:1]:
        wall, comp, samp = [], [], []
        with busy_loops(n):
            for _ in range(ROUNDS):
                t0 = time.perf_counter()
                r = quiet()
                wall.append(time.perf_counter() - t0)
                attrs = r.posterior["sample_stats"].attrs
                comp.append(attrs["compile_seconds"])
                samp.append(attrs["sampling_seconds"])
        record_median_ratio(benchmark, "wall s / goal s", Timed(call=np.asarray(wall), base=np.array([GOALS_S[model]])),
                            "<= 1", load=load, invert=True)
        benchmark.extra_info.update({f"[{load}] wall s: median": float(np.median(wall)),
                                     f"[{load}] compile s: median": float(np.median(comp)),
                                     f"[{load}] sampling s: median": float(np.median(samp))})
        print(f"\n{model} [{load}]: wall {np.median(wall):.1f} s (compile {np.median(comp):.1f} s, "
              f"sampling {np.median(samp):.1f} s) over {ROUNDS} warm fits; first fit compile "
              f"{first.get('compile_seconds', float('nan')):.1f} s (cache {first.get('compile_cache')}); "
              f"verdict ok={res.verdict.ok}, max R-hat {s['r_hat'].max():.4f}, min bulk ESS {s['ess_bulk'].min():.0f}")
