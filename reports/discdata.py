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
        try:
            frame = pd.DataFrame(raw)
        except (ValueError, TypeError) as exc:          # columns of unequal length, scalars without an index
            raise DataFileError(inv.run_dir / rel, f"curve: not a table of columns delta_mm, pc, lo95, hi95 "
                                                   f"({exc})") from None
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


def _is_value(raw) -> bool:
    """A number (NaN and infinities too: JSON's null, NaN, Infinity), or a string that
    :func:`parse_value` reads as one or as a bound ("> 25")."""
    if raw is None or (isinstance(raw, (int, float)) and not isinstance(raw, bool)):
        return True
    return isinstance(raw, str) and not math.isnan(parse_value(raw).value)


def check_shape(path, obj: dict) -> None:
    """Each field the report reads from a discrimination.json has the shape discriminate
    writes; else a one-line DataFileError naming the field, what it holds and what is
    allowed (a hand-edited file gave AttributeError, TypeError and ValueError tracebacks).

    Tolerant as the reader is: absent fields, null and NaN values, and bounds written as
    text ("> 25") pass."""
    from feeler.errors import DataFileError

    def bad(key: str, allowed: str, value) -> None:
        raise DataFileError(path, f"{key} holds {value!r:.40}; expected {allowed}")

    def is_estimate_or_value(key: str) -> None:
        value = obj.get(key)
        if isinstance(value, dict):
            for k in ("mean", "mean_mm", "median", "lo95", "hi95"):
                if not _is_value(value.get(k)):
                    bad(f"{key}.{k}", "a number or a bound such as \"> 0.025\"", value[k])
            found = value.get("found")
            if found is not None and not (_is_value(found) and not isinstance(found, str) and 0 <= found <= 1):
                bad(f"{key}.found", "the fraction of draws that reach 75 %, 0-1", found)
        elif not _is_value(value):
            bad(key, "an object {mean, lo95, hi95} or a number", value)

    for key in ("threshold_mm", "weber"):
        is_estimate_or_value(key)
    if isinstance(obj.get("pse"), dict):
        is_estimate_or_value("pse")
    elif obj.get("pse") is not None:
        bad("pse", "an object {mean_mm, lo95, hi95, speed_ref_mm_s, speed_test_mm_s}", obj["pse"])
    pairs = obj.get("pairs")
    if pairs is not None:
        if not isinstance(pairs, list) or not all(isinstance(p, dict) for p in pairs):
            bad("pairs", "a list of objects {low_mm, high_mm, pc, lo95, hi95}", pairs)
        for i, p in enumerate(pairs):
            for k in ("low_mm", "high_mm", "pc", "lo95", "hi95"):
                if not _is_value(p.get(k)):
                    bad(f"pairs[{i}].{k}", "a number", p[k])
    notes = obj.get("notes")
    if notes is not None and not isinstance(notes, str) and not (isinstance(notes, list) and
                                                                  all(isinstance(n, str) for n in notes)):
        bad("notes", "a list of strings", notes)
    curve = obj.get("curve", obj.get("threshold_curve"))
    if curve is not None and not isinstance(curve, (dict, list)):
        bad("curve", "an object of columns (delta_mm, pc, lo95, hi95) or a list of rows", curve)


def _load(inv, part) -> RobotDisc:
    from feeler.reports.readers import read_json

    path = inv.run_dir / part.path("discrimination.json")
    obj = read_json(path, ("pairs", "threshold_mm", "weber"))
    check_shape(path, obj)
    ref_um = parse_value(obj.get("reference_mm", math.nan)).value * 1e3
    pse = obj.get("pse")
    pse_est = estimate(pse, mean_key="mean_mm").scaled(1e3) if isinstance(pse, dict) else None
    speeds = (pse.get("speed_ref_mm_s"), pse.get("speed_test_mm_s")) if isinstance(pse, dict) else (None, None)
    curve, curve_rel = _curve(inv, part, obj)
    return RobotDisc(part=part, reference_um=ref_um, threshold_um=estimate(obj["threshold_mm"]).scaled(1e3),
                     weber=estimate({**obj["weber"], "found": (obj["threshold_mm"].get("found")
                                                               if isinstance(obj["threshold_mm"], dict) else None)}
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
