"""One PNG per subject (and ``all``) and condition: the fitted psychometric function with
its 95 % band and the data.

Files: ``curves/<subject>_<standard_um>um_<standard_speed>mm_s_<comparison_speed>mm_s.png``
and ``curves/index.csv`` (subject, standard_um, standard_speed_mm_s,
comparison_speed_mm_s, file; ``file`` relative to the fit directory, e.g.
``curves/S1_10um_20mm_s_20mm_s.png``). The curve is the pointwise posterior median of P,
the band its pointwise 95 % interval (over up to 400 draws); points are the observed
proportions with 95 % Clopper–Pearson intervals, area ∝ trials. matplotlib (Agg) is
imported only here.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd

from feeler.calib.psychometric.outputs.display import threshold_cells
from feeler.calib.psychometric.outputs.table import threshold_table
from feeler.calib.psychometric.model.task import Task

__all__ = ["write_curves", "curve_name", "curve_figure", "INDEX_COLUMNS"]

INDEX_COLUMNS = ("subject", "standard_um", "standard_speed_mm_s", "comparison_speed_mm_s", "file")
MAX_DRAWS = 400


def curve_name(subject: str, standard_um: float, v_std: float, v_cmp: float) -> str:
    """``S1_10um_20mm_s_20mm_s.png`` (characters outside [A-Za-z0-9.-] in the label → _)."""
    safe = re.sub(r"[^A-Za-z0-9.\-]", "_", str(subject))
    return f"{safe}_{standard_um:g}um_{v_std:g}mm_s_{v_cmp:g}mm_s.png"


def _row_data(tree, o: int, c: int):
    obs = tree["observed_data"]
    x, n, k = (np.asarray(obs[v].values, float) for v in ("x_um", "n_trials", "n_counted"))
    sel = np.asarray(obs["condition_index"].values) == c
    if o >= 0:
        sel &= np.asarray(obs["subject_index"].values) == o
    levels = np.unique(x[sel])
    nn = np.array([n[sel][x[sel] == v].sum() for v in levels])
    kk = np.array([k[sel][x[sel] == v].sum() for v in levels])
    return levels, nn, kk


def _row_draws(post, o: int, c: int):
    suffix = "_all" if o < 0 else ""

    def get(v):
        a = np.asarray(post[v + suffix].values, float)
        a = a.reshape((-1,) + a.shape[2:])
        if o >= 0:
            a = a[:, o]
        return a[:, c] if a.ndim == 2 else a
    take = np.linspace(0, get("pse").shape[0] - 1, min(MAX_DRAWS, get("pse").shape[0])).astype(int)
    return get("pse")[take], get("sigma")[take], get("lapse")[take]


def _plot(path: Path, task: Task, row, data, draws, synthetic: bool) -> None:
    import matplotlib.pyplot as plt

    fig = curve_figure(task, row, data, draws, synthetic)
    fig.savefig(path)
    plt.close(fig)


def curve_figure(task: Task, row, data, draws, synthetic: bool):
    """The figure of one row (matplotlib Figure, Agg): the curve, its band and the data in
    the axes; the PSE, threshold and fit numbers in a block under them, where they hide
    nothing (drawn over the upper left of the axes, they covered the data points near the
    threshold and notched the band: an outside walk-through), beside the legend
    (:func:`_below_the_axes`)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from scipy.stats import beta

    x, n, k = data
    pse, sig, lam = draws
    thr = row.threshold_um if np.isfinite(row.threshold_um) else row.pse_ub_um
    lo, hi = float(min(x.min(), row.pse_lb_um, thr)), float(max(x.max(), row.pse_ub_um, thr))
    pad = 0.15 * (hi - lo if hi > lo else max(abs(hi), 1.0))
    grid = np.linspace(lo - pad, hi + pad, 200)
    p = task.p(grid[None, :], pse[:, None], sig[:, None], lam[:, None])
    band = np.quantile(p, [0.025, 0.5, 0.975], axis=0)
    # drawn at about the size the report's gallery shows it (two a row, ~3.2 in): at 4.6 in with
    # 6.5 pt text, four a row, the annotations printed at 3-4 pt (an outside reader of the report);
    # 0.5 in taller than the axes need, for the block of numbers and legend under them
    fig, ax = plt.subplots(figsize=(3.3, 3.1), dpi=170)
    ax.fill_between(grid, band[0], band[2], color="C0", alpha=0.25, lw=0, label="95 % band")
    ax.plot(grid, band[1], color="C0", lw=1.5, label="posterior median")
    with np.errstate(invalid="ignore"):
        lo_ci = np.where(k > 0, beta.ppf(0.025, k, n - k + 1), 0.0)
        hi_ci = np.where(k < n, beta.ppf(0.975, k + 1, n - k), 1.0)
    prop = k / n
    ax.errorbar(x, prop, yerr=[prop - lo_ci, hi_ci - prop], fmt="none", ecolor="k", lw=0.8, capsize=2)
    ax.scatter(x, prop, s=6 + 30 * n / n.max(), color="k", zorder=3, label="data (area ∝ trials)")
    ax.axvline(row.pse_um, color="C1", ls=":", lw=1)
    if np.isfinite(row.threshold_um):
        ax.axvline(row.threshold_um, color="C2", ls="--", lw=1)
        ax.axhline(row.pc, color="C2", ls="--", lw=0.6)
    tag = " (SYNTHETIC)" if synthetic else ""
    ax.set(xlabel="comparison height (µm)", ylabel=f"P({task.response})", ylim=(-0.02, 1.02),
           title=f"{row.subject}{tag}: standard {row.standard_um:g} µm, {row.standard_speed_mm_s:g}/"
                 f"{row.comparison_speed_mm_s:g} mm/s")
    what = "PSE" if not task.is_nafc else "m"
    th = threshold_cells(row)                  # a bound or "—" where draws never reach pc, never NaN
    fit = (f"deviance {row.deviance:.3g}, GOF p {row.gof_p:.3g}" if np.isfinite(row.gof_p)
           else "population mean: no deviance")
    text = (f"{what} {row.pse_um:.3g} [{row.pse_lb_um:.3g}, {row.pse_ub_um:.3g}] µm (dotted)\n"
            f"threshold@{row.pc:g} {th['threshold_um']} µm (dashed)\nslope {th['slope_per_um']}/µm\n{fit}")
    ax.title.set_fontsize(7.5)
    ax.xaxis.label.set_fontsize(7.5)
    ax.yaxis.label.set_fontsize(7.5)
    ax.tick_params(labelsize=6.5)
    _below_the_axes(fig, ax, text)
    return fig


def _below_the_axes(fig, ax, text: str) -> None:
    """The numbers (left) and the legend (right) in a block under the axes, the axes laid
    out above it: neither hides any of the data. Where the two would meet (long numbers),
    the numbers go above the legend."""
    pad = 0.015
    block = fig.text(0.03, pad, text, va="bottom", ha="left", fontsize=6.5)
    legend = fig.legend(*ax.get_legend_handles_labels(), fontsize=6, loc="lower right",
                        bbox_to_anchor=(1 - pad, pad), framealpha=0.8)
    fig.canvas.draw()
    to_fig = fig.transFigure.inverted()
    words, key = (a.get_window_extent().transformed(to_fig) for a in (block, legend))
    if words.x1 + pad > key.x0:                          # side by side they would meet: stack them
        block.set_y(key.y1 + pad)
        words = block.get_window_extent(fig.canvas.get_renderer()).transformed(to_fig)
    fig.tight_layout(rect=(0, max(words.y1, key.y1) + pad, 1, 1))


def write_curves(result, out_dir: str | Path, *, synthetic: bool = False) -> Path:
    """Write every row's PNG and ``index.csv`` into ``out_dir`` (created); returns it."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    post = result.posterior["posterior"]
    subjects = json.loads(post.attrs["subjects"])
    conditions = [tuple(c) for c in json.loads(post.attrs["conditions"])]
    task = Task(json.loads(post.attrs.get("n_alternatives", "null")))
    index = []
    for row in threshold_table(result).itertuples(index=False):
        o = -1 if row.subject == "all" else subjects.index(row.subject)
        c = conditions.index((row.standard_um, row.standard_speed_mm_s, row.comparison_speed_mm_s))
        name = curve_name(row.subject, row.standard_um, row.standard_speed_mm_s, row.comparison_speed_mm_s)
        _plot(out / name, task, row, _row_data(result.posterior, o, c), _row_draws(post, o, c), synthetic)
        index.append((row.subject, row.standard_um, row.standard_speed_mm_s, row.comparison_speed_mm_s,
                      f"{out.name}/{name}"))
    pd.DataFrame(index, columns=list(INDEX_COLUMNS)).to_csv(out / "index.csv", index=False,
                                                            float_format="%.6g", lineterminator="\n")
    return out
