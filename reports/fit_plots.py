"""Posterior figures of each model, every parameter named by what it is.

- M1: the matrix C entry by entry against the true C when the run holds the simulated
  sensor's truth, marginals of all nine entries, of σ per axis and of cond(C);
- M2: a, τ, h and σ with their units;
- M4 and the finger route: :mod:`feeler.reports.psy_plots`;
- any other model: the marginals of all its entries, six to a figure.

Samplers (NUTS, emcee) also get one line per chain and traces; other backends' draws are
independent and pooled.
"""
from __future__ import annotations

import json

import numpy as np

from feeler.reports.model import Figure, Note, error_span, make_figure, subplots

__all__ = ["labels_of", "plate_steps", "plots_of", "plot_inputs", "conditions_of", "split_finite", "NO_FINITE", "DENSITY",
           "fixed_and_copies", "even_chunk"]

_UNITS = {"a": "a (mm per unit strain)", "tau_s": "τ (s)", "h": "h (mm)", "sigma_mm": "σ (mm)",
          "sigma_d_um": "σ_d (µm)", "lapse": "lapse", "cond_C": "cond(C)", "lapse_all": "lapse (pooled)"}
_PER_FIG = 6
#: the y label of a marginal panel (its ticks are left out: the scale is per unit of x)
DENSITY = "density"
#: what stands in for the figure of an entry whose draws are all NaN or infinite
NO_FINITE = "no finite draws: the fit failed, see its verdict"


def split_finite(draws: dict) -> tuple[dict, list[str]]:
    """(the entries of ``draws`` with at least one finite draw, the names of those with
    none): a failed fit may leave some parameters undefined, and their histograms cannot
    be drawn."""
    kept, empty = {}, []
    for name, x in draws.items():
        if np.isfinite(np.asarray(x, float)).any():
            kept[name] = x
        else:
            empty.append(name)
    return kept, empty


def fixed_and_copies(draws: dict, names) -> tuple[dict, dict]:
    """({name: value} of entries equal at every draw, {name: earlier name} of entries equal
    draw for draw to an earlier one, to rounding): neither gets a panel of its own."""
    fixed, copies, seen = {}, {}, []
    for name in names:
        x = np.asarray(draws[name], float)
        if x.size and np.all(x == x.flat[0]):
            fixed[name] = float(x.flat[0])
            continue
        twin = next((n for n in seen if np.shape(draws[n]) == x.shape
                     and np.allclose(draws[n], x, rtol=1e-12, atol=0.0)), None)
        if twin is None:
            seen.append(name)
        else:
            copies[name] = twin
    return fixed, copies


def even_chunk(n: int, most: int) -> int:
    """Panels per figure: as few figures as ``most`` a figure allows, filled evenly (19
    entries: 5, 5, 5, 4, not 6, 6, 6, 1 with a lone full-width panel)."""
    figures = max(1, -(-n // most))
    return max(1, -(-n // figures))


def _finite(x) -> np.ndarray:
    """The finite values of ``x``, flattened."""
    x = np.ravel(np.asarray(x, float))
    return x[np.isfinite(x)]


def _density(ax, x, bins: int, **kw) -> None:
    """A step histogram of the finite draws ``x``; draws that are one value (to rounding: a
    parameter the model pins, such as a two-plate decoder's plate means) are a vertical line,
    where a histogram has no width to divide into bins (numpy raised 'Too many bins'), or
    whose bins would be rounding error (ticks 1e-17 apart)."""
    x = _finite(x)
    if not x.size:
        return
    if np.ptp(x) <= max(1e-9 * float(np.max(np.abs(x))), 1e-12):     # 1e-12: a zero that rounding spreads
        kw = {k: v for k, v in kw.items() if k in ("color", "label", "lw")}
        v = float(np.median(x))
        v = v if abs(v) > 1e-12 else 0.0           # a zero that rounding left at 1e-17
        ax.axvline(v, **kw)
        half = 0.05 * abs(v) if v else 1.0         # else the axis spans the rounding: ticks 1e-14 apart
        ax.set_xlim(v - half, v + half)
        return
    ax.hist(x, bins=bins, histtype="step", density=True, **kw)


def _json(value, default):
    if isinstance(value, str):
        try:
            return json.loads(value)
        except json.JSONDecodeError:
            return default
    return default if value is None else list(value)


def conditions_of(attrs) -> list[str]:
    """M4 conditions as words, "10 µm at 40 vs 20 mm/s", in index order."""
    out = []
    for c in _json(attrs.get("conditions"), []):
        c = list(c) + [np.nan] * 3
        out.append(f"{c[0]:g} µm at {c[1]:g} vs {c[2]:g} mm/s")
    return out


def plate_steps(result):
    """An M2 fit's plate heights (mm) in the order of its per-plate entries (``plate_mean_mm[i]``
    is the plate of ``steps[i]``), or None when the fit does not record them."""
    try:
        obs = result.posterior["observed_data"]
    except (KeyError, AttributeError, TypeError):
        return None
    if "plate_steps_mm" not in obs:
        return None
    return [float(v) for v in np.ravel(obs["plate_steps_mm"].values)]


def _m2_label(name: str, steps) -> str:
    """``plate_mean_mm[1] · plate 0.05 mm``: which plate an index is (the report named the
    entries plate_mean_mm[0..3] and never said which height each was: an outside walk-through)."""
    base, _, idx = name.partition("[")
    i = idx.rstrip("]")
    if base.startswith("plate_") and i.isdigit() and int(i) < len(steps):
        return f"{name} · plate {steps[int(i)]:g} mm"
    return _UNITS.get(name, name)


def _m1_label(name: str) -> str:
    base, _, idx = name.partition("[")
    ij = [int(i) for i in idx.rstrip("]").split(",") if i.strip().isdigit()]
    if base == "C" and len(ij) == 2:
        return f"C[{ij[0]},{ij[1]}]  U_{'xyz'[ij[0]]} ← F_{'xyz'[ij[1]]} (mm/N)"
    if base == "K" and len(ij) == 2:
        return f"K[{ij[0]},{ij[1]}]  F_{'xyz'[ij[0]]} ← U_{'xyz'[ij[1]]} (N/mm)"
    if base == "sigma_n" and len(ij) == 1:
        return f"σ_{'xyz'[ij[0]]} (N)"
    return _UNITS.get(name, name)


def labels_of(model: str, attrs, names, steps=None) -> dict:
    """Readable names of summary entries (M1 entries by axis, M4 indices as subjects and
    conditions, M2's per-plate entries by their plate's height when ``steps`` gives the
    heights in index order, units where the model states them)."""
    if model == "m1":
        return {n: _m1_label(n) for n in names}
    if model == "m2" and steps is not None:
        return {n: _m2_label(n, steps) for n in names}
    if model != "m4":
        return {n: _UNITS.get(n, n) for n in names}
    subjects, conds = _json(attrs.get("subjects"), []), conditions_of(attrs)
    out = {}
    for n in names:
        base, _, idx = n.partition("[")
        parts = [int(i) for i in idx.rstrip("]").split(",") if i.strip().isdigit()] if idx else []
        if base.endswith("_all"):
            who, rest = "all", parts
        else:
            who, rest = (subjects[parts[0]] if parts and parts[0] < len(subjects) else "?"), parts[1:]
        cond = conds[rest[0]] if rest and rest[0] < len(conds) else ""
        out[n] = f"{base.removesuffix('_all')} · {who}" + (f" · {cond}" if cond else "")
    return out


def _marginals(draws, names, labels, *, per_chain: bool, title: str, src) -> Figure:
    from matplotlib.ticker import MaxNLocator

    n = len(names)
    ncols = 4 if n == 4 else min(n, 3)
    fig, axes = subplots(ncols, nrows=-(-n // ncols), width_in=7.0 / ncols, height_in=1.45, squeeze=False)
    for ax in axes.ravel()[n:]:
        ax.set_visible(False)
    for ax, name in zip(axes.ravel(), names):
        x = np.asarray(draws[name], float).reshape(-1, np.shape(draws[name])[-1])
        for chain in (x if per_chain else x.reshape(1, -1)):
            _density(ax, chain, 30, lw=0.9)                 # a chain of a failed fit may hold NaN
        lo, hi = np.quantile(_finite(x), [0.025, 0.975])
        ax.axvspan(lo, hi, color="0.85", zorder=0)
        ax.set_title(labels.get(name, name), fontsize=7)
        ax.xaxis.set_major_locator(MaxNLocator(3))
        ax.ticklabel_format(axis="x", style="plain", useOffset=False)
        ax.tick_params(labelsize=6)
        ax.set_yticks([])
        ax.set_ylabel(DENSITY, fontsize=6)
    how = "one line per chain (chains that agree overlap)" if per_chain else "all draws pooled"
    return make_figure(title, fig, src, f"Marginal posterior densities, {how}; grey: 95 % interval.")


def _traces(draws, names, labels, src) -> Figure:
    n = len(names)
    fig, axes = subplots(min(n, 3), nrows=-(-n // 3), width_in=7.0 / min(n, 3), height_in=1.3, squeeze=False)
    for ax in axes.ravel()[n:]:
        ax.set_visible(False)
    for ax, name in zip(axes.ravel(), names):
        x = np.asarray(draws[name], float).reshape(-1, np.shape(draws[name])[-1])
        step = max(1, x.shape[1] // 300)
        for chain in x:
            ax.plot(np.arange(0, x.shape[1], step), chain[::step], lw=0.4, alpha=0.8)
        ax.set_title(labels.get(name, name), fontsize=7)
        ax.set_xlabel("draw", fontsize=6)
        ax.tick_params(labelsize=6)
    return make_figure("Traces", fig, src, "Each chain's draws in order (every "
                       f"{max(1, np.shape(draws[names[0]])[-1] // 300)}th shown).")


def _forest(ax, labels, mean, lo, hi, *, truth=None, band=None, color="C0") -> None:
    y = np.arange(len(labels))[::-1]
    ax.errorbar(mean, y, xerr=error_span(mean, lo, hi), fmt="o", ms=3, capsize=2,
                color=color, label="posterior mean, 95 % interval")
    if truth is not None:
        ax.plot(truth, y, "x", color="k", ms=5, label="true value (simulated)")
    if band is not None:
        ax.axvspan(*band, color=color, alpha=0.15, label="pooled 95 % interval")
    ax.set_yticks(y, labels, fontsize=6)
    ax.tick_params(axis="x", labelsize=6)


def _summary_cols(result, names):
    s = result.summary.set_index("name").loc[names]
    return s["mean"].to_numpy(), s["eti95_lb"].to_numpy(), s["eti95_ub"].to_numpy()


def _true_c(inv):
    from feeler.reports.readers import run_json

    part = inv.first("calibration-data", prefer="sensor-calibration")
    if part is None or not inv.has(part.path("truth.json")):
        return None, None
    from feeler.errors import DataFileError

    rel = part.path("truth.json")
    node = run_json(inv, rel)
    for key in ("scene", "sensor"):                 # the simulated scene's [sensor] table, when recorded
        node = node.get(key) if isinstance(node, dict) else node
        if node is None:
            return None, None
        if not isinstance(node, dict):
            raise DataFileError(inv.run_dir / rel, f"{key} holds {type(node).__name__} {node!r:.30}; expected an "
                                                   f"object (the simulated scene as `feeler simulate` records it)")
    c = node.get("c_mm_per_n")
    if c is None:
        return None, None
    try:
        c = np.asarray(c, float).ravel()
    except (TypeError, ValueError):
        c = np.array([])
    if c.size != 9 or not np.all(np.isfinite(c)):
        raise DataFileError(inv.run_dir / rel, f"scene.sensor.c_mm_per_n holds {node['c_mm_per_n']!r:.40}; expected "
                                               f"the 3x3 compliance matrix, mm/N")
    return c, rel


def _m1(inv, result, draws, sampler, src) -> list:
    names = [f"C[{i},{j}]" for i in range(3) for j in range(3)]
    truth, truth_rel = _true_c(inv)
    fig, ax = subplots(width_in=4.6, height_in=2.6)
    _forest(ax, [f"C[{i},{j}]  U_{'xyz'[i]} ← F_{'xyz'[j]}" for i in range(3) for j in range(3)],
            *_summary_cols(result, names), truth=truth)
    ax.set(xlabel="compliance (mm/N)", title="Force→displacement matrix C, entry by entry")
    ax.legend(fontsize=6)
    out = [make_figure("The matrix C", fig, src + ((truth_rel,) if truth_rel else ()),
                       "Posterior mean and 95 % interval of every entry" +
                       ("; ×: the simulated sensor's true C." if truth is not None else "."))]
    labels = {n: _m1_label(n) for n in names} | {f"sigma_n[{j}]": f"σ_{'xyz'[j]} (N)" for j in range(3)} | \
        {"cond_C": "cond(C)"}
    out.append(_marginals(draws, names[:6], labels, per_chain=sampler, title="Marginals of C, rows x and y", src=src))
    rest = names[6:] + [n for n in ("sigma_n[0]", "sigma_n[1]", "sigma_n[2]", "cond_C") if n in draws]
    out.append(_marginals(draws, rest, labels, per_chain=sampler, title="Marginals of C row z, σ and cond(C)",
                          src=src))
    return out


def plot_inputs(inv, part) -> None:
    """Read the run's files :func:`plots_of` draws from beside the fit (M1: the campaign's
    truth.json; the human fits: the human data), before the report's first figure."""
    if part.model == "m1":
        _true_c(inv)
    elif part.model in ("m4", "finger-route"):
        from feeler.reports.psy_plots import synthetic_inv

        synthetic_inv(inv)


def plots_of(inv, part, result, attrs, *, sampler: bool) -> list:
    """The figures of one fit (see the module docstring); entries without a finite draw
    are named in a note instead of drawn (:data:`NO_FINITE`)."""
    from feeler.reports.psy_plots import m4_figures, route_marginals, synthetic_inv

    draws, empty = split_finite(result.draws())
    src = (part.path("posterior.nc"),)
    labels = labels_of(part.model, attrs, list(draws) + empty, plate_steps(result))
    if part.model == "m1" and all(f"C[{i},{j}]" in draws for i in range(3) for j in range(3)):
        out = _m1(inv, result, draws, sampler, src)
        key = ["C[0,0]", "C[1,1]", "C[2,2]", "sigma_n[0]", "sigma_n[1]", "sigma_n[2]"]
    elif part.model == "m4":
        out = m4_figures(result, draws, attrs, src, synthetic_inv(inv))
        key = [n for n in draws if n.startswith(("pse_all", "dt_all", "lapse_all"))][:_PER_FIG]
    elif part.model == "finger-route":
        out = route_marginals(draws, attrs, src, synthetic_inv(inv))
        key = [n for n in ("tau_s", "sigma_d_um", "lapse") if n in draws]
    else:
        names = [n for n in result.summary["name"] if n in draws]
        fixed, copies = fixed_and_copies(draws, names)
        names = [n for n in names if n not in fixed and n not in copies]
        per = even_chunk(len(names), _PER_FIG)
        out = [_marginals(draws, names[i:i + per], labels, per_chain=sampler, src=src,
                          title="Marginal posteriors" + (f" ({i // per + 1})" if len(names) > per else ""))
               for i in range(0, len(names), per)]
        key = names[:_PER_FIG]
        if fixed or copies:
            words = [f"{labels.get(n, n)} = {v:g} at every draw (fixed)" for n, v in fixed.items()]
            words += [f"{labels.get(n, n)} equals {labels.get(t, t)} draw for draw" for n, t in copies.items()]
            out.append(Note("Not drawn: " + "; ".join(words) + ".", sources=src))
    if empty:
        out.insert(0, Note(f"{', '.join(labels.get(n, n) for n in empty)}: {NO_FINITE}.", level="failed",
                           sources=src))
    if sampler and key:
        out.append(_traces(draws, [k for k in key if k in draws], labels, src))
    elif not sampler:
        out.append(Note(f"Backend {result.backend}: independent draws, so chains are not compared and no "
                        "traces are drawn."))
    return out
