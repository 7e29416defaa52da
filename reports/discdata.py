"""The robot's discrimination (``feeler discriminate --out``) read tolerantly for the report.

``discrimination.json`` holds the 2AFC pairs, the difference threshold at 75 % around a
reference step with its Weber fraction, and the PSE across scan speeds. A threshold that
not every posterior draw reaches is a bound: either written so (``"> 25"``, or a
``found`` fraction below 0.975 — the 95 % interval's upper end is then not reached) and
shown as "> x µm (n % of draws never reach 75 %)". The psychometric curve behind the
threshold, P(correct) against the height increment with its 95 % band, is read from the
JSON (``curve`` or ``threshold_curve``) or from ``threshold_curve.csv`` beside it.
``notes`` (strings) and ``extrapolated`` (the reference or a compared height lies outside
the plates the fit was trained on) are read when the file has them (older files do not).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from feeler.reports.humandata import parse_value
from feeler.reports.model import fmt

__all__ = ["Estimate", "RobotDisc", "robot_disc", "CURVE_FILE"]

CURVE_FILE = "threshold_curve.csv"
_BOUND_KEYS = ("bound_mm", "lower_bound_mm", "max_delta_mm", "searched_max_mm")


@dataclass(frozen=True)
class Estimate:
    """An estimate with its 95 % interval (in the unit the caller chose); ``bound`` ">"
    when the estimate is only a lower bound, ``never`` the fraction of draws that never
    reach the criterion (None when not known)."""
    value: float
    lo: float
    hi: float
    bound: str = ""
    never: float | None = None

    def scaled(self, factor: float) -> "Estimate":
        return Estimate(self.value * factor, self.lo * factor, self.hi * factor, self.bound, self.never)

    def text(self, digits: int = 3, unit: str = "") -> str:
        u = f" {unit}" if unit else ""
        never = (f" ({100 * self.never:.0f} % of draws never reach 75 %)"
                 if self.never is not None and self.never > 0 else "")
        if self.bound:
            return f"{self.bound} {fmt(self.value, digits)}{u}{never}"
        return f"{fmt(self.value, digits)} [{fmt(self.lo, digits)}, {fmt(self.hi, digits)}]{u}{never}"


def estimate(obj, *, mean_key: str = "mean") -> Estimate:
    """An :class:`Estimate` from ``{"mean", "lo95", "hi95", "found"?, bound keys?}``."""
    if not isinstance(obj, dict):
        v = parse_value(obj)
        return Estimate(v.value, math.nan, math.nan, v.bound)
    mean = parse_value(obj.get(mean_key))
    lo, hi = parse_value(obj.get("lo95")).value, parse_value(obj.get("hi95")).value
    found = obj.get("found")
    never = None if found is None else max(0.0, 1.0 - float(found))
    if mean.bound:
        return Estimate(mean.value, lo, hi, mean.bound, never)
    if never is not None and never > 0.025:               # the interval's top is not reached
        bound = next((float(obj[k]) for k in _BOUND_KEYS if k in obj), lo if math.isfinite(lo) else mean.value)
        return Estimate(bound, lo, math.nan, ">", never)
    return Estimate(mean.value, lo, hi, "", never)


@dataclass(frozen=True)
class RobotDisc:
    """Attributes: part; reference_um; threshold_um, weber, pse_um (:class:`Estimate`);
    pse_speeds (reference, test speed mm/s); pairs (list of dicts); curve (DataFrame with
    delta_um, pc, lo95, hi95, or None) and curve_rel; notes (the file's notes, str) and
    extrapolated (True when the file says a height lies outside the trained plates)."""
    part: object
    reference_um: float
    threshold_um: Estimate
    weber: Estimate
    pse_um: Estimate | None
    pse_speeds: tuple
    pairs: list
    curve: object
    curve_rel: str
    notes: tuple = ()
    extrapolated: bool = False


def _curve(inv, part, obj):
    """(DataFrame delta_um, pc, lo95, hi95) or None, and its source."""
    import pandas as pd

    from feeler.errors import DataFileError
    from feeler.reports.readers import read_table

    raw, rel = obj.get("curve", obj.get("threshold_curve")), part.path("discrimination.json")
    if raw is not None:
        frame = pd.DataFrame(raw)
    elif (inv.run_dir / part.path(CURVE_FILE)).is_file():
        rel = part.path(CURVE_FILE)
        frame = read_table(inv.run_dir / rel)
    else:
        return None, ""
    if "delta_um" not in frame and "delta_mm" in frame:
        frame["delta_um"] = pd.to_numeric(frame["delta_mm"], errors="coerce") * 1e3
    pc = next((c for c in ("pc", "pc_mean", "mean") if c in frame), None)
    if pc is None or not {"delta_um", "lo95", "hi95"} <= set(frame.columns):
        raise DataFileError(inv.run_dir / rel, "a threshold curve needs columns delta_mm (or delta_um), "
                                               "pc, lo95, hi95")
    out = pd.DataFrame({"delta_um": frame["delta_um"], "pc": frame[pc], "lo95": frame["lo95"],
                        "hi95": frame["hi95"]}).apply(pd.to_numeric, errors="coerce").dropna()
    return out.sort_values("delta_um").reset_index(drop=True), rel


def _notes(raw) -> tuple[str, ...]:
    """The file's notes: a list of strings (one string is taken as one note; absent: none)."""
    items = [raw] if isinstance(raw, str) else list(raw or [])
    return tuple(str(n).strip() for n in items if str(n).strip())


def _load(inv, part) -> RobotDisc:
    from feeler.reports.readers import read_json

    obj = read_json(inv.run_dir / part.path("discrimination.json"), ("pairs", "threshold_mm", "weber"))
    ref_um = parse_value(obj.get("reference_mm", math.nan)).value * 1e3
    pse = obj.get("pse")
    pse_est = estimate(pse, mean_key="mean_mm").scaled(1e3) if isinstance(pse, dict) else None
    speeds = (pse.get("speed_ref_mm_s"), pse.get("speed_test_mm_s")) if isinstance(pse, dict) else (None, None)
    curve, curve_rel = _curve(inv, part, obj)
    return RobotDisc(part=part, reference_um=ref_um, threshold_um=estimate(obj["threshold_mm"]).scaled(1e3),
                     weber=estimate({**obj["weber"], "found": obj["threshold_mm"].get("found")}
                                    if isinstance(obj["weber"], dict) else obj["weber"]),
                     pse_um=pse_est, pse_speeds=speeds, pairs=list(obj["pairs"] or []), curve=curve,
                     curve_rel=curve_rel, notes=_notes(obj.get("notes")),
                     extrapolated=obj.get("extrapolated") is True)


def robot_disc(inv) -> RobotDisc | None:
    """The run's robot discrimination (the first discrimination.json found), read once."""
    part = inv.first("discriminate", prefer="discriminate")
    return None if part is None else inv.cached("disc", lambda: _load(inv, part))


def pairs_frame(disc: RobotDisc):
    """The 2AFC pairs as rows (low_mm, high_mm, pc, lo95, hi95) with NaN for what is absent."""
    rows = []
    for p in disc.pairs:
        if isinstance(p, dict):
            rows.append([parse_value(p.get(k, np.nan)).value for k in ("low_mm", "high_mm", "pc", "lo95", "hi95")])
    return np.array(rows, float).reshape(-1, 5)
