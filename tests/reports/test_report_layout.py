"""Every figure's layout checked by code: the checker against figures made to fail each
check, then every figure of the demo report and the manifest that names them."""
from __future__ import annotations

import json

import numpy as np
import pytest

from feeler.reports.build import MANIFEST
from feeler.reports.layout import check_figure
from feeler.reports.model import make_figure, report_style, subplots


def _checked(fig):
    fig.canvas.draw()
    problems = check_figure(fig)
    import matplotlib.pyplot as plt
    plt.close(fig)
    return problems


def test_a_clean_figure_has_no_problems():
    with report_style():
        fig, ax = subplots(width_in=4, height_in=3)
        t = np.linspace(0, 1, 50)
        ax.plot(t, np.sin(6 * t), label="sine")
        ax.set(xlabel="t (s)", ylabel="y", title="clean")
        ax.legend(loc="upper right")
        assert _checked(fig) == ()


def test_overlapping_tick_labels_are_found():
    fig, ax = subplots(width_in=1.2, height_in=2)
    ax.plot([0.000001, 0.000002], [0, 1])
    ax.set_xticks(np.linspace(0.000001, 0.000002, 9))
    ax.ticklabel_format(axis="x", style="plain", useOffset=False)
    assert any("overlap" in p for p in _checked(fig))


def test_text_cut_at_the_edge_is_found():
    fig, ax = subplots(width_in=3, height_in=2, layout=None)
    ax.plot([0, 1], [0, 1])
    ax.annotate("l2 (converged)", (1.0, 0.5), xytext=(40, 0), textcoords="offset points", annotation_clip=False)
    assert any("cut at the figure's edge" in p and "l2 (converged)" in p for p in _checked(fig))


def test_a_text_across_a_panels_frame_is_found():
    fig, ax = subplots(width_in=3, height_in=2)
    ax.plot([0, 1], [0, 1])
    ax.set(xlim=(0, 1.02), title="counts")
    ax.annotate("38", (0.98, 0.5), xytext=(3, -8), textcoords="offset points")     # to the right of the point
    ax.annotate("inside", (0.5, 0.5))
    ax.text(1.1, 0.5, "beside", transform=ax.transAxes)                            # wholly outside: on purpose
    assert [p for p in _checked(fig) if "frame" in p] == ["panel 'counts': text '38' crosses its frame"]


def test_the_calibration_curves_counts_stay_inside_its_frame():
    """A count right of a point at confidence 0.98 crossed the right frame (review s49, item 17)."""
    from feeler.reports.sec_classify import _calibration

    conf = np.r_[np.full(38, 0.98), np.full(6, 0.75), np.full(2, 0.55), np.full(3, 0.05)]
    hit = np.r_[np.ones(38), np.ones(4), np.zeros(2), np.ones(2), np.zeros(3)].astype(bool)
    with report_style():
        figure = _calibration(conf, hit, 0.05, ("classify/classification.csv",))
    assert figure.problems == ()


def test_an_empty_panel_is_found():
    fig, axes = subplots(2, width_in=2.5, height_in=2)
    axes[0].plot([0, 1], [0, 1])
    axes[1].set_title("nothing")
    assert [p for p in _checked(fig) if "empty" in p] == ["panel 'nothing' is empty"]


def test_a_line_going_back_in_time_is_found():
    fig, ax = subplots(width_in=3, height_in=2)
    t = np.tile(np.linspace(0, 1, 5), 2)                  # two histories joined end to end
    ax.plot(t, np.arange(10), label="joined")
    ax.set(xlabel="t (s)", title="zig-zag")
    problems = _checked(fig)
    assert any("does not increase in time" in p and "'joined'" in p for p in problems)


def test_a_legend_over_the_data_is_found():
    fig, ax = subplots(width_in=3, height_in=2)
    x = np.linspace(0, 1, 30)
    for k in range(4):
        ax.plot(x, np.full_like(x, k), label=f"line {k}")
    ax.legend(loc="center")
    assert any("legend covers" in p for p in _checked(fig))


def test_make_figure_moves_a_covering_legend_out_of_the_way():
    with report_style():
        fig, ax = subplots(width_in=3, height_in=2)
        x = np.linspace(0, 1, 30)
        for k in range(4):
            ax.plot(x, np.full_like(x, k), label=f"line {k}")
        ax.legend(loc="center")
        figure = make_figure("moved", fig, ("x.csv",))
    assert figure.problems == () and figure.uri.startswith("data:image/png;base64,")


def test_every_figure_of_the_demo_report_is_clean_and_traced(report):
    manifest = json.loads((report / MANIFEST).read_text(encoding="utf-8"))
    figures = manifest["figures"]
    assert len(figures) >= 20 and [f["number"] for f in figures] == list(range(1, len(figures) + 1))
    assert [(f["number"], f["title"], f["layout_problems"]) for f in figures if f["layout_problems"]] == []
    for f in figures:
        assert f["sources"] and all((report / s).exists() for s in f["sources"]), f
    html = (report / "report.html").read_text(encoding="utf-8")
    assert html.count("<img ") == len(figures)
    for f in figures:
        # R: the report's own numbering, apart from the paper's "Fig. 7" its captions cite (an outside reader
        # found "Figure 7" and "Fig. 7" naming different figures)
        assert f'id="fig-{f["number"]}"' in html and f"Figure R{f['number']}. {f['title']}" in html.replace(
            "&#39;", "'").replace("&amp;", "&")


@pytest.mark.parametrize("title", ["Fig. 3: strain at the corpuscle", "Fig. 4: normalised pulse density",
                                   "Fig. 5: peak pulse density against step height",
                                   "Fig. 6: accepted against presented step height",
                                   "The skin fidelity ladder: seconds per slide against error",
                                   "Robot and human psychometric functions on one axis"])
def test_the_papers_figures_are_in_the_demo_report(report, title):
    manifest = json.loads((report / MANIFEST).read_text(encoding="utf-8"))
    assert title in [f["title"] for f in manifest["figures"]]
