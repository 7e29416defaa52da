"""``thresholds.csv``: one row per subject (and ``all``) and condition with trials.

Columns (heights µm, slopes per µm; ``*_um`` = posterior mean, ``_median``, ``_map`` =
at the posterior mode over (m, σ, λ), ``_lb``/``_ub`` = 95 % equal-tailed bounds):

- ``subject``; ``estimand``: "subject", or for ``all`` "pooled trials" (every trial
  fitted as one observer) or "population mean" (hierarchical model);
- ``standard_um``, ``standard_speed_mm_s``, ``comparison_speed_mm_s``: the condition;
- ``design`` ("comparison" or "nAFC", e.g. "4AFC"), ``backend``;
- ``pse_*``: the PSE (comparison design) or the location m where Φ = ½ (nAFC: psignifit's
  threshold at the unscaled ½);
- ``dt_*``: difference threshold, PSE → the 75 % point (comparison design; empty in nAFC);
- ``pc``, ``threshold_*``: the stimulus where P = pc; ``threshold_unreached``: the
  posterior mass whose lapse keeps P below pc (bounds past it are ``inf``);
- ``slope_*_per_um``: dP/dx at that point; ``sigma_*_um``, ``lapse*``;
- ``n_levels``, ``n_trials``, ``deviance`` (at the MAP; hierarchical: at the posterior
  mean), ``gof_p`` (posterior predictive p of the deviance; empty for the population
  mean), ``gof_ok``.

The table is stored with the posterior (attribute ``thresholds_csv``) so that
:func:`threshold_table` returns it after :func:`feeler.calib.fit.load`.
"""
from __future__ import annotations

import io

import numpy as np
import pandas as pd

__all__ = ["THRESHOLD_COLUMNS", "LEGACY_COLUMNS", "QUANTITIES", "table_rows", "threshold_table",
           "table_csv"]

LEGACY_COLUMNS = ("subject", "standard_speed_mm_s", "comparison_speed_mm_s", "pse_um",
                  "pse_lb_um", "pse_ub_um", "dt_um", "dt_lb_um", "dt_ub_um")
#: (stats key, column stem, unit suffix)
QUANTITIES = (("pse", "pse", "_um"), ("dt", "dt", "_um"), ("threshold", "threshold", "_um"),
              ("slope", "slope", "_per_um"), ("sigma", "sigma", "_um"), ("lapse", "lapse", ""))


def _columns() -> tuple[str, ...]:
    cols = ["subject", "estimand", "standard_um", "standard_speed_mm_s", "comparison_speed_mm_s",
            "design", "backend"]
    for _, stem, unit in QUANTITIES:
        if stem == "threshold":
            cols.append("pc")
        cols += [f"{stem}{unit}", f"{stem}_lb{unit}", f"{stem}_ub{unit}", f"{stem}_median{unit}",
                 f"{stem}_map{unit}"]
        if stem == "threshold":
            cols.append("threshold_unreached")
    return tuple(cols + ["n_levels", "n_trials", "deviance", "gof_p", "gof_ok"])


THRESHOLD_COLUMNS = _columns()


def table_rows(rows: list[dict]) -> pd.DataFrame:
    """The table from row dicts with the identification columns, ``stats`` (per
    quantity: mean, lb, ub, median), ``map`` (per quantity) and the fit columns."""
    out = []
    for r in rows:
        rec = {k: r[k] for k in ("subject", "estimand", "standard_um", "standard_speed_mm_s",
                                 "comparison_speed_mm_s", "design", "backend", "pc", "n_levels",
                                 "n_trials", "deviance", "gof_p", "gof_ok")}
        for key, stem, unit in QUANTITIES:
            s = r["stats"][key]
            rec |= {f"{stem}{unit}": s["mean"], f"{stem}_lb{unit}": s["lb"], f"{stem}_ub{unit}": s["ub"],
                    f"{stem}_median{unit}": s["median"], f"{stem}_map{unit}": r["map"].get(key, np.nan)}
        rec["threshold_unreached"] = r["stats"]["threshold"].get("unreached", 0.0)
        out.append(rec)
    return pd.DataFrame(out, columns=list(THRESHOLD_COLUMNS))


def table_csv(table: pd.DataFrame) -> str:
    """The CSV text of the table (as written to thresholds.csv, without the notes)."""
    return table.to_csv(index=False, float_format="%.6g", lineterminator="\n")


def threshold_table(result, *, observed: pd.DataFrame | None = None) -> pd.DataFrame:
    """The thresholds table of an M4 FitResult (also after :func:`feeler.calib.fit.load`).

    Args:
        observed: a trial table; when given, only rows whose subject (any subject for
            ``all``) has trials in that condition are kept.
    Raises:
        DataFileError: a posterior written without the table (an older feeler).
    """
    from feeler.errors import DataFileError

    attrs = result.posterior["posterior"].attrs
    if "thresholds_csv" not in attrs:
        raise DataFileError("posterior.nc", "has no thresholds table (written by an older feeler); refit")
    table = pd.read_csv(io.StringIO(attrs["thresholds_csv"]), keep_default_na=True,
                        dtype={"subject": str, "estimand": str, "design": str, "backend": str})
    if observed is None:
        return table
    tested = observed[observed["n_trials"] > 0]
    keys = set(zip(tested["subject"].astype(str), tested["standard_um"].astype(float),
                   tested["standard_speed_mm_s"].astype(float), tested["comparison_speed_mm_s"].astype(float)))
    any_keys = {k[1:] for k in keys}
    keep = [((s, a, b, c) in keys) or (s == "all" and (a, b, c) in any_keys)
            for s, a, b, c in zip(table.subject, table.standard_um, table.standard_speed_mm_s,
                                  table.comparison_speed_mm_s)]
    return table[keep].reset_index(drop=True)
