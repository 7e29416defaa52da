"""Fit sections an outside review (s49) read: a fixed parameter with ESS values and its own
empty panel (item 13), a NumPy repr in the priors (item 18), a footnote stating a rule the
fit's backend is not judged by (item 20)."""
from __future__ import annotations

import re

import numpy as np

from feeler.reports import discover
from feeler.reports.fit_plots import even_chunk, fixed_and_copies
from feeler.reports.sec_fits import RULE_INDEPENDENT, fit_section, independent_draws, readable_prior


def _section(run_dir, key):
    inv = discover(run_dir)
    return fit_section(inv, next(s for s in inv.present if s.key == key))


def _table(section, title):
    return next(b for b in section.blocks if b.kind == "table" and b.title == title)


def test_fixed_and_copied_entries_are_found():
    x = np.random.default_rng(1).normal(size=(2, 50))
    draws = {"a": x, "fixed": np.zeros((2, 50)), "copy": x * (1 + 1e-15), "other": x + 1}
    assert fixed_and_copies(draws, list(draws)) == ({"fixed": 0.0}, {"copy": "a"})


def test_marginal_panels_fill_their_figures_evenly():
    assert [even_chunk(n, 6) for n in (1, 6, 7, 19, 22, 24)] == [1, 6, 4, 5, 6, 6]


def test_a_fixed_parameter_gets_no_diagnostics_and_no_panel(run_dir):
    section = _section(run_dir, "fit:m2")
    rows = {r[0]: r for r in _table(section, "Posterior summary and diagnostics").rows}
    fixed = [r for r in rows.values() if r[1].endswith("(fixed)")]
    assert fixed and all(r[3:] == ("—", "—", "—") for r in fixed)
    assert "plate_snap_mm[0] · plate 0 mm" in [r[0] for r in fixed]            # named by its plate's height
    note = next(b for b in section.blocks if b.kind == "note" and b.text.startswith("Not drawn: "))
    assert "plate_snap_mm[0] · plate 0 mm = 0 at every draw (fixed)" in note.text
    assert re.search(r"plate_\w+_sd_mm\[0\] · plate 0 mm equals plate_\w*sd_mm\[0\] · plate 0 mm draw for draw",
                     note.text), note.text


def test_priors_show_matrices_as_rows():
    text = "K0 = [[4., 0., 0.], [0., 5., 0.], [0., 0., 4.]] N/mm"
    assert readable_prior(text) == "K0 = (4 0 0; 0 5 0; 0 0 4) N/mm"
    assert readable_prior("pse[10 um, 20/20 mm/s]") == "pse[10 µm, 20/20 mm/s]"


def test_the_demo_priors_hold_no_numpy_repr(run_dir):
    cells = [c for r in _table(_section(run_dir, "fit:m1"), "Priors").rows for c in r]
    assert not any("[[" in c or "4.," in c for c in cells) and any("(4 0 0; 0 5 0; 0 0 4)" in c for c in cells)


def test_the_footnote_states_the_rule_of_the_fits_backend(run_dir):
    assert independent_draws("m4", "exact (adaptive grid)") and independent_draws("finger-route", "grid (l0)")
    assert not independent_draws("m4", "nuts") and not independent_draws("m1", "exact")
    for key in ("fit:m4", "fit:finger-route"):
        caption = _table(_section(run_dir, key), "Posterior summary and diagnostics").caption
        assert RULE_INDEPENDENT in caption and "A fit passes with R-hat" not in caption, key
    caption = _table(_section(run_dir, "fit:m1"), "Posterior summary and diagnostics").caption
    assert "A fit passes with R-hat ≤ 1.01 and bulk ESS ≥ 400" in caption and "independent draws" in caption


def _drawn_panels(monkeypatch, run_dir, key):
    """(figure title, panel) of every visible panel the fit section of ``key`` draws."""
    import feeler.reports.fit_plots as fit_plots
    import feeler.reports.psy_plots as psy_plots

    panels, real = [], fit_plots.make_figure

    def keep(title, fig, sources, caption=""):
        panels.extend((title, ax) for ax in fig.axes if ax.get_visible())
        return real(title, fig, sources, caption)

    for module in (fit_plots, psy_plots):
        monkeypatch.setattr(module, "make_figure", keep)
    _section(run_dir, key)
    return panels


def test_every_marginal_panel_says_what_its_y_axis_is(monkeypatch, run_dir):
    """The posterior marginals had neither y ticks nor a y label (review s49, item 17): a
    panel without y ticks is labelled (a density, or the τ grid's density over its peak)."""
    from feeler.reports.fit_plots import DENSITY

    for key in ("fit:m1", "fit:m2", "fit:m4", "fit:finger-route"):
        panels = _drawn_panels(monkeypatch, run_dir, key)
        unlabelled = [(t, ax.get_title() or ax.get_xlabel()) for t, ax in panels
                      if not ax.get_yticks().size and not ax.get_ylabel()]
        assert panels and unlabelled == [], key
        assert any(ax.get_ylabel() == DENSITY for _, ax in panels), key


def test_the_finger_routes_lapse_is_a_density_not_a_comb(monkeypatch, run_dir):
    """The lapse's draws sit on the grid's 8 quantile nodes, and their histogram was a comb
    of 8 spikes (review s49, item 17): the panel draws the grid's density, positive from
    the first node to the last, with the nodes marked."""
    from feeler.calib.psychometric.finger_route import RouteGrid

    (ax,) = [ax for _, ax in _drawn_panels(monkeypatch, run_dir, "fit:finger-route") if ax.get_xlabel() == "lapse"]
    nodes = RouteGrid().lapses()
    (line,) = [ln for ln in ax.lines if ln.get_label() == "posterior"]
    x, y = line.get_xydata().T
    inner = (x >= nodes[0]) & (x <= nodes[-1])
    assert inner.sum() > 100 and np.all(y[inner] > 0) and not ax.patches           # no histogram bars
    marks = [ln for ln in ax.lines if ln.get_marker() == "^"]
    assert len(marks) == 1 and np.allclose(marks[0].get_xdata(), nodes)


def test_the_marginals_of_c_name_their_entry_and_unit(monkeypatch, run_dir):
    """The marginals of C were titled "C[0,0]" alone, with no axis label: a reader could not
    tell the unit (the forest plot above them says mm/N). Each now names its entry's axes
    and unit, as the forest plot does."""
    titles = [ax.get_title() for _, ax in _drawn_panels(monkeypatch, run_dir, "fit:m1") if ax.get_title()]
    c_titles = [t for t in titles if t.startswith("C[")]
    assert len(c_titles) == 9 and all(t.endswith("(mm/N)") and "←" in t for t in c_titles), titles
