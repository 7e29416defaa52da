"""The two-mode noise models: touches that snap onto the upper level or ride over the edge."""
import dataclasses
import re
import warnings

import numpy as np
import pandas as pd
import pytest

from feeler.calib.neuron import fit_neuron
from feeler.calib.neuron.classify import classify, scan_modes
from feeler.calib.neuron.decoder import DecoderDraws, isotonic_rows, monotone_curve
from feeler.calib.neuron.grid import two_mode_draws
from feeler.calib.neuron.model import PeakTable, Plates, make_priors, plate_stats
from feeler.calib.neuron.modes import Cells, own_spread_weight, snap_flags
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
    """Many touches drawn from the model itself: every cell mean, each mode's σ and π inside
    their central 99 % posterior intervals, and the named plate mean and sd are the mixture's."""
    rng = np.random.default_rng(3)
    steps = np.repeat([0.0, 0.1, 0.2], 400)
    pi, sigma = 0.3, {False: 0.02, True: 0.012}     # rides spread wider than snaps
    snap = (rng.random(steps.size) < pi) & (steps > 0)
    ride = {0.0: 1.0, 0.1: 1.5, 0.2: 2.0}
    gap = {0.0: 0.0, 0.1: 0.1, 0.2: 0.2}
    peaks = np.array([ride[s] + gap[s] * f + sigma[bool(f)] * rng.standard_normal() for s, f in zip(steps, snap)])
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
    # each mode's sd (one σ for its cells, constant noise) covers the truth; the plate's sd (mm) is
    # the mixture's: (1 − π)σ_r² + πσ_s² + π(1 − π)·gap² in P units
    ride_sd, snap_sd = out["plate_ride_sd_mm"] / a[:, None], out["plate_snap_sd_mm"] / a[:, None]
    for within, truth in ((ride_sd, sigma[False]), (snap_sd[:, 1:], sigma[True])):
        np.testing.assert_allclose(within, within[:, :1] * np.ones(within.shape[1]), rtol=1e-9)
        assert np.quantile(within[:, 0], 0.005) < truth < np.quantile(within[:, 0], 0.995)
    assert np.corrcoef(ride_sd[:, 0], snap_sd[:, 1])[0, 1] < 0.1          # drawn apart
    np.testing.assert_allclose(snap_sd[:, 0], ride_sd[:, 0])              # the floor has no snaps: its rides'
    pi_s = out["snap_share"][:, None]
    np.testing.assert_allclose(out["plate_sd_mm"] / a[:, None], np.sqrt(
        (1 - pi_s) * ride_sd ** 2 + pi_s * snap_sd ** 2 + pi_s * (1 - pi_s) * gaps ** 2), rtol=1e-9)
    shared = two_mode_draws(rng, np.ones(400), table.at(np.ones(400)), plates, make_priors(table), shared_spread=True)
    np.testing.assert_array_equal(shared["plate_ride_sd_mm"], shared["plate_snap_sd_mm"])


def _mode_scans(rng, sd_ride, sd_snap, per_cell, growth=0.0):
    """Peaks of three risers (0.1, 0.2, 0.3 mm) and a floor, ``per_cell`` touches in each
    (plate, mode) cell (the floor: rides only), sd σ·exp(growth·x) in each mode."""
    steps, snap, peaks = [], [], []
    for c, step in enumerate([0.0, 0.1, 0.2, 0.3]):
        for mode, sd in ((False, sd_ride), (True, sd_snap)):
            if mode and step == 0:
                continue
            scale = sd * np.exp(growth * c / 3)
            steps += [step] * per_cell
            snap += [mode] * per_cell
            peaks += list(1.0 + 5 * step + 0.3 * mode * step + scale * rng.standard_normal(per_cell))
    return np.array(steps), np.array(snap), np.array(peaks)


def test_own_spread_weight_is_the_bic_weight_of_the_restricted_likelihoods():
    """Constant spread: Λ in closed form from the pooled variances (each cell's mean taken
    out: r_c = n_c − 1 degrees of freedom), w = expit((Λ − ln n)/2). Growing spread: Λ
    against a numerical maximum of Σ_c −r_c ln σ_c − SS_c / 2σ_c² over (σ₀, g), the sums of
    squares computed from the scans here, not by plate_stats."""
    from scipy.optimize import minimize
    from scipy.special import expit

    rng = np.random.default_rng(11)
    steps, snap, peaks = _mode_scans(rng, 0.02, 0.012, 6, growth=0.7)
    cells = Cells(Plates.of(steps, snap), snap)
    group = cells.as_plates.group
    ss = np.array([np.sum((peaks[group == k] - peaks[group == k].mean()) ** 2) for k in range(cells.size)])
    r = cells.as_plates.counts - 1.0
    n = steps.size

    def pooled(sel):
        return -0.5 * r[sel].sum() * np.log(ss[sel].sum() / r[sel].sum())
    modes = [cells.mode == k for k in (0, 1)]
    lam = 2 * (pooled(modes[0]) + pooled(modes[1]) - pooled(np.ones(cells.size, bool)))
    np.testing.assert_allclose(own_spread_weight(ss[None], cells, "constant"), expit(0.5 * (lam - np.log(n))),
                               rtol=1e-10)

    def best(sel, x):
        def neg(theta):
            log_sd = theta[0] + theta[1] * x
            return np.sum(r[sel] * log_sd + 0.5 * ss[sel] * np.exp(-2 * log_sd))
        return -min(minimize(neg, [np.log(0.02), g0], bounds=[(-10, 2), (-3, 3)]).fun for g0 in (-1.0, 0.0, 1.0))
    x_all = cells.as_plates.x
    x_own = [cells.of_mode(k)[2].x for k in (0, 1)]
    lam_g = 2 * (best(modes[0], x_own[0]) + best(modes[1], x_own[1]) - best(np.ones(cells.size, bool), x_all))
    w = own_spread_weight(ss[None], cells, "growing")[0]
    lam_grid = 2 * np.log(w / (1 - w)) + 2 * np.log(n)
    assert lam_g > 0 and abs(lam_grid - lam_g) < 0.02 * max(1.0, lam_g)


def test_own_spreads_where_the_modes_spread_apart_one_curve_where_they_do_not():
    """Two modes of equal spread (8 touches a cell): the BIC weight of a curve each is small
    (40 datasets: median under 0.05); spreads 2.5 times apart (16 a cell): over 0.99 in all
    40. two_mode_draws gives that share of its draws a curve each, the rest one for both; a
    cell that never varies leaves the weight finite."""
    rng = np.random.default_rng(5)
    for sd_snap, per_cell in ((0.02, 8), (0.008, 16)):
        w = []
        for _ in range(40):
            steps, snap, peaks = _mode_scans(rng, 0.02, sd_snap, per_cell)
            plates = Plates.of(steps, snap)
            cells = Cells(plates, snap)
            table = single_window_table(peaks, 1.0)
            w.append(own_spread_weight(plate_stats(table.at(np.ones(1)), cells.as_plates)[1], cells, "growing")[0])
        if sd_snap == 0.02:
            assert np.median(w) < 0.05 and np.mean(w) < 0.15
        else:
            assert min(w) > 0.99
        out = two_mode_draws(rng, np.ones(2000), table.at(np.ones(2000)), plates, make_priors(table),
                             within="growing")
        apart = np.mean(~np.isclose(out["plate_ride_sd_mm"][:, 1], out["plate_snap_sd_mm"][:, 1], rtol=1e-12))
        assert abs(apart - w[-1]) < 0.04
    ss = np.array([[0.0, 0.1, 0.2, 0.0, 0.3, 0.1, 0.2]])
    assert np.isfinite(own_spread_weight(ss, cells, "growing")).all()


def test_each_mode_has_a_spread_curve_of_its_own_only_with_the_scans_for_it():
    """Cells.own_spreads needs OWN_SPREAD_DOF scans more than cells in each mode; of_mode
    gives each mode's cells as plates, the snaps' starting at the lowest riser."""
    steps = np.repeat([0.0, 0.1, 0.2], 4)
    snap = np.zeros(12, bool)
    snap[[4, 5, 8, 9]] = True                       # 2 snaps on each riser: 4 scans, 2 cells
    cells = Cells(Plates.of(steps, snap), snap)
    assert not cells.own_spreads                    # 4 − 2 < 3
    keep, scans, sub = cells.of_mode(1)
    np.testing.assert_array_equal(sub.steps_mm, [0.1, 0.2])
    np.testing.assert_array_equal(sub.x, [0.0, 1.0])
    np.testing.assert_array_equal(scans, snap)
    np.testing.assert_array_equal(cells.mode[keep], [1, 1])
    snap[[6, 7, 10]] = True                         # snaps 7 in 2 cells, rides 5 in 2 (plate 0.1 has none)
    cells = Cells(Plates.of(steps, snap), snap)
    assert cells.own_spreads                        # 7 − 2 and 5 − 2 ≥ 3
    _, _, rides = cells.of_mode(0)
    np.testing.assert_array_equal(rides.steps_mm, [0.0, 0.2])
    np.testing.assert_array_equal(rides.counts, [4, 1])
    steps = np.array([0, 0, 0.1, 0.1, 0.1, 0.1, 0.2, 0.2, 0.2, 0.2])
    snap = np.array([0, 0, 1, 1, 1, 0, 1, 1, 1, 0], bool)
    assert not Cells(Plates.of(steps, snap), snap).own_spreads          # rides 4 − 3 < 3


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


def _mode_decoder(S=50):
    """A two-mode decoder whose ride draws (window 1 s, γ 0.8) and snap draws (window 3 s,
    γ 1.6) differ in every parameter."""
    rng = np.random.default_rng(5)
    ride = dataclasses.replace(_decoder(0.05 + 0.002 * rng.random((S, 3)), np.full(S, 0.4)), sharpness=0.8)
    snap = dataclasses.replace(_decoder(0.08 + 0.002 * rng.random((S, 3)), np.full(S, 0.6)), sharpness=1.6,
                               tau_s=np.full(S, 3.0), a=np.full(S, 1.1), h=np.full(S, 0.01),
                               mean_mm=ride.mean_mm[::-1] * 0.9 + 0.01)
    joined = dataclasses.replace(ride, **{k: np.concatenate([getattr(ride, k), getattr(snap, k)])
                                          for k in ("tau_s", "a", "h", "mean_mm", "sd_mm", "snap_mm", "snap_share")},
                                 draw_mode=np.repeat([0, 1], S), mode_sharpness=(0.8, 1.6), sharpness=1.0)
    return ride, snap, joined


def test_each_mode_is_read_by_its_own_draws():
    """With a decoder per mode, a ride scan's plate probabilities and height interval are
    those of the ride draws alone (with the rides' γ), a snap's those of the snap draws;
    a scan whose mode is unknown is read by every draw (the mixture, the joint γ)."""
    ride, snap, joined = _mode_decoder()
    S = ride.size
    rng = np.random.default_rng(6)
    p = 0.2 * rng.random((2 * S, 8))                                   # P at each draw's window
    flags = np.array([0, 1, 1, 0, 1, 0, 0, 1], bool)
    got = joined.class_log_prob(p, flags)
    heights = joined.height(p, flags)
    for part, rows, sel in ((ride, slice(0, S), ~flags), (snap, slice(S, 2 * S), flags)):
        np.testing.assert_allclose(got[sel], part.class_log_prob(p[rows][:, sel], flags[sel]), atol=1e-12)
        for x, y in zip(heights, part.height(p[rows][:, sel], flags[sel])):
            np.testing.assert_allclose(x[sel], y, atol=1e-8)
    assert np.max(np.abs(got[~flags] - joined.class_log_prob(p, np.zeros(8, bool))[~flags])) < 1e-12
    assert np.max(np.abs(got[flags] - joined.class_log_prob(p, np.zeros(8, bool))[flags])) > 0.01
    both = dataclasses.replace(joined, draw_mode=None, mode_sharpness=None)
    np.testing.assert_allclose(joined.class_log_prob(p), both.class_log_prob(p), atol=1e-12)
    np.testing.assert_array_equal(joined.take(np.arange(S - 5, S + 5)).draw_mode, [0] * 5 + [1] * 5)


def test_each_modes_draws_sit_at_the_windows_that_read_that_mode():
    """Rides that tell their plates apart only at the long window, snaps only at the short
    one: the joint weights split between the windows, the rides' decoder sits at the long
    one and the snaps' at the short one, each with its own γ."""
    from feeler.calib.neuron.fit import mode_decoders
    rng = np.random.default_rng(8)
    steps = np.repeat([0.0, 0.05, 0.1, 0.15], 16)
    snap = np.tile([False, True], 32) & (steps > 0)
    level = steps / 0.05
    short = np.where(snap, 1.0 + level, 1.0) + 0.15 * rng.standard_normal(steps.size)
    long = np.where(snap, 2.0, 1.0 + level) + 0.15 * rng.standard_normal(steps.size)
    table = PeakTable(log_tau=np.log([0.5, 4.0]), peak=np.column_stack([short, long]))
    plates = Plates.of(steps, snap)
    pri = make_priors(table)
    elpd = loo_elpd(table, plates, "two-mode", pointwise=True)
    out = mode_decoders(table, plates, pri, "two-mode", elpd, chains=2, draws=200, rng=rng)
    assert set(out) == {"ride", "snap"} and out["ride"]["scans"] == 40 and out["snap"]["scans"] == 24
    assert np.median(out["ride"]["draws"]["tau_s"]) > 2.0 > np.median(out["snap"]["draws"]["tau_s"])
    assert out["ride"]["draws"]["plate_mean_mm"].shape == (2, 200, 4)
    # floor scans whose noise reads as a snap when the plate is unknown are read by the snaps'
    # decoder in classify, so its window and γ are fitted with them
    read = snap.copy()
    read[:3] = True
    mixed = Plates.of(steps, snap, read)
    out = mode_decoders(table, mixed, pri, "two-mode", loo_elpd(table, mixed, "two-mode", pointwise=True),
                        chains=1, draws=50, rng=rng)
    assert out["ride"]["scans"] == 37 and out["snap"]["scans"] == 27
    assert out["snap"]["mask"][:3].all() and not out["ride"]["mask"][:3].any()
    few = Plates.of(steps, snap & (np.arange(steps.size) < 12))      # 5 snaps: no decoder per mode
    assert mode_decoders(table, few, pri, "two-mode", loo_elpd(table, few, "two-mode", pointwise=True),
                         chains=1, draws=50, rng=rng) == {}


def test_loo_reading_exact_cases():
    """Accuracy and log score of the left-out scans against the plates' shares: a decoder
    sure and right, one at even odds (no better than the shares of balanced plates), one
    sure and wrong, and the shares of unbalanced plates."""
    from feeler.calib.neuron.fit import loo_reading
    g = np.array([0, 1, 2, 2])
    sure = np.log(np.full((4, 3), 1e-6))
    sure[np.arange(4), g] = np.log(1 - 2e-6)
    r = loo_reading(sure, g)
    base = 0.5 * np.log(0.25) + 0.5 * np.log(0.5)
    assert r["accuracy"] == 1.0 and r["log_score"] == pytest.approx(np.log(1 - 2e-6))
    assert r["base_accuracy"] == 0.5 and r["base_log_score"] == pytest.approx(base) and r["informative"]
    even = loo_reading(np.full((3, 3), -np.log(3)), np.array([0, 1, 2]))
    assert even["log_score"] == pytest.approx(even["base_log_score"]) == pytest.approx(-np.log(3))
    assert not even["informative"]
    wrong = loo_reading(np.roll(sure, 1, axis=1), g)         # each scan read as the next plate up
    assert wrong["accuracy"] == 0.0 and not wrong["informative"]


def test_a_mode_that_reads_at_chance_is_named():
    """Rides whose peaks do not depend on the plate at any window, snaps that tell their
    plates apart: the rides' leave-one-out reading is no better than the plates' shares,
    the snaps' is, and the fit's CLI lines say so of the rides only."""
    import json

    from feeler.calib.neuron.fit import mode_decoders
    from feeler.commands._calibrate_neuron import mode_lines
    rng = np.random.default_rng(12)
    steps = np.repeat([0.0, 0.05, 0.1, 0.15], 16)
    snap = np.tile([False, True], 32) & (steps > 0)
    level = steps / 0.05
    peaks = [np.where(snap, 1.0 + level, 1.0) + 0.15 * rng.standard_normal(steps.size) for _ in range(2)]
    table = PeakTable(log_tau=np.log([0.5, 4.0]), peak=np.column_stack(peaks))
    plates = Plates.of(steps, snap)
    elpd = loo_elpd(table, plates, "two-mode", pointwise=True)
    out = mode_decoders(table, plates, make_priors(table), "two-mode", elpd, chains=2, draws=200, rng=rng)
    ride, snapped = out["ride"]["loo"], out["snap"]["loo"]
    assert not ride["informative"] and ride["log_score"] <= ride["base_log_score"]
    assert snapped["informative"] and snapped["accuracy"] > 0.9
    assert ride["base_accuracy"] == pytest.approx(16 / 40)                # the floor plate's 16 of 40 rides
    lines = mode_lines(json.loads(json.dumps({k: {"sharpness": v["sharpness"], "scans": v["scans"], "tau_s": 1.0,
                                                  "loo": v["loo"]} for k, v in out.items()})))
    assert lines[0].startswith("decoded by mode: rides at a window of about 1 s") and "40 scans; " in lines[0]
    assert len(lines) == 2 and lines[1].startswith("note: rides read no better when left out than their plates' "
                                                   "shares alone (log score per scan -")


def test_no_decoder_per_mode_when_a_modes_draws_cannot_be_read(monkeypatch):
    """A mode whose draws leave more lines undecodable than classify reads (here 6 % of the
    rides' draws with a = NaN) gives no decoder per mode: the fit decodes with its joint
    draws, which its verdict checked. 4 % (within the limit) keeps them."""
    import feeler.calib.neuron.grid as grid_module
    from feeler.calib.neuron.decoder import undecodable_draws
    from feeler.calib.neuron.fit import mode_decoders
    rng = np.random.default_rng(8)
    steps = np.repeat([0.0, 0.05, 0.1, 0.15], 16)
    snap = np.tile([False, True], 32) & (steps > 0)
    peaks = np.where(snap, 1.5, 1.0) + steps / 0.05 + 0.15 * rng.standard_normal(steps.size)
    table = single_window_table(peaks, 1.0)
    plates = Plates.of(steps, snap)
    pri = make_priors(table)
    elpd = loo_elpd(table, plates, "two-mode", pointwise=True)
    original = grid_module.sample_grid
    for share, kept in ((0.06, False), (0.04, True)):
        calls = []

        def spoiled(*args, **kwargs):
            out = original(*args, **kwargs)
            if not calls:                                   # the rides' draws
                a = out["a"].copy()
                a.reshape(-1)[: int(share * a.size)] = np.nan
                out["a"] = a
                assert undecodable_draws(out).mean() == pytest.approx(share, abs=1e-3)
            calls.append(1)
            return out
        monkeypatch.setattr(grid_module, "sample_grid", spoiled)
        out = mode_decoders(table, plates, pri, "two-mode", elpd, chains=2, draws=500, rng=rng)
        assert calls and bool(out) == kept


def test_a_two_mode_fit_decodes_fresh_touches_and_live_ends_as_classify(tmp_path):
    """On few-scans (half the touches snap) the default fit picks a two-mode model with a
    decoder per mode; it classifies fresh touches better than one that ignores the modes,
    reads them the same once saved and loaded, and a live decoder fed one scan sample by
    sample ends where classify does."""
    from feeler.calib.fit import load
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
    assert {"ride_decoder", "snap_decoder"} <= set(two.posterior.children)
    assert DecoderDraws.from_result(two, rng=np.random.default_rng(0), n_draws=1).draw_mode.tolist() == [0, 1]
    back = classify(load(two.save(tmp_path / "fit")), fresh.strain, fresh.t_s, rng=np.random.default_rng(0),
                    n_draws=200)
    np.testing.assert_allclose(back.log_prob, c2.log_prob, atol=1e-12)
    np.testing.assert_allclose(back.hi90_mm, c2.hi90_mm, atol=1e-12)
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
    modes = next(s for s in out if s.startswith("decoded by mode:"))
    read = r"(\d+) % read as their plate when left out, the most common plate alone \d+ %"
    got = re.fullmatch(r"decoded by mode: rides at a window of about [0-9.]+ s \(gamma [0-9.]+, (\d+) scans; " + read
                       + r"\), snaps at a window of about [0-9.]+ s \(gamma [0-9.]+, (\d+) scans; " + read + r"\); .*",
                       modes)
    assert got, modes
    # the whole set reads as classify reads it: each scan by its mode's decoder
    whole = re.fullmatch(r"leave-one-out reading: (\d+) of (\d+) training scans \((\d+) %\) read as their own plate "
                         r"when each is left out, against \d+ % for the most common plate alone; log score per scan -[0-9.]+ \(the plates' "
                         r"shares alone: -[0-9.]+\)", next(s for s in out if s.startswith("leave-one-out reading:")))
    assert whole, [s for s in out if s.startswith("leave-one-out")]
    n_ride, acc_ride, n_snap, acc_snap = (int(x) for x in got.groups())
    assert int(whole[2]) == n_ride + n_snap
    assert abs(int(whole[1]) - (n_ride * acc_ride + n_snap * acc_snap) / 100) <= 1      # the printed % are rounded
    # the floor plate's snap offset is 0 at every draw: shown as fixed, not as R-hat nan
    floor = next(s for s in out if s.strip().startswith("plate_snap_mm[0]")).split()
    assert floor[-3:] == ["fixed", "-", "-"] and not any("nan" in s.split() for s in out)


@pytest.fixture(scope="module")
def fast_frames_fit(tmp_path_factory):
    """(run, fit): hard/exponential-fast-frames simulated and fitted by the CLI (two modes,
    a decoder per mode)."""
    from feeler.cli import main
    tmp = tmp_path_factory.mktemp("fast-frames")
    run, fit = tmp / "run", tmp / "fit"
    assert main(["simulate", str(HARD_SCENES / "exponential-fast-frames.toml"), "--out", str(run),
                 "--no-progress"]) == 0
    assert main(["calibrate", "neuron", str(run), "--out", str(fit), "--no-progress"]) == 0
    return run, fit


def test_the_fit_reads_its_training_scans_as_classify_reads_them(fast_frames_fit):
    """The fit's leave-one-out reading of the whole set reads each scan by its mode's
    decoder, as classify does: its accuracy and log score are the modes' weighted by their
    scans (on exponential-fast-frames the joint decoder alone reads 40 of 60, the modes 45)."""
    import json

    import xarray as xr

    with xr.open_datatree(fast_frames_fit[1] / "posterior.nc") as tree:
        attrs = dict(tree["posterior"].attrs)
    whole, modes = json.loads(attrs["loo_reading"]), json.loads(attrs["mode_decoders"])
    n = sum(v["scans"] for v in modes.values())
    for key in ("accuracy", "log_score"):
        assert whole[key] == pytest.approx(sum(v["scans"] * v["loo"][key] for v in modes.values()) / n, abs=1e-12)
    assert modes["snap"]["loo"]["accuracy"] > modes["ride"]["loo"]["accuracy"]


def test_classify_notes_new_scans_of_a_mode_the_fit_reads_at_chance(fast_frames_fit, tmp_path, capsys):
    """classify says how many new scans are of a mode whose training scans the fit reads no
    better than their plates' shares (here the rides, marked so in a real two-mode fit's
    record), counting them as the decoder read them; nothing for a mode that reads well."""
    import json
    import shutil
    from pathlib import Path

    import xarray as xr

    from feeler.cli import main
    from feeler.calib.neuron.classify import chance_mode_notes
    run, fit = fast_frames_fit
    capsys.readouterr()
    assert main(["classify", str(fit), str(run), "--no-progress"]) == 0
    assert "which this fit reads no better" not in capsys.readouterr().out        # both modes read well here
    marked = Path(shutil.copytree(fit, tmp_path / "marked"))
    with xr.open_datatree(fit / "posterior.nc") as stored:
        tree = stored.load()
    modes = json.loads(tree["posterior"].attrs["mode_decoders"])
    modes["ride"]["loo"] |= {"informative": False, "log_score": -1.5, "base_log_score": -1.3}
    tree["posterior"].attrs["mode_decoders"] = json.dumps(modes)
    tree.to_netcdf(marked / "posterior.nc")
    assert main(["classify", str(marked), str(run), "--no-progress"]) == 0
    notes = [s for s in capsys.readouterr().out.splitlines() if "which this fit reads no better" in s]
    scans = pd.read_csv(run / "scans.csv")
    strain = np.stack([g.sort_values("t_s")["uy_mm"].to_numpy() for _, g in scans.groupby("scan_id")])
    rides = int(np.sum(~scan_modes(strain)))
    assert notes == [f"note: {rides} of {len(strain)} scans are rides, which this fit reads no better than its "
                     f"training rides' plate shares when each is left out (log score per scan -1.500 against "
                     f"-1.300): their plate probabilities say little"]
    # the live decoder reads each scan's mode at its end as classify does, and says the same
    assert main(["decode", str(marked), str(run), "--out", str(tmp_path / "live"), "--no-progress"]) == 0
    assert [s for s in capsys.readouterr().out.splitlines() if "which this fit reads no better" in s] == notes
    assert main(["decode", str(fit), str(run), "--out", str(tmp_path / "live2"), "--no-progress"]) == 0
    assert "which this fit reads no better" not in capsys.readouterr().out
    assert chance_mode_notes({"mode_decoders": json.dumps(modes)}, None) == []     # a one-mode reading: no modes



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
    share = snap[steps > 0].mean()
    for shared in (False, True):      # each mode's cells pooled apart (15 rides in 4 cells, 9 snaps in 3), or all
        got = loo_elpd(table, plates, "two-mode", shared_spread=shared)
        assert np.all(np.isfinite(got))
        for j in range(2):
            ref = 0.0
            for k in range(p.size):
                keep = np.arange(p.size) != k
                cells = Cells(plates.subset(keep), snap[keep])
                mean, ss = plate_stats(table.peak[keep, j], cells.as_plates)
                mode = int(snap[k])
                # each cell's spread from its mode's pool (the floor's snap view is its ride cell)
                pools = [np.ones(cells.size, bool)] * 2 if shared else [cells.mode == 0, cells.mode == 1]
                var = np.array([ss[q].sum() / (cells.as_plates.counts[q].sum() - q.sum()) for q in pools])
                sd = np.sqrt(var[cells.mode] * (1 + 1 / cells.as_plates.counts))
                own, own_sd = mean[cells.index[:, mode]], sd[cells.index[:, mode]]
                mix = (1 - share) * mean[cells.index[:, 0]] + share * mean[cells.index[:, 1]]
                curve, ends = monotone_curve(plates.steps_mm, own, mix)
                ref += continuous_log_density(np.array(table.peak[k, j]), np.array(plates.group[k]), curve, own_sd,
                                              plates.steps_mm, ends)
            assert got[j] == pytest.approx(ref, rel=1e-10)


def test_a_scan_alone_in_its_mode_on_its_plate_does_not_score_the_sharpness():
    """Left out, a snap that is its plate's only snap leaves no snap cell there, and the
    leave-one-out reads it by the rides' curve: 1.5 above its plate's rides it reads as
    the next plate, confidently, though no new snap of that plate meets an empty cell.
    Such scans pulled the sharpness γ down: on a random untuned scene (12 touches a plate,
    14 % snaps, 8 training sets) the fits were under-confident (accuracy 0.83, ECE 0.053;
    0.032 without them). Under a two-mode model they now get even odds, as a scan alone
    on its plate does; one-mode models keep them."""
    from feeler.calib.neuron.window import alone, loo_class_cond

    rng = np.random.default_rng(7)
    levels = np.array([0.0, 0.05, 0.1, 0.2])
    steps = np.repeat(levels, 6)
    snap = np.zeros(steps.size, bool)
    snap[[7, 8, 9, 13, 14, 15]] = True          # three snaps on 0.05 mm, three on 0.1 mm
    lone = 19                                   # the only snap of the 0.2 mm plate
    snap[lone] = True
    ride = np.searchsorted(levels, steps).astype(float)
    p = ride + 1.5 * snap + 0.2 * rng.standard_normal(steps.size)
    plates = Plates.of(steps, snap)
    table = PeakTable(log_tau=np.log([1.0, 2.0]), peak=np.column_stack([p, 1.1 * p + 0.2]))

    assert np.flatnonzero(alone(plates, "two-mode")).tolist() == [lone]
    assert not alone(plates).any() and not alone(plates, "constant").any()
    cond = loo_class_cond(table, plates, "two-mode")
    np.testing.assert_allclose(cond[:, lone, :], -np.log(levels.size))          # even odds
    others = np.delete(np.arange(steps.size), lone)
    assert np.all(np.max(cond[:, others, :], axis=2) > np.log(0.5))             # the others are read
    assert np.max(loo_class_cond(table, plates, "constant")[:, lone, :]) > np.log(0.5)


def _two_mode_peaks(seed):
    """Six touches on each of four plates, three of each riser's snapping; the snaps
    spread 0.1, the rides 0.3 (units of P), at two windows: PeakTable and Plates."""
    rng = np.random.default_rng(seed)
    levels = [0.0, 0.05, 0.1, 0.2]
    steps = np.repeat(levels, 6)
    snap = np.tile([False, False, False, True, True, True], 4) & (steps > 0)
    p = np.searchsorted(levels, steps) + 1.5 * snap + np.where(snap, 0.1, 0.3) * rng.standard_normal(steps.size)
    table = PeakTable(log_tau=np.log([1.0, 2.0]), peak=np.column_stack([p, 1.2 * p + 0.3]))
    return table, Plates.of(steps, snap)


@pytest.mark.parametrize("floor_read_as_snaps", [0, 2])
def test_class_leave_one_out_of_a_two_mode_model_by_hand(floor_read_as_snaps):
    """loo_class_cond (the probabilities the sharpness γ is fitted on), each scan left out
    in turn and its plates refitted by hand: the cells' means in the mode the scan is read
    in as classify reads a new scan, the plate unknown (the floor has no snap cell: a snap
    reads its ride cell), their variance pooled over the cells of that mode (each mode has
    the scans for a curve of its own), a Student-t with that pool's scans less its cells as
    degrees of freedom and scale s·√(1 + 1/n_cell), normalised over the plates.

    A flat plate's scan never snaps, so its cell is a ride's, but its noise can read as a
    snap when the plate is not known: classify then reads it with the snaps' cells of the
    other plates. The leave-one-out read every floor scan as a ride (random scene 13 of an
    untuned family: 4-9 of 10 floor scans a training set read as snaps, and the snaps'
    decoder, its γ and window fitted on riser snaps alone, read its training scans at
    accuracy 1.0 and fresh snaps at 0.90-0.93)."""
    from scipy import stats

    from feeler.calib.neuron.window import loo_class_cond

    table, known = _two_mode_peaks(11)
    snap = known.snap
    read = snap.copy()
    read[:floor_read_as_snaps] = True                       # the first floor scans read as snaps
    plates = Plates.of(known.steps_mm[known.group], snap, read)
    assert Cells(plates, snap).own_spreads                  # rides 15 in 4 cells, snaps 9 in 3
    got = loo_class_cond(table, plates, "two-mode")
    for k in range(snap.size):
        keep = np.arange(snap.size) != k
        cells = Cells(plates.subset(keep), snap[keep])
        mode = int(read[k])
        pools = [cells.mode == 0, cells.mode == 1]
        dof = np.array([cells.as_plates.counts[q].sum() - q.sum() for q in pools], float)
        cell = cells.index[:, mode]
        for j in range(2):
            mean, ss = plate_stats(table.peak[keep, j], cells.as_plates)
            var = np.array([ss[q].sum() for q in pools]) / dof
            sd = np.sqrt(var[cells.mode] * (1 + 1 / cells.as_plates.counts))
            ll = stats.t.logpdf(table.peak[k, j], dof[mode], mean[cell], sd[cell])
            np.testing.assert_allclose(got[j, k], ll - np.logaddexp.reduce(ll), rtol=1e-10, atol=1e-12)
