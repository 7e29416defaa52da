"""The robot's psychometric curve for the report (a demo stage after ``discriminate``).

``feeler discriminate`` writes the robot's 75 % threshold and, since it records it, the
curve it reads it from (``curve`` in discrimination.json: P(correct) that reference + Δ
gives the larger peak z, per Δ, with its 95 % band of posterior and simulation error). For
an older output without it, this stage computes it as the command does (its touches, draws
and seed as the file records them, else the command's defaults; the same increments), so
the curve crosses 75 % where the threshold lies, and writes ``discriminate/threshold_curve.csv``.
An outside review found the curve drawn from 400 touches a height beside a threshold from
1000: it crossed 75 % at 4.24 um against the 4.49 um printed on it.
"""
from __future__ import annotations

import json
from pathlib import Path

__all__ = ["write_threshold_curve", "CURVE_FILE"]

CURVE_FILE = "threshold_curve.csv"


def _has_curve(disc_dir: Path) -> bool:
    if (disc_dir / CURVE_FILE).is_file():
        return True
    try:
        obj = json.loads((disc_dir / "discrimination.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(obj, dict) and ("curve" in obj or "threshold_curve" in obj)


def write_threshold_curve(m2_dir: Path, disc_dir: Path, *, n_scans: int | None = None, n_draws: int | None = None,
                          seed: int = 0) -> Path | None:
    """Write ``disc_dir/threshold_curve.csv`` (delta_mm, pc, lo95, hi95:
    :meth:`~feeler.calib.neuron.discriminate.Threshold.curve_of`) unless the discrimination
    output already has its curve; returns the path written or None. ``n_scans``/``n_draws``:
    as the output records them unless given."""
    from feeler.calib.fit import load
    from feeler.calib.neuron.discriminate import Discriminator

    if _has_curve(disc_dir):
        return None
    obj = json.loads((disc_dir / "discrimination.json").read_text(encoding="utf-8"))
    reference = float(obj.get("reference_mm", 0.1))
    n_scans = int(n_scans or obj.get("n_scans") or 1000)
    n_draws = int(n_draws or obj.get("n_draws") or 200)
    curve = Discriminator(load(m2_dir), n_scans=n_scans, n_draws=n_draws, seed=seed).threshold(reference).curve
    path = disc_dir / CURVE_FILE
    header = (f"# the robot's 2AFC curve around {reference:g} mm, from {m2_dir.name}/ as feeler discriminate reads "
              f"its threshold (seed {seed}, {n_scans} touches per height, {n_draws} posterior draws; pc the mean over "
              f"draws, lo95/hi95 the 2.5/97.5 % quantiles of its resampled values), written by feeler demo\n"
              "delta_mm,pc,lo95,hi95\n")
    rows = zip(curve["delta_mm"], curve["pc"], curve["lo95"], curve["hi95"])
    path.write_text(header + "".join(f"{d:.6g},{p:.6g},{lo:.6g},{hi:.6g}\n" for d, p, lo, hi in rows),
                    encoding="utf-8")
    return path
