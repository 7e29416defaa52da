"""Speed/accuracy trades measured during the demo (small versions of ``make bench``).

Every demo report shows the trades. What ``make bench`` measured is copied into
``OUT/benchmarks/``; whatever it did not measure, the demo measures now, small and
labelled so:

- ``OUT/skin-ladder/``: the skin ladder on the two coarsest meshes of ``feeler skin ladder
  --small`` (L2 on the finer one is the reference): seconds per slide and peak strain-rate
  error of L2, L1 and L0 (always: the benchmarks time the ladder but not its error);
- ``OUT/speed/backends.csv``: M1 on the demo's sensor calibration data, exact and emcee,
  against the exact posterior with many draws (unless ``benchmarks/m1.csv`` exists);
- ``OUT/speed/fidelity.csv``: M1 on the sensor-calibration scene simulated at the
  displacement, areas and images fidelities, error against the true C (unless
  ``benchmarks/fidelity.csv`` exists);
- ``OUT/speed/decoder.csv``: the live decoder's decision latency against accuracy over
  thresholds on the held-out scans (unless ``benchmarks/decoder.csv`` exists);
- ``OUT/speed/speed.json``: when and how these were measured.

Seconds are wall time on the machine running the demo.
"""
from __future__ import annotations

import csv
import datetime as _dt
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from feeler.rundir import write_json

__all__ = ["measure_trades", "EMCEE_DRAWS", "REFERENCE_DRAWS"]

EMCEE_DRAWS, EMCEE_TUNE = 400, 200
REFERENCE_DRAWS = 5_000          # per chain: the reference's own Monte Carlo error is < 0.01 sd
FIDELITIES = ("displacement", "areas", "images")
_C = [f"C[{i},{j}]" for i in range(3) for j in range(3)]


def _write(path: Path, columns, rows) -> None:
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(columns)
        w.writerows(rows)


def _prior(scene):
    from feeler.calib.matrix import MatrixPrior

    return MatrixPrior(c0_mm_per_n=scene.prior.c0_mm_per_n, rel_sd=scene.prior.rel_sd,
                       sigma_f_scale_n=scene.prior.sigma_f_scale_n)


def _fit(data, prior, backend, seed=7, **kw):
    from feeler.calib.matrix import fit_matrix

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fit_matrix(data, prior, backend=backend, rng=np.random.default_rng(seed), progress=False, **kw)


def _backends(cal_dir: Path, path: Path) -> str:
    from feeler.calib.matrix import read_calibration_csv
    from feeler.scene import load_scene

    data, prior = read_calibration_csv(cal_dir / "calibration.csv"), _prior(load_scene(cal_dir / "scene.toml"))
    ref = _fit(data, prior, "exact", seed=99, draws=REFERENCE_DRAWS).summary.set_index("name").loc[_C]
    rows = []
    for label, backend, kw in (("exact, 4 x 1000 draws", "exact", {}),
                               (f"emcee, {EMCEE_DRAWS} draws after {EMCEE_TUNE}", "emcee",
                                {"draws": EMCEE_DRAWS, "tune": EMCEE_TUNE})):
        t0 = time.perf_counter()
        res = _fit(data, prior, backend, **kw)
        wall = time.perf_counter() - t0
        s = res.summary.set_index("name").loc[_C]
        err = ((s["mean"] - ref["mean"]).abs() / ref["sd"]).max()
        sd_err = (s["sd"] / ref["sd"] - 1).abs().max()
        rows.append((label, f"{wall:.4g}", f"{err:.4g}", f"{sd_err:.4g}", res.verdict.ok))
    _write(path, ("option", "seconds", "error_ref_sd", "sd_error", "ok"), rows)
    return (f"M1 on {cal_dir.name}/: wall seconds of the fit, error_ref_sd = largest |posterior mean − reference| over "
            f"the entries of C in reference sds (reference: exact, 4 x {REFERENCE_DRAWS} draws), sd_error = largest "
            "|sd / reference sd − 1|, ok = the fit's verdict.")


def _fidelity_scene(src: Path, tmp: Path, fidelity: str) -> Path:
    """The sensor-calibration scene at ``fidelity`` (same seed), its layout beside it."""
    text = src.read_text(encoding="utf-8")
    if fidelity != "displacement":
        layout = src.parent / "layouts" / "sensor-16.toml"
        (tmp / "layouts").mkdir(exist_ok=True)
        (tmp / "layouts" / "sensor-16.toml").write_bytes(layout.read_bytes())
        text = text.replace("[design]", f'fidelity = "{fidelity}"\n\n[design]', 1)
        text += '\n[optics]\nlayout = "layouts/sensor-16.toml"\n'
    path = tmp / f"{fidelity}.toml"
    path.write_text(text, encoding="utf-8")
    return path


def _fidelity(scene_src: Path, path: Path) -> str:
    from feeler.calib.matrix import read_calibration_csv
    from feeler.scene import load_scene
    from feeler.simulate import run_simulation

    rows = []
    with tempfile.TemporaryDirectory(prefix="feeler-demo-fidelity-") as tmp:
        tmp = Path(tmp)
        for fid in FIDELITIES:
            scene_path = _fidelity_scene(scene_src, tmp, fid)
            t0 = time.perf_counter()
            run = run_simulation(scene_path, tmp / f"run-{fid}", progress=False)     # timed: no output
            sim_s = time.perf_counter() - t0
            scene = load_scene(scene_path)
            t0 = time.perf_counter()
            res = _fit(read_calibration_csv(run / "calibration.csv"), _prior(scene), "exact")
            fit_s = time.perf_counter() - t0
            post = res.posterior["posterior"]["C"]
            err = post.mean(("chain", "draw")).values - np.asarray(scene.sensor.c_mm_per_n)
            err_sd = float((np.abs(err) / post.std(("chain", "draw")).values).max())
            rows.append((fid, f"{sim_s + fit_s:.4g}", f"{sim_s:.4g}", f"{fit_s:.4g}", f"{err_sd:.4g}",
                         f"{np.abs(err).max():.4g}", res.verdict.ok))
    _write(path, ("option", "seconds", "simulate_s", "fit_s", "error_sd", "error_mm_per_n", "ok"), rows)
    return (f"M1 (exact) on {scene_src.name} simulated at each sensor fidelity: seconds = simulate + fit, error_sd = "
            "largest |posterior mean − true C| in posterior sds.")


def measure_trades(out: Path, data_dir: Path, echo=print) -> dict:
    """Measure what the benchmarks in ``out/benchmarks`` do not cover; returns speed.json."""
    from feeler.rundir import prepare_out_dir
    from feeler.skin.study import ladder_files, run_ladder_study

    stamp = _dt.datetime.now().isoformat(timespec="seconds")
    measured = f"during `feeler demo` at {stamp}"
    bench = {p.stem for p in (out / "benchmarks").glob("*.csv")} if (out / "benchmarks").is_dir() else set()
    ladder = prepare_out_dir(out / "skin-ladder", ladder_files(), force=True)
    result = run_ladder_study(ladder, tiny=True, measured=measured)
    echo(f"  skin ladder (two coarse meshes): L1 {result['l1_speedup']:.3g}x and L0 {result['l0_speedup']:.3g}x "
         f"faster per slide than L2, L1 error {100 * result['l1_rate_error']:.2g} %")
    speed = out / "speed"
    speed.mkdir(exist_ok=True)
    tables = {}
    if "m1" not in bench and (out / "sensor-calibration" / "calibration.csv").is_file():
        tables["backends"] = _backends(out / "sensor-calibration", speed / "backends.csv")
        echo("  calibration backends: speed/backends.csv")
    if "fidelity" not in bench:
        tables["fidelity"] = _fidelity(data_dir / "sensor-calibration.toml", speed / "fidelity.csv")
        echo("  sensor fidelities: speed/fidelity.csv")
    if "decoder" not in bench and (out / "m2").is_dir() and (out / "held-out" / "scene.toml").is_file():
        from feeler.calib.neuron.live.trade import demo_table
        tables["decoder"] = demo_table(out / "m2", out / "held-out", speed / "decoder.csv")
        echo("  live decoder latency/accuracy: speed/decoder.csv")
    index = {"measured": measured, "tables": tables,
             "times": "times in wall seconds on this machine, but the live decoder's latency, which is scan time "
                      "since the step"}
    write_json(speed / "speed.json", index)
    return index
