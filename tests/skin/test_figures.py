"""The paper's Figs 3–6 claims, at small size with L2 (nonlinear contact, viscoelastic)."""
import dataclasses

import numpy as np
import pytest

from feeler.scene import load_scene
from feeler.simulate.finger import finger_runs
from feeler.skin.figures import figure_data
from tests.skin.conftest import SMALL
from tests.skin.test_scene_sim import SHIPPED


@pytest.fixture(scope="module")
def small_scene():
    scene = load_scene(SHIPPED)
    mesh = dataclasses.replace(scene.mesh, h_contact_mm=SMALL.h_contact_mm, h_corpuscle_mm=SMALL.h_corpuscle_mm,
                               h_far_mm=SMALL.h_far_mm, grade=SMALL.grade)
    loading = dataclasses.replace(scene.loading, travel_step_mm=0.05)
    return dataclasses.replace(scene, mesh=mesh, loading=loading,
                               model=dataclasses.replace(scene.model, level="l2"))


@pytest.fixture(scope="module")
def runs(small_scene):
    return finger_runs(small_scene)


def test_fig3_two_spikes_growing_with_height(runs):
    peaks = {}
    for r in runs:
        e = r.eps_y[r.slide_start:] - r.eps_y[r.slide_start]
        hi, lo = int(np.argmax(e)), int(np.argmin(e))
        assert e[hi] > 0 > e[lo] and hi < lo                    # tension spike, then compression
        x_hi, x_lo = r.x_mm[r.slide_start + hi], r.x_mm[r.slide_start + lo]
        assert 4.0 < x_hi < 5.0 < x_lo < 6.0                    # both within 1 mm of the step
        peaks.setdefault(r.speed_mm_s, []).append(e[hi] - e[lo])
    for v, p in peaks.items():
        assert np.all(np.diff(p) > 0)


def test_fig4_fig5_normalised_linear_and_faster_is_higher(runs, small_scene):
    data = figure_data(runs, small_scene.neuron, small_scene.loading.press_s)
    assert data.peak_z[-1, -1] == pytest.approx(1.0)
    assert max(z.max() for _, z in data.z_norm) == pytest.approx(1.0)
    for f in data.fits:
        assert f.r2 >= 0.98
    assert np.all(data.peak_z[:, 1] > data.peak_z[:, 0])          # 40 mm/s above 20 mm/s


def test_fig6_speed_effect_shrinks_with_tau(runs, small_scene):
    data = figure_data(runs, small_scene.neuron, small_scene.loading.press_s)
    assert np.all(np.diff(data.taus_s) > 0)
    assert np.all(np.diff(data.speed_ratio) < 0) and np.all(data.speed_ratio > 1.0)
    for k in range(len(data.taus_s)):
        acc = data.accepted_um[k]
        assert np.all(acc[:, 1] > acc[:, 0])                    # felt higher at 40 mm/s
        mean_slope = np.mean(data.heights_um @ acc / (data.heights_um @ data.heights_um))
        assert mean_slope == pytest.approx(1.0, rel=1e-12)      # κ from the mean regression slope


@pytest.mark.parametrize("tau_s", [0.001, 10.0])
def test_neuron_window_extremes(runs, small_scene, tau_s):
    neuron = dataclasses.replace(small_scene.neuron, tau_s=tau_s, tau_sweep_s=(tau_s,))
    data = figure_data(runs, neuron, small_scene.loading.press_s)
    assert np.all(np.isfinite(data.accepted_um)) and np.all(data.peak_z > 0)
    if tau_s >= 1.0:      # the window holds the whole slide: total variation, no speed effect
        assert data.speed_ratio[0] == pytest.approx(1.0, abs=1e-3)
    else:                 # a short window: u ≈ τ |ε̇| ∝ speed
        assert data.speed_ratio[0] == pytest.approx(2.0, rel=0.1)


def test_standalone_figures_are_the_reports_with_a_clean_layout(runs, small_scene, tmp_path):
    from feeler.skin.figures import plot_figures

    data = figure_data(runs, small_scene.neuron, small_scene.loading.press_s)
    human = [(10.0, 10.0, 9.8, 10.2, 20.0, "human PSE, standard at 20 mm/s")]
    out = plot_figures(runs, data, tmp_path, label="skin L2", tau_s=small_scene.neuron.tau_s,
                       step_mm=small_scene.steps.position_mm, human=human)
    assert [p.name for p, _ in out] == ["fig3_strain.png", "fig3_detail.png", "fig4_pulse_density.png",
                                        "fig5_peak_vs_height.png", "fig6_accepted.png"]
    assert [(p.name, problems) for p, problems in out if problems] == []
    assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p, _ in out)


def test_fig5_keeps_coinciding_speeds_visible_and_names_its_lines():
    from feeler.reports.finger_plots import fig5
    from feeler.reports.layout import check_figure

    heights = np.array([5.0, 10.0, 15.0])
    peaks = np.column_stack([heights / 15, heights / 15])           # the two speeds coincide exactly
    fig = fig5(heights, np.array([20.0, 40.0]), peaks, [(1 / 15, 0.0, 1.0), (1 / 15, 0.0, 1.0)])
    fig.canvas.draw()
    ax = fig.axes[0]
    points = [ln for ln in ax.lines if ln.get_linestyle() == "None"]
    assert len(points) == 2 and points[0].get_marker() != points[1].get_marker()
    assert points[0].get_markersize() > points[1].get_markersize()      # the one below stays visible
    lines = [ln for ln in ax.lines if ln.get_linestyle() != "None"]
    assert lines[0].get_linewidth() > 2 * lines[1].get_linewidth() and lines[0].get_zorder() < lines[1].get_zorder()
    labels = ax.get_legend_handles_labels()[1]
    assert labels == ["20 mm/s", "line, 20 mm/s (R² = 1.0000)", "40 mm/s", "line, 40 mm/s (R² = 1.0000)"]
    assert check_figure(fig) == ()


def test_fig6_shows_the_human_intervals_and_lines_that_coincide():
    """Fig. 6's 20 and 40 mm/s lines at τ = 300 ms lay one on the other, and the human
    PSEs' 95 % intervals (±0.2 µm) were shorter than their stars (an outside reader saw
    neither): the lower line is wider, and a panel shows each interval taller than its star."""
    from feeler.reports.finger_plots import fig6
    from feeler.reports.layout import check_figure

    heights = np.array([5.0, 7.5, 10.0, 12.5, 15.0])
    acc = np.stack([np.column_stack([0.8 * heights, 1.2 * heights]), np.column_stack([heights, heights])])
    human = [(10.0, 10.0, 9.84, 10.2, 20.0, "human, standard at 20 mm/s"),
             (10.0, 10.8, 10.5, 11.0, 40.0, "human, standard at 40 mm/s")]
    fig = fig6(np.array([0.01, 0.3]), heights, np.array([20.0, 40.0]), acc, human)
    fig.canvas.draw()
    assert check_figure(fig) == ()
    main = fig.axes[0]
    same = [ln for ln in main.lines if ln.get_label().startswith("τ = 300 ms")]
    assert len(same) == 2 and same[0].get_linewidth() > 2 * same[1].get_linewidth()
    px_per_pt = fig.dpi / 72
    for x, pse, lo, hi, _, _ in human:
        shown = []
        for ax in fig.axes:
            (y0, y1), (x0, x1) = ax.get_ylim(), ax.get_xlim()
            star = max(ln.get_markersize() for ln in ax.lines if ln.get_marker() == "*")
            span = np.ptp(ax.transData.transform([(x, lo), (x, hi)])[:, 1])
            shown.append(y0 < lo and hi < y1 and x0 < x < x1 and span > 2 * star * px_per_pt)
        assert any(shown), (pse, shown)


def test_ladder_plot_labels_fit_in_the_figure():
    from feeler.reports.finger_plots import ladder_trade
    from feeler.reports.layout import check_figure

    rows = [("l2", "converged", 1.99, 0.0), ("l1", "converged", 0.0094, 0.0078), ("l2", "coarsest", 0.78, 0.029),
            ("l1", "coarsest", 0.0025, 0.042), ("l0", "closed form", 0.00054, 0.354),
            ("l0-fitted", "closed form", 0.00032, 0.022)]
    fig = ladder_trade(rows)
    fig.canvas.draw()
    assert check_figure(fig) == ()
    assert "L2 (converged) = reference" in [t.get_text() for t in fig.legends[0].get_texts()]


def test_the_ladder_png_calls_its_finest_mesh_converged_only_when_the_study_says_so(tmp_path, monkeypatch):
    """The report's copy of the figure said "L2 (converged)" under "convergence: NOT met" (an
    outside reader); the study's own ladder.png now takes the same verdict."""
    from types import SimpleNamespace

    import feeler.reports.finger_plots as plots
    from feeler.skin.study import _plot_trade

    seen = []
    real = plots.ladder_trade
    monkeypatch.setattr(plots, "ladder_trade", lambda rows, converged=None: seen.append(converged) or real(rows, converged))
    trade = [SimpleNamespace(level="l2", mesh="converged", seconds_per_slide=1.99, rate_error=0.0),
             SimpleNamespace(level="l1", mesh="converged", seconds_per_slide=0.0094, rate_error=0.0078)]
    for verdict in (False, True):
        _plot_trade(trade, tmp_path / f"ladder_{verdict}.png", converged=verdict)
    assert seen == [False, True] and (tmp_path / "ladder_False.png").stat().st_size > 0
    fig = real([(t.level, t.mesh, t.seconds_per_slide, t.rate_error) for t in trade], False)
    assert "L2 (finest, reference)" in " ".join(t.get_text() for t in fig.legends[0].get_texts())
