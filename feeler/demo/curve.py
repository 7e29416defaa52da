"""The robot's psychometric curve for the report (a demo stage after ``discriminate``).

``feeler discriminate`` writes the robot's 75 % threshold; the report also draws the curve
it comes from: P(correct) that reference + Δ gives the larger peak z, per Δ, with its 95 %
band over the posterior draws. When the discriminate output does not carry the curve,
this stage computes it with the command's defaults (same seed, touches, draws and
reference, 13 points over the range its 26-point grid spans: the same responses, so the
curve crosses 75 % where the command's threshold lies) and writes ``discriminate/threshold_curve.csv``.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

__all__ = ["write_threshold_curve", "CURVE_FILE", "N_POINTS"]

CURVE_FILE = "threshold_curve.csv"
N_POINTS = 13          # over discriminate's search range (0 … Discriminator.search_top_mm; its grid has 26)


def _has_curve(disc_dir: Path) -> bool:
    if (disc_dir / CURVE_FILE).is_file():
        return True
    try:
        obj = json.loads((disc_dir / "discrimination.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(obj, dict) and ("curve" in obj or "threshold_curve" in obj)


def write_threshold_curve(m2_dir: Path, disc_dir: Path, *, n_scans: int = 400, n_draws: int = 200,
                          seed: int = 0, n_points: int = N_POINTS) -> Path | None:
    """Write ``disc_dir/threshold_curve.csv`` (delta_mm, pc, lo95, hi95: the posterior median
    of P(correct) over draws and its 2.5 and 97.5 % quantiles) unless the
    discrimination output already has its curve; returns the path written or None."""
    from feeler.calib.fit import load
    from feeler.calib.neuron.discriminate import Discriminator

    if _has_curve(disc_dir):
        return None
    obj = json.loads((disc_dir / "discrimination.json").read_text(encoding="utf-8"))
    reference = float(obj.get("reference_mm", 0.1))
    disc = Discriminator(load(m2_dir), n_scans=n_scans, n_draws=n_draws, seed=seed)
    deltas = np.linspace(0.0, disc.search_top_mm(reference), n_points)
    ref = disc.responses(reference, reference=True)
    rows = []
    for d in deltas:
        pc = disc.proportion_correct(ref, disc.responses(reference + d))
        lo, mid, hi = np.quantile(pc, [0.025, 0.5, 0.975])
        rows.append((d, mid, lo, hi))          # the median: inside its band even where most draws give 1
    path = disc_dir / CURVE_FILE
    header = (f"# the robot's 2AFC curve around {reference:g} mm, from {m2_dir.name}/ with feeler discriminate's "
              f"defaults (seed {seed}, {n_scans} touches per height, {n_draws} posterior draws; pc the median over "
              f"draws, lo95/hi95 its 2.5/97.5 % quantiles), written by feeler demo\n"
              "delta_mm,pc,lo95,hi95\n")
    path.write_text(header + "".join(f"{d:.6g},{p:.6g},{lo:.6g},{hi:.6g}\n" for d, p, lo, hi in rows),
                    encoding="utf-8")
    return path
