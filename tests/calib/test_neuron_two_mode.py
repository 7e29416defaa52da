"""The two-mode noise models: touches that snap onto the upper level or ride over the edge."""
import dataclasses
import warnings

import numpy as np
import pytest

from feeler.calib.neuron import fit_neuron
from feeler.calib.neuron.classify import classify, scan_modes
from feeler.calib.neuron.decoder import DecoderDraws, isotonic_rows, monotone_curve
from feeler.calib.neuron.grid import two_mode_draws
from feeler.calib.neuron.model import PeakTable, Plates, make_priors, plate_stats
from feeler.calib.neuron.modes import Cells, snap_flags
from feeler.calib.neuron.synth import FOUR_PLATES, HARD_SCENES, scene_scans, single_window_table
from feeler.calib.neuron.window import continuous_log_density, loo_elpd
from feeler.errors import ArgumentError


def _scans_with_modes(path, seed, per_plate=None):
    from feeler.calib.neuron.data import data_from_scans
    from feeler.scene import load_scene
    from feeler.simulate import simulate_scans

    sc = load_scene(path)
    sc = dataclasses.replace(sc, scene=dataclasses.replace(sc.scene, seed=int(seed)))
    if per_plate:
        sc = dataclasses.replace(sc, repeats=dataclasses.replace(sc.repeats, scans_per_plate=per_plate))
    scans, touches = simulate_scans(sc, scene_path=path, progress=False)
    data = data_from_scans(scans, length_mm=sc.neuron.length_mm, kernel=sc.neuron.kernel)
    return data, np.array([bool(t["snaps"]) for t in touches])


@pytest.mark.parametrize("name, at_least", [("four-plates", 0.97), ("few-scans", 0.95), ("near-floor", 0.85)])
def test_the_mode_read_from_a_scan_agrees_with_the_simulated_touch(name, at_least):
    """The simulator records whether each touch snapped; the scan alone tells it (on the
    plates with a riser) for 0.97+ of four-plates' touches, 0.95+ of few-scans' (0.05 mm
    and up) and 0.85+ at the noise floor (0.01-0.03 mm steps, 1 um read-out)."""
    path = FOUR_PLATES if name == "four-plates" else HARD_SCENES / f"{name}.toml"
    data, truth = _scans_with_modes(path, 7, per_plate=40)
    riser = data.step_mm > 0
    flags = snap_flags(data.strain, data.step_mm)
    agree = np.mean(flags[riser] == truth[riser])
    print(f"\n{name}: mode read from the scan agrees with the touch on {agree:.3f} of {riser.sum()} touches")
    assert agree >= at_least
    assert not flags[~riser].any()                              # no riser, no snap
    np.testing.assert_array_equal(scan_modes(data.strain)[riser], flags[riser])    # the plate is not needed


def test_cells_index_the_modes_a_plate_shows():
    """(plate, mode) cells hold scans; a mode a plate never shows reads as the other."""
    plates = Plates.of([0, 0, 0.1, 0.1, 0.1, 0.2, 0.2], [False, False, False, True, True, True, True])
    cells = Cells(plates, plates.snap)
    np.testing.assert_array_equal(cells.index, [[0, 0], [1, 2], [3, 3]])
    np.testing.assert_array_equal(cells.as_plates.group, [0, 0, 1, 2, 2, 3, 3])
    np.testing.assert_array_equal(cells.as_plates.counts, [2, 1, 2, 2])
    np.testing.assert_array_equal(cells.as_plates.steps_mm, [0, 0.1, 0.1, 0.2])
    assert (cells.snaps, cells.rides, cells.size) == (4, 1, 4)


def test_two_mode_draws_recover_the_cells_and_the_share():
    """Many touches drawn from the model itself: every cell mean, σ and π inside their
    central 99 % posterior intervals, and the named plate mean and sd are the mixture's."""
    rng = np.random.default_rng(3)
    steps = np.repeat([0.0, 0.1, 0.2], 400)
    pi, sigma = 0.3, 0.02
    snap = (rng.random(steps.size) < pi) & (steps > 0)
    ride = {0.0: 1.0, 0.1: 1.5, 0.2: 2.0}
    gap = {0.0: 0.0, 0.1: 0.1, 0.2: 0.2}
    peaks = np.array([ride[s] + gap[s] * f for s, f in zip(steps, snap)]) + sigma * rng.standard_normal(steps.size)
    plates = Plates.of(steps, snap)
    table = single_window_table(peaks, 1.0)
    out = two_mode_draws(rng, np.ones(4000), table.at(np.ones(4000)), plates, make_priors(table))
    a = out["a"]
    lo, hi = np.quantile(out["snap_share"], [0.005, 0.995])
    share = snap[steps > 0].mean()
    assert lo < share < hi and abs(share - pi) < 0.06
    gaps = out["plate_snap_mm"] / a[:, None]
    for c, s in enumerate([0.0, 0.1, 0.2]):
        q = np.quantile(gaps[:, c], [0.005, 0.995])
        assert (q[0] <= gap[s] <= q[1]) if s > 0 else np.all(gaps[:, c] == 0)
    # the plate's sd (mm) is the mixture's: σ² + π(1 − π)·gap² in P units
    sd_p = out["plate_sd_mm"] / a[:, None]
    within = np.sqrt(sd_p ** 2 - (out["snap_share"] * (1 - out["snap_share"]))[:, None] * gaps ** 2)
    np.testing.assert_allclose(within, within[:, :1] * np.ones(3), rtol=1e-9)          # one σ
    assert np.quantile(within[:, 0], 0.005) < sigma < np.quantile(within[:, 0], 0.995)


def _decoder(snap_mm=None, share=None):
    rng = np.random.default_rng(0)
    S = 50
    mean = np.array([0.0, 0.1, 0.2]) + 0.002 * rng.standard_normal((S, 3))
    sd = 0.02 + 0.001 * rng.random((S, 3))
    return DecoderDraws(steps_mm=np.array([0.0, 0.1, 0.2]), tau_s=np.ones(S), a=np.ones(S), h=np.zeros(S),
                        mean_mm=mean, sd_mm=sd, snap_mm=snap_mm, snap_share=share)


def test_a_decoder_without_an_offset_reads_as_the_one_mode_decoder():
    one = _decoder()
    two = _decoder(np.zeros((50, 3)), np.full(50, 0.4))
    p = np.linspace(-0.05, 0.3, 9)[None, :].repeat(50, axis=0)
    for snap in (None, np.arange(9) % 2 == 0):
        np.testing.assert_allclose(two.class_log_prob(p, snap), one.class_log_prob(p), atol=1e-12)
        for x, y in zip(two.height(p, snap), one.height(p)):
            np.testing.assert_allclose(x, y, atol=1e-9)


def test_a_known_mode_reads_its_own_component():
    """With the scan's mode given, the plate probabilities are those of a one-mode decoder
    whose plates sit at that mode's means with the within-mode sd (closed form)."""
    S = 50
    rng = np.random.default_rng(1)
    gap = np.column_stack([np.zeros(S), 0.05 + 0.001 * rng.random(S), 0.06 + 0.001 * rng.random(S)])
    share = np.full(S, 0.5)
    within = _decoder().sd_mm
    two = dataclasses.replace(_decoder(gap, share), sd_mm=np.sqrt(within ** 2 + 0.25 * gap ** 2))
    p = np.linspace(0.0, 0.3, 7)[None, :].repeat(S, axis=0)
    for flag, shift in ((False, -0.5 * gap), (True, 0.5 * gap)):
        ref = dataclasses.replace(_decoder(), mean_mm=two.mean_mm + shift, sd_mm=within)
        np.testing.assert_allclose(two.class_log_prob(p, np.full(7, flag)), ref.class_log_prob(p), atol=1e-10)
        for x, y in zip(two.height(p, np.full(7, flag)), ref.height(p)):
            np.testing.assert_allclose(x, y, atol=1e-8)


def test_a_two_mode_fit_decodes_fresh_touches_and_live_ends_as_classify():
    """On few-scans (half the touches snap) the default fit picks a two-mode model; it
    classifies fresh touches better than one that ignores the modes, and a live decoder
    fed one scan sample by sample ends where classify does."""
    from feeler.calib.neuron.live import LiveDecoder
    from feeler.calib.neuron.synth import scene_scans

    path = HARD_SCENES / "few-scans.toml"
    _, _, train = scene_scans(path, seed=20040521)
    _, _, fresh = scene_scans(path, seed=20040521 + 10 ** 6, per_plate=60)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        two = fit_neuron(train, seed=1)
        one = fit_neuron(train, seed=1, noise="growing")
    assert two.posterior["posterior"].attrs["noise"].startswith("two-mode")
    truth = np.searchsorted(np.unique(train.step_mm), fresh.step_mm)
    c2 = classify(two, fresh.strain, fresh.t_s, rng=np.random.default_rng(0), n_draws=200)
    c1 = classify(one, fresh.strain, fresh.t_s, rng=np.random.default_rng(0), n_draws=200)
    ll2 = -np.mean(c2.log_prob[np.arange(truth.size), truth])
    ll1 = -np.mean(c1.log_prob[np.arange(truth.size), truth])
    print(f"\nlog-loss two-mode {ll2:.3f}, growing {ll1:.3f}")
    assert ll2 < ll1
    live = LiveDecoder(two, seed=0, n_draws=200)
    for k in (0, 61, 130, 200):
        live.reset()
        for t, u in zip(fresh.t_s if fresh.t_s.ndim == 1 else fresh.t_s[k], fresh.strain[k] * fresh.length_mm):
            live.push(float(t), float(u))
        end = live.finish()
        np.testing.assert_allclose(end.prob, c2.prob[k], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose([end.height_mm, end.lo90_mm, end.hi90_mm],
                                   [c2.height_mm[k], c2.lo90_mm[k], c2.hi90_mm[k]], rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("backend", ["nuts", "emcee"])
def test_the_two_mode_models_are_the_grid_backends(backend):
    from feeler.calib.neuron.synth import scene_scans

    _, _, data = scene_scans(per_plate=4)
    with pytest.raises(ArgumentError, match="two-mode models are drawn exactly"):
        fit_neuron(data, backend=backend, noise="two-mode")


def test_the_cli_says_why_a_two_mode_model_was_chosen(capsys, tmp_path):
    """Its leave-one-out score can be below a one-mode model's; the line says what the
    touches showed and why it was chosen anyway."""
    from feeler.cli import main

    run = tmp_path / "run"
    assert main(["simulate", str(HARD_SCENES / "few-scans.toml"), "--out", str(run), "--no-progress"]) == 0
    capsys.readouterr()
    main(["calibrate", "neuron", str(run), "--no-progress"])
    out = capsys.readouterr().out.splitlines()
    line = next(s for s in out if s.startswith("decoder noise:"))
    assert line.startswith("decoder noise: two-mode") and "touches of plates with a riser snapped onto the upper" in line
    assert "two standard errors" in line
    # the floor plate's snap offset is 0 at every draw: shown as fixed, not as R-hat nan
    floor = next(s for s in out if s.strip().startswith("plate_snap_mm[0]")).split()
    assert floor[-3:] == ["fixed", "-", "-"] and not any("nan" in s.split() for s in out)


@pytest.mark.parametrize("C", [2, 3, 4, 6, 8])
def test_isotonic_rows_equal_scipys_isotonic_regression(C):
    """The vectorised min–max formula against scipy's pool-adjacent-violators, row by row
    (ties included), and the defining properties: non-decreasing, the mean kept, and
    rows already in order left as they are."""
    from scipy.optimize import isotonic_regression

    rng = np.random.default_rng(C)
    x = rng.normal(size=(500, C)) + np.linspace(0.0, 1.0, C)
    x[::5] = np.round(x[::5], 1)
    got = isotonic_rows(x)
    np.testing.assert_allclose(got, [isotonic_regression(r).x for r in x], atol=1e-12)
    assert np.all(np.diff(got, axis=1) >= -1e-12)
    np.testing.assert_allclose(got.mean(axis=1), x.mean(axis=1), atol=1e-12)
    ordered = np.sort(x, axis=1)
    np.testing.assert_array_equal(monotone_curve(np.linspace(0, 1, C), ordered)[0], ordered)


def test_two_mode_leave_one_out_reads_a_scan_by_its_modes_monotone_curve():
    """Each scan left out in turn, its plates refitted from the others by hand: the cells'
    means, the pooled spread s·√(1 + 1/n_cell), the scan's own mode's curve made monotone
    as the decoder makes it, its end slopes bounded by the plates' (mixture) curve. The
    ride means are built to turn down (plate 2's rides lie below plate 1's), which the
    leave-one-out used to score −∞ at every window, ruling the model out."""
    rng = np.random.default_rng(4)
    steps = np.repeat([0.0, 0.05, 0.1, 0.2], 6)
    snap = np.tile([False, False, False, True, True, True], 4) & (steps > 0)
    ride = np.array([1.0, 2.4, 2.0, 5.0])[np.searchsorted([0.0, 0.05, 0.1, 0.2], steps)]
    p = ride + 1.5 * snap * (steps > 0) + 0.25 * rng.standard_normal(steps.size)
    plates = Plates.of(steps, snap)
    table = PeakTable(log_tau=np.log([1.0, 2.0]), peak=np.column_stack([p, 1.2 * p + 0.3]))
    got = loo_elpd(table, plates, "two-mode")
    assert np.all(np.isfinite(got))
    share = snap[steps > 0].mean()
    for j in range(2):
        ref = 0.0
        for k in range(p.size):
            keep = np.arange(p.size) != k
            cells = Cells(plates.subset(keep), snap[keep])
            mean, ss = plate_stats(table.peak[keep, j], cells.as_plates)
            var = ss.sum() / (keep.sum() - cells.size)
            sd = np.sqrt(var * (1 + 1 / cells.as_plates.counts))
            mode = int(snap[k])
            own, own_sd = mean[cells.index[:, mode]], sd[cells.index[:, mode]]
            mix = (1 - share) * mean[cells.index[:, 0]] + share * mean[cells.index[:, 1]]
            curve, ends = monotone_curve(plates.steps_mm, own, mix)
            ref += continuous_log_density(np.array(table.peak[k, j]), np.array(plates.group[k]), curve, own_sd,
                                          plates.steps_mm, ends)
        assert got[j] == pytest.approx(ref, rel=1e-10)
