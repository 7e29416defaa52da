"""A section per fitted model (M1, M2, M4, finger route, ...): verdict, posterior plots,
the diagnostics table and the priors. A failed verdict marks the section ``failed`` so
the report puts it first under a red banner.
"""
from __future__ import annotations

import numpy as np

from feeler.reports.model import Figure, Note, Section, Table, figure_uri, fmt, subplots, table_from_frame
from feeler.reports.readers import load_fit, read_json

__all__ = ["fit_section", "N_PLOTTED"]

N_PLOTTED = 6            # parameters drawn per fit (the table lists them all)
_COLUMNS = ("name", "mean", "sd", "eti95_lb", "eti95_ub", "r_hat", "ess_bulk", "ess_tail")


def fit_section(inv, spec) -> Section:
    """Verdict, marginal posteriors per chain, traces and the diagnostics of one fit."""
    name = spec.key.split(":", 1)[1]
    result = load_fit(inv.run_dir / name)
    files = tuple(spec.required)
    verdict = result.verdict
    blocks = []
    if verdict.ok:
        blocks.append(Note(f"Verdict: passed every diagnostic (backend {result.backend}, "
                           f"{fmt(result.seconds, 3)} s).", sources=(f"{name}/verdict.json",)))
    else:
        blocks.append(Note("Verdict: FAILED — do not use this posterior. " + "; ".join(verdict.problems),
                           level="failed", sources=(f"{name}/verdict.json",)))
    draws = result.draws()
    shown = [n for n in result.summary["name"] if n in draws][:N_PLOTTED]
    if shown:
        blocks.append(_marginals(draws, shown, (f"{name}/posterior.nc",)))
        blocks.append(_traces(draws, shown, (f"{name}/posterior.nc",)))
    cols = [c for c in _COLUMNS if c in result.summary.columns]
    blocks.append(table_from_frame(result.summary[cols], title="Posterior summary and diagnostics",
                                   sources=(f"{name}/summary.csv",),
                                   caption="95 % equal-tailed intervals; R-hat ≤ 1.01 and bulk ESS ≥ 400 pass."))
    if result.priors:
        rows = tuple((str(k), str(v)) for k, v in result.priors.items())
        blocks.append(Table("Priors", ("parameter", "prior"), rows, (f"{name}/posterior.nc",)))
    for rel in spec.optional:
        if rel.endswith(".json") and inv.has(rel):
            blocks.append(_json_table(inv.run_dir / rel, rel))
    return Section(spec.key, spec.title + f" ({name}/)", tuple(blocks), failed=not verdict.ok,
                   problems=tuple(verdict.problems))


def _marginals(draws, names, src) -> Figure:
    fig, axes = _grid(len(names))
    for ax, n in zip(axes, names):
        x = np.asarray(draws[n], float)
        for c, chain in enumerate(x.reshape(-1, x.shape[-1])):
            ax.hist(chain, bins=30, histtype="step", density=True, label=f"chain {c}")
        ax.set_title(n, fontsize=8)
        ax.tick_params(labelsize=6)
    return Figure("Marginal posteriors, one line per chain", figure_uri(fig), src,
                  caption=f"First {len(names)} parameters; chains that agree overlap.")


def _traces(draws, names, src) -> Figure:
    fig, axes = _grid(len(names))
    for ax, n in zip(axes, names):
        x = np.asarray(draws[n], float)
        for chain in x.reshape(-1, x.shape[-1]):
            ax.plot(chain, lw=0.4)
        ax.set_title(n, fontsize=8)
        ax.set_xlabel("draw", fontsize=7)
        ax.tick_params(labelsize=6)
    return Figure("Traces", figure_uri(fig), src, caption="Draw against iteration, per chain.")


def _grid(n: int):
    """Up to three panels per row; unused panels hidden."""
    ncols = min(n, 3)
    nrows = -(-n // ncols)
    fig, axes = subplots(ncols, nrows=nrows, width_in=2.6, height_in=2.1, squeeze=False)
    flat = axes.ravel()
    for ax in flat[n:]:
        ax.set_axis_off()
    return fig, flat[:n]


def _json_table(path, rel) -> Table:
    """A flat key → value table of a small JSON file (e.g. ppc.json, tau_report.json)."""
    obj = read_json(path)
    return Table(rel.rsplit("/", 1)[-1], ("key", "value"),
                 tuple((str(k), _cell(v)) for k, v in obj.items()), (rel,))


def _cell(value) -> str:
    if isinstance(value, list):
        return ", ".join(_cell(v) for v in value)
    if isinstance(value, dict):
        return "; ".join(f"{k}: {_cell(v)}" for k, v in value.items())
    return fmt(value)
