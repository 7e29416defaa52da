"""Sensor fidelity in the speed/accuracy table (issue 4 §5): M1 and M2 fitted on datasets
simulated at the ``displacement``, ``areas`` and ``images`` levels.

- M1 (sensor-calibration, exact backend): wall time of simulation and fit, and the error of
  the posterior mean of C against the true C (max |error| in mm/N and in posterior sds).
- M2 (four-plates, all 96 scans, grid backend): wall times, and the error of the posterior
  means of (a, τ, h, σ) against the displacement-fidelity fit (in that fit's sds). The
  optical levels carry less read-out noise than the scene's 2 µm displacement noise, so σ
  (and through it the other parameters) differ by design; the table says by how much.

Ratios are to the displacement-fidelity row measured in the same run; the table is
printed at the end. Fit times are medians with their spread (``_ratios``) over repeated
fits after the benchmark's own (the first fit of a process also pays imports and compiles),
idle and with two busy loops; a simulation runs once per fidelity (seconds each), so
its ratio is of single runs.
"""
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

from _ratios import LOADS, Timed, busy_loops, record_median_ratio, record_ratio, seconds_of
from feeler.calib.matrix import MatrixPrior, fit_matrix, read_calibration_csv
from feeler.calib.neuron import data_from_scans, fit_neuron
from feeler.datasets import read_scans
from feeler.scene import load_scene
from feeler.simulate import run_simulation

SHIPPED = Path("datasets-synthetic")
FIDELITIES = ("displacement", "areas", "images")
M2_NAMES = ["a", "tau_s", "h", "sigma_mm"]
ROWS: dict[tuple[str, str], dict] = {}


def _scene(tmp: Path, kind: str, fidelity: str) -> Path:
    """The shipped scene at ``fidelity`` (same seed, same touches), in ``tmp`` beside the layouts."""
    src = SHIPPED / ("sensor-calibration.toml" if kind == "M1" else "four-plates.toml")
    text = src.read_text()
    if fidelity != "displacement":
        text = (text.replace("[design]", f'fidelity = "{fidelity}"\n\n[design]') if kind == "M1"
                else text.replace('fidelity = "displacement"', f'fidelity = "{fidelity}"'))
        text += '\n[optics]\nlayout = "layouts/sensor-16.toml"\n'
    (tmp / "layouts").mkdir(exist_ok=True)
    (tmp / "layouts" / "sensor-16.toml").write_bytes((SHIPPED / "layouts" / "sensor-16.toml").read_bytes())
    path = tmp / f"{kind}-{fidelity}.toml"
    path.write_text(text)
    return path


def _simulate(tmp: Path, kind: str, fidelity: str) -> tuple[Path, float]:
    scene = _scene(tmp, kind, fidelity)
    t0 = time.perf_counter()
    out = run_simulation(scene, tmp / f"run-{kind}-{fidelity}")
    return out, time.perf_counter() - t0


@pytest.mark.parametrize("fidelity", FIDELITIES)
def test_m1_on_fidelity(benchmark, tmp_path, fidelity):
    run, sim_s = _simulate(tmp_path, "M1", fidelity)
    scene = load_scene(run / "scene.toml")
    prior = MatrixPrior(c0_mm_per_n=scene.prior.c0_mm_per_n, rel_sd=scene.prior.rel_sd,
                        sigma_f_scale_n=scene.prior.sigma_f_scale_n)
    data = read_calibration_csv(run / "calibration.csv")

    def fit():
        return fit_matrix(data, prior, backend="exact", rng=np.random.default_rng(7))

    res = benchmark.pedantic(fit, rounds=1, iterations=1)   # also the warm-up of the timed fits
    times = _fit_times(fit, rounds=7)
    post = res.posterior["posterior"]["C"]
    err = post.mean(("chain", "draw")).values - np.asarray(scene.sensor.c_mm_per_n)
    err_sd = np.abs(err) / post.std(("chain", "draw")).values
    _row(benchmark, ("M1", fidelity), simulate_s=sim_s, fit_s=float(np.median(next(iter(times.values())))),
         error=float(np.abs(err).max()), error_sd=float(err_sd.max()), ok=res.verdict.ok, times=times)
    assert np.abs(err).max() < 0.01


@pytest.mark.parametrize("fidelity", FIDELITIES)
def test_m2_on_fidelity(benchmark, tmp_path, fidelity):
    run, sim_s = _simulate(tmp_path, "M2", fidelity)
    data = data_from_scans(read_scans(run), length_mm=3.0)

    def fit():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return fit_neuron(data, backend="grid", seed=7)

    res = benchmark.pedantic(fit, rounds=1, iterations=1)   # also the warm-up of the timed fits
    times = _fit_times(fit, rounds=3)
    s = res.summary.set_index("name").loc[M2_NAMES]
    ref = s if fidelity == "displacement" else ROWS[("M2", "displacement")]["summary"]
    err_sd = ((s["mean"] - ref["mean"]) / ref["sd"]).abs()
    _row(benchmark, ("M2", fidelity), simulate_s=sim_s, fit_s=float(np.median(next(iter(times.values())))),
         error=float(err_sd.max()), error_sd=float(err_sd.max()), ok=res.verdict.ok, summary=s,
         per_param=", ".join(f"{n} {err_sd[n]:.1f}" for n in M2_NAMES), times=times)


def _fit_times(fit, rounds: int) -> dict:
    """Wall times of ``rounds`` fits under each of ``_ratios.LOADS`` (s)."""
    out = {}
    for load, n in LOADS.items():
        with busy_loops(n):
            out[load] = seconds_of(fit, rounds, warmup=0)
    return out


def _row(benchmark, key, **row) -> None:
    ROWS[key] = row
    benchmark.extra_info.update({k: v for k, v in row.items() if k not in ("summary", "per_param", "times")})
    base = ROWS.get((key[0], "displacement"))
    if key[1] != "displacement" and base is not None:
        record_ratio(benchmark, "simulate time / displacement (one run each)", row["simulate_s"] / base["simulate_s"],
                     "informational")
        for load in row["times"]:
            record_median_ratio(benchmark, "fit time / displacement",
                                Timed(call=row["times"][load], base=base["times"][load]), "informational",
                                load=load, invert=True)
        if key[0] == "M1":
            record_ratio(benchmark, "max |C error| / displacement", row["error"] / base["error"], "informational")


def test_print_fidelity_table():
    if len(ROWS) < 2 * len(FIDELITIES):
        pytest.skip("run the whole module to get the table")
    print("\nmodel  fidelity      simulate s  fit s (median, first load)   verdict  error")
    for (model, fid), r in ROWS.items():
        what = (f"max |C mean - C true| {r['error']:.5f} mm/N ({r['error_sd']:.2f} posterior sd)" if model == "M1"
                else f"|mean - displacement fit| in its sds: {r['per_param']}")
        print(f"{model:6s} {fid:13s} {r['simulate_s']:9.2f} {r['fit_s']:7.3f}   {'ok' if r['ok'] else 'FAILED':7s}  {what}")
