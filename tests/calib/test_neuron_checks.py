"""M2's verdict checks, one failing case per branch: identifiability, units, the decoder's fit."""
import dataclasses
import json
import warnings

import numpy as np
import pytest

from feeler.calib.neuron import fit_neuron
from feeler.calib.neuron.checks import data_problems, posterior_problems, unit_problems
from feeler.calib.neuron.units import _scale_problem
from feeler.calib.neuron.grid import sample_grid
from feeler.calib.neuron.model import PeakTable, Plates, make_priors
from feeler.calib.neuron.synth import Truth, scene_scans, simulate_peaks
from feeler.calib.neuron.window import choose_noise


@pytest.fixture(scope="module")
def data():
    return scene_scans(per_plate=10)[2]


def _table(p, n_nodes=2, spread=1e-6):
    """Peaks that do not depend on τ (flat τ weights)."""
    return PeakTable(log_tau=np.linspace(0.0, spread, n_nodes), peak=np.repeat(np.asarray(p)[:, None], n_nodes, 1))


def _fit(table, plates, noise, rng, log_w=None):
    lw = np.zeros(table.log_tau.size) if log_w is None else log_w
    post = sample_grid(table, plates, make_priors(table), noise, lw, chains=1, draws=400, rng=rng)
    return posterior_problems(table, plates, noise, lw, post)


def _quiet_fit(d, **kw):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = fit_neuron(d, draws=200, **kw)
    leaked = [w for w in caught if issubclass(w.category, RuntimeWarning)]
    assert not leaked, [str(w.message) for w in leaked]            # no raw numpy warning reaches a user
    return res


def test_constant_noise_on_unequal_plates_is_too_narrow_for_the_wide_plate():
    rng = np.random.default_rng(4)
    plates = Plates.of(np.repeat([0.0, 0.05, 0.1, 0.2], 60))
    p = simulate_peaks(plates, Truth(mu=np.array([1.0, 2.0, 3.0, 4.0]), sigma=np.array([0.1, 0.1, 0.1, 0.25])), rng)
    problems, info = _fit(_table(p), plates, "constant", rng)
    assert any("plate 0.2 mm" in q and "too narrow" in q for q in problems), problems
    good, info = _fit(_table(p), plates, "per-plate", rng)
    assert good == [] and min(info["loo_coverage90"]) > 0.8
    assert choose_noise(_table(p), plates)[0] != "constant"       # leave-one-out rejects the pooled spread
    odd = simulate_peaks(plates, Truth(mu=np.array([1.0, 2.0, 3.0, 4.0]), sigma=np.array([0.25, 0.1, 0.1, 0.25])),
                         rng)
    assert choose_noise(_table(odd), plates)[0] == "per-plate"    # and no log-linear trend fits these


def test_a_plate_whose_scans_never_leave_the_band_is_too_wide():
    rng = np.random.default_rng(5)
    plates = Plates.of(np.repeat([0.0, 0.1], 200))
    p = np.where(np.arange(400) % 2 == 0, 1.0, -1.0) * 0.1 + np.repeat([1.0, 2.0], 200)   # two points, ±1 sd
    problems, _ = _fit(_table(p), plates, "per-plate", rng)
    assert any("too wide" in q for q in problems), problems


def test_skewed_plate_is_reported_as_biased():
    rng = np.random.default_rng(6)
    plates = Plates.of(np.repeat([0.0, 0.1, 0.2], 600))
    p = np.repeat([1.0, 2.0, 3.0], 600) + 0.1 * rng.standard_normal(1800)
    p[1200:] = 3.0 + 0.1 * (rng.lognormal(0.0, 1.5, 600) - np.exp(1.125))     # right-skewed top plate
    problems, info = _fit(_table(p), plates, "per-plate", rng)
    print("\n", info["loo_mean_pit"], problems)
    assert any("plate 0.2 mm" in q and "biased" in q for q in problems)


def test_plates_the_decoder_cannot_order():
    rng = np.random.default_rng(7)
    plates = Plates.of(np.repeat([0.0, 0.05, 0.1], 12))
    p = np.repeat([1.0, 1.0, 2.0], 12) + 0.1 * rng.standard_normal(36)
    problems, info = _fit(_table(p), plates, "per-plate", rng)
    assert any("cannot order plates 0 mm and 0.05 mm" in q for q in problems), info


def test_two_plates_with_swapped_labels_are_named_not_called_an_overlap():
    """Middle plates' labels swapped: their scans are well apart, in the wrong order."""
    rng = np.random.default_rng(9)
    plates = Plates.of(np.repeat([0.0, 0.05, 0.1, 0.2], 12))
    p = np.repeat([1.0, 3.0, 2.0, 5.0], 12) + 0.1 * rng.standard_normal(48)
    problems, info = _fit(_table(p), plates, "per-plate", rng)
    order = [q for q in problems if "plate 0.1 mm's scans decode below plate 0.05 mm's" in q]
    assert len(order) == 1 and "labels are probably swapped" in order[0], problems
    assert not any("cannot order" in q for q in problems) and info["p_ordered"][1] < 0.01
    # ordered plates, but most draws without a decodable line (NaN means): not ordered, not swapped
    p = np.repeat([1.0, 2.0, 3.0, 5.0], 12) + 0.1 * rng.standard_normal(48)
    table, lw = _table(p), np.zeros(2)
    post = sample_grid(table, plates, make_priors(table), "per-plate", lw, chains=1, draws=400, rng=rng)
    post["plate_mean_mm"] = np.where(np.arange(400)[None, :, None] < 398, np.nan, post["plate_mean_mm"])
    problems, info = posterior_problems(table, plates, "per-plate", lw, post)
    lines = [q for q in problems if q.startswith("plate_mean_mm:")]
    assert len(lines) == 3 and all("cannot order" in q for q in lines), lines      # P = 0.005


def test_a_window_the_data_do_not_pin():
    rng = np.random.default_rng(8)
    plates = Plates.of(np.repeat([0.0, 0.1], 12))
    p = np.repeat([1.0, 2.0], 12) + 0.1 * rng.standard_normal(24)
    table = _table(p, n_nodes=64, spread=2.0)                               # every τ reads the same peaks
    problems, _ = _fit(table, plates, "per-plate", rng)
    assert any(q.startswith("tau_s: not pinned") for q in problems)


def test_two_pinned_mode_windows_are_not_an_unpinned_window():
    """Joint window draws split between a snap's short window and a ride's long one: not a
    problem when each mode's own draws are pinned; a mode whose own draws spread is named."""
    from feeler.calib.neuron.checks import window_problems

    rng = np.random.default_rng(4)
    table = _table(np.ones(4), n_nodes=64, spread=np.log(20.0))          # windows 1-20 s
    snap, ride = np.exp(rng.normal(np.log(1.2), 0.05, 500)), np.exp(rng.normal(np.log(12.0), 0.05, 500))
    joint = np.concatenate([snap, ride])
    info = {}
    (line,) = window_problems(table, joint, None, info)
    assert line.startswith("tau_s: not pinned") and info["tau_spread_of_prior"] > 0.7
    assert window_problems(table, joint, {"ride": ride, "snap": snap}, info) == []
    assert max(info["tau_spread_of_prior_by_mode"].values()) < 0.1
    loose = np.exp(rng.uniform(0.0, np.log(20.0), 500))
    (line,) = window_problems(table, joint, {"ride": loose, "snap": snap}, info)
    assert line.startswith("tau_s: the rides' window is not pinned") and "snap" not in line


def test_the_shipped_noisy_scene_passes_with_each_mode_at_its_own_window():
    """hard/noisy.toml as `feeler simulate` writes it (its own seed): snaps read at about
    0.54 s, rides at 3.4 s; the joint draws spread over 98 % of the prior's range, and the
    verdict failed on it ('tau_s: not pinned', session 51 audit) though each mode was pinned."""
    from feeler.calib.neuron.synth import HARD_SCENES

    res = _quiet_fit(scene_scans(f"{HARD_SCENES}/noisy.toml")[2])
    info = json.loads(res.posterior["posterior"].attrs["checks"])
    assert info["tau_spread_of_prior"] > 0.7
    assert max(info["tau_spread_of_prior_by_mode"].values()) < 0.7
    assert res.verdict.ok, res.verdict.problems


def test_one_plate_fails_naming_what_it_cannot_pin(data):
    one = dataclasses.replace(data, step_mm=np.full(data.step_mm.size, 0.1))
    res = _quiet_fit(one)
    assert not res.verdict.ok
    assert any("one plate (0.1 mm)" in q and "a, h, tau_s" in q for q in res.verdict.problems)


def test_noise_free_scans_fail_with_zero_spread(data):
    first = np.searchsorted(data.step_mm, np.unique(data.step_mm))           # one scan per plate, repeated
    idx = np.repeat(first, 10)
    same = dataclasses.replace(data, strain=data.strain[idx], step_mm=data.step_mm[idx], x_mm=data.x_mm[idx],
                               speed_mm_s=data.speed_mm_s[idx])
    res = _quiet_fit(same)
    assert not res.verdict.ok and any("identical" in q and "noise-free" in q for q in res.verdict.problems)
    assert any(q.startswith("plate_sd_mm, tau_s:") and "zero spread" in q for q in res.verdict.problems)
    assert np.all(np.isfinite(res.summary["mean"]))


def test_a_plate_with_one_scan(data):
    keep = np.r_[0:30, 30]                                                  # plate 3 keeps one scan
    one = dataclasses.replace(data, strain=data.strain[keep], step_mm=data.step_mm[keep], x_mm=data.x_mm[keep],
                              speed_mm_s=data.speed_mm_s[keep])
    problems = data_problems(one.table(n_grid=16), Plates.of(one.step_mm))
    assert any("0.2 mm have one scan" in q for q in problems)


def test_a_plate_with_one_scan_fails_for_that_alone_and_quietly(data):
    """A lone scan has no left-out prediction. It used to make every window's score −inf
    (numpy warnings on the way), so the τ weights went flat and the verdict added "tau_s:
    not pinned", which these data do pin. Now the lone scan adds nothing to the scores."""
    keep = np.r_[0:30, 30]
    one = dataclasses.replace(data, strain=data.strain[keep], step_mm=data.step_mm[keep], x_mm=data.x_mm[keep],
                              speed_mm_s=data.speed_mm_s[keep])
    res = _quiet_fit(one)
    assert res.verdict.problems == ("plate_sd_mm: plate(s) 0.2 mm have one scan; a plate's spread needs at least 2",)
    checks = json.loads(res.posterior["posterior"].attrs["checks"])
    assert np.isnan(checks["loo_coverage90"][3]) and np.all(np.isfinite(checks["loo_coverage90"][:3]))
    assert np.isfinite(res.posterior["posterior"].attrs["ppc_coverage90"])


def test_a_scan_with_a_one_sample_glitch_is_named_first(data):
    """One sample 1 mm off in one scan made the fit fail for 'the scans show no step' and
    plates it 'cannot order'; the glitch itself is named now, with its scan and sample."""
    strain = data.strain.copy()
    strain[7, 12] += 1.0 / data.length_mm
    res = _quiet_fit(dataclasses.replace(data, strain=strain))
    assert not res.verdict.ok
    assert res.verdict.problems[0].startswith(f"uy_mm: 1 scan(s) with a single-sample spike (e.g. "
                                              f"{data.scan_names[7]}: U_y jumps +")
    assert data.scan_names[7] == "scan_id 7"
    assert "at sample 13 and back" in res.verdict.problems[0]
    assert not any("spike" in q for q in data_problems(data.table(n_grid=16), Plates.of(data.step_mm), data.strain,
                                                       data.length_mm))


def test_steps_labelled_with_the_wrong_sign(data):
    """Depths for heights (steps negated): the rise falls as the label rises. One line names
    it; the per-entry "no finite draws" of the undefined decoder come as one line too."""
    table, plates = data.table(n_grid=16), Plates.of(-data.step_mm)
    q = unit_problems(table, plates, length_mm=3.0, t_s=data.t_s)
    assert len(q) == 1 and "wrong sign" in q[0] and "slope -" in q[0]
    assert unit_problems(table, Plates.of(data.step_mm), length_mm=3.0, t_s=data.t_s) == []
    # heights >= 0 in reverse order (0 <-> top): no sign to be wrong; the order is named
    top = data.step_mm.max()
    (q,) = unit_problems(table, Plates.of(top - data.step_mm), length_mm=3.0, t_s=data.t_s)
    assert "slope -" in q and "labelled in reverse order" in q and "sign" not in q
    (q,) = unit_problems(table, Plates.of(top / 2 - data.step_mm), length_mm=3.0, t_s=data.t_s)
    assert "wrong sign or in reverse order" in q
    # labels shuffled: the scans tilt by chance, no sign mistake, but no step is seen either
    shuffled = Plates.of(np.random.default_rng(3).permutation(data.step_mm))
    (q,) = unit_problems(table, shuffled, length_mm=3.0, t_s=data.t_s)
    assert "does not change with the labelled step at any window" in q and "no step shows through" in q
    # it named only the labels and the column; steps this small against the noise are one cause too
    # (an outside audit: 0 and 0.02 mm under 4 um noise, U_y rising 20 um on the upper plate)
    assert "steps of 0, 0.05, 0.1, 0.2 mm may be too small for this read-out noise" in q
    assert "or uy_mm may not hold the normal displacement or step_mm each scan's plate" in q
    res = _quiet_fit(dataclasses.replace(data, step_mm=-data.step_mm))
    assert "wrong sign" in res.verdict.problems[0]
    assert [x for x in res.verdict.problems if "no finite posterior draws" in x] == [
        "a, h, sigma_mm, plate_mean_mm[0-3], plate_sd_mm[0-3]: no finite posterior draws (not defined by these data)"]
    assert not any("-0 mm" in x for x in res.verdict.problems)
    assert not any("order" in x for x in res.verdict.problems)      # no finite plate means: nothing to order


def test_units_micrometres_and_milliseconds(data):
    table = data.table(n_grid=32)
    plates = Plates.of(data.step_mm)
    assert unit_problems(table, plates, length_mm=3.0, t_s=data.t_s, x_mm=data.x_mm, speed_mm_s=data.speed_mm_s) == []
    um = unit_problems(PeakTable(table.log_tau, 1000 * table.peak), plates, length_mm=3.0, t_s=data.t_s)
    assert len(um) == 1 and "U_y probably in um" in um[0]
    tiny = unit_problems(PeakTable(table.log_tau, table.peak / 1000), plates, length_mm=3.0, t_s=data.t_s)
    assert "steps probably in um" in tiny[0]
    ms = unit_problems(table, plates, length_mm=3.0, t_s=1000 * data.t_s, x_mm=data.x_mm, speed_mm_s=data.speed_mm_s)
    assert len(ms) == 2 and all("times probably in ms" in q for q in ms)
    minutes = unit_problems(table, plates, length_mm=3.0, t_s=data.t_s / 60, x_mm=data.x_mm, speed_mm_s=data.speed_mm_s)
    assert [q.split(": ")[-1] for q in minutes] == ["times probably in min (expected s)"]
    x_um = unit_problems(table, plates, length_mm=3.0, t_s=data.t_s, x_mm=1000 * data.x_mm, speed_mm_s=data.speed_mm_s)
    assert [q.split(": ")[-1] for q in x_um] == ["x probably in um (expected mm)"]
    # the speed label in mm/min, the unit of a Grbl feed rate: 1/60 of the speed x and t give (it said 'ms')
    per_min = unit_problems(table, plates, length_mm=3.0, t_s=data.t_s, x_mm=data.x_mm, speed_mm_s=60 * data.speed_mm_s)
    assert [q.split(": ")[-1] for q in per_min] == [
        "speed_mm_s probably in mm/min, the unit of Grbl's feed rate F (expected mm/s)"]
    res = _quiet_fit(dataclasses.replace(data, strain=1000 * data.strain))
    assert not res.verdict.ok and "U_y probably in um" in res.verdict.problems[0]


@pytest.mark.parametrize("per_mm, words", [(0.1, "steps probably in cm"), (1 / 25.4, "steps probably in inches")])
def test_steps_in_cm_or_inches_are_named(data, per_mm, words):
    """Labels in cm or inches make U_y rise 10 or 25 times the step, under the x30 of the
    um check: the fit said verdict ok. A face riding over a step rises by at most the step
    (0.31-1.09 measured, :data:`MAX_GAIN`)."""
    res = _quiet_fit(dataclasses.replace(data, step_mm=per_mm * data.step_mm))
    assert not res.verdict.ok and words in res.verdict.problems[0], res.verdict.problems


@pytest.mark.parametrize("per_mm", [0.5, 1 / 3])
def test_steps_labelled_too_small_are_named(data, per_mm):
    """Steps labelled half or a third of their height make U_y rise 2 or 3 times the step,
    under MAX_GAIN: the fit said verdict ok (an outside audit). The shipped labels are not
    flagged, nor a rise a third below the step."""
    res = _quiet_fit(dataclasses.replace(data, step_mm=per_mm * data.step_mm))
    assert not res.verdict.ok
    (q,) = [q for q in res.verdict.problems if q.startswith("a: ")]
    assert "the steps are probably labelled too small, the scans reading them about" in q, q
    assert abs(float(q.split("reading them about ")[1].split(" ")[0]) - 1 / per_mm) < 0.3, q
    table, plates = data.table(n_grid=32), Plates.of(data.step_mm)
    assert unit_problems(table, plates, length_mm=3.0, t_s=data.t_s) == []
    assert unit_problems(PeakTable(table.log_tau, table.peak / 1.5), plates, length_mm=3.0, t_s=data.t_s) == []


@pytest.mark.parametrize("per_mm, words", [(0.1, "U_y probably in cm, expected mm (or the steps labelled 10 times"),
                                            (1 / 25.4, "U_y probably in inches")])
def test_displacements_in_cm_or_inches_are_named(data, per_mm, words):
    """U_y in cm or inches (steps in mm) rises 0.1 or 0.04 times the step, above the 1/30 of
    the um check: the fit said verdict ok (an outside audit). A face riding over a step rises
    by 0.3-1.1 of it (:data:`MIN_GAIN`); U_y a third of the truth still reads as physics."""
    res = _quiet_fit(dataclasses.replace(data, strain=per_mm * data.strain))
    assert not res.verdict.ok and words in res.verdict.problems[0], res.verdict.problems
    table, plates = data.table(n_grid=32), Plates.of(data.step_mm)
    (q,) = unit_problems(table, Plates.of(10 * data.step_mm), length_mm=3.0, t_s=data.t_s)     # steps x10: the same
    assert "U_y probably in cm" in q and "steps labelled 10 times too large" in q
    assert unit_problems(PeakTable(table.log_tau, table.peak / 3), plates, length_mm=3.0, t_s=data.t_s) == []


def test_plates_labelled_closer_than_they_read_are_not_a_unit(data):
    """Two plates labelled 1 um apart whose scans differ by their noise: the slope through
    them is 10^4, which the check read as U_y in um, though each plate rises about its step.
    The labels are named instead; U_y truly in um (both ratios off) still is."""
    table = data.table(n_grid=32)
    top = data.step_mm == data.step_mm.max()
    steps = np.where(top, 0.1 + 1e-6, 0.1)                        # the 0.2 mm plate vs the rest, 1 um apart
    (q,) = unit_problems(table, Plates.of(steps), length_mm=3.0, t_s=data.t_s)
    assert "labelled closer together than their scans read them" in q and "um" not in q, q
    assert "(0.1, 0.100001 mm)" in q
    q = _scale_problem(0.1, 1.2, np.array([0.0, 2.0]))            # a slope of 0.1, the top plate rising its step
    assert "labelled further apart than their scans read them" in q and "cm" not in q, q
    (q,) = unit_problems(PeakTable(table.log_tau, 1000 * table.peak), Plates.of(data.step_mm), length_mm=3.0,
                         t_s=data.t_s)
    assert "U_y probably in um" in q


def test_steps_and_displacements_both_in_another_unit(data):
    """Steps and U_y both in µm (or both in m): their ratio is about 1, so the ratio check
    passed, and the fit said verdict ok on plates of 50-200 mm. The largest step names it."""
    table = data.table(n_grid=32)
    for scale, unit in ((1000.0, "um"), (1e-3, "m")):
        (q,) = unit_problems(PeakTable(table.log_tau, scale * table.peak), Plates.of(scale * data.step_mm),
                             length_mm=3.0, t_s=data.t_s)
        assert q.startswith(f"a: the labelled steps reach {0.2 * scale:.4g} mm and the scans' rise in U_y follows "
                            f"them") and q.endswith(f"steps and U_y probably both in {unit} (expected mm)")
    res = _quiet_fit(dataclasses.replace(data, strain=1000 * data.strain, step_mm=1000 * data.step_mm))
    assert not res.verdict.ok and "probably both in um" in res.verdict.problems[0]
    # the hard scenes' finest plates (0-0.03 mm) and a coarse 5 mm step set are lengths in mm
    for scale in (0.15, 25.0):
        assert unit_problems(PeakTable(table.log_tau, scale * table.peak), Plates.of(scale * data.step_mm),
                             length_mm=3.0, t_s=data.t_s) == []


def test_checks_are_recorded(data):
    res = _quiet_fit(data)
    checks = json.loads(res.posterior["posterior"].attrs["checks"])
    assert set(checks) >= {"loo_coverage90", "loo_mean_pit", "p_ordered", "tau_spread_of_prior"}


def test_a_window_leaning_on_an_end_of_the_scans_range_is_noted_not_failed(capsys, tmp_path):
    """The window's range is the scans' own (one sample interval to half a scan): a
    posterior leaning on either end is a note naming that end, not a failed verdict. The
    untuned three-exponential scene's first training set put 8 % of its draws below
    0.515 s and failed with 'posterior piles against its lower prior bound 0.5', so
    classify refused a fit whose plates it decodes like the others."""
    from feeler.calib.neuron.checks import window_edge_notes
    from feeler.calib.neuron.model import Priors
    from feeler.calib.neuron.synth import HARD_SCENES
    from feeler.cli import main

    pri = Priors(tau_lo_s=0.5, tau_hi_s=10.0)
    rng = np.random.default_rng(5)
    low = 0.5 * np.exp(np.abs(rng.normal(0, 0.05, 4000)))
    high = 10.0 * np.exp(-np.abs(rng.normal(0, 0.05, 4000)))
    inside = np.exp(rng.normal(np.log(2.0), 0.2, 4000))
    (lo,), (hi,) = window_edge_notes(low, pri), window_edge_notes(high, pri)
    assert lo.startswith("tau_s: leans on its lower prior bound 0.5 (") and "shortest window these scans resolve" in lo
    assert hi.startswith("tau_s: leans on its upper prior bound 10 (") and "longest window these scans allow" in hi
    assert window_edge_notes(inside, pri) == []
    run = tmp_path / "run"
    assert main(["simulate", str(HARD_SCENES / "three-exponential.toml"), "--seed", "20040502", "--out", str(run),
                 "--no-progress"]) == 0
    capsys.readouterr()
    assert main(["calibrate", "neuron", str(run), "--seed", "1", "--noise", "growing", "--no-progress"]) == 0
    out = capsys.readouterr().out                   # growing: the model that fit leaned with
    assert "note: tau_s: leans on its lower prior bound 0.5 (8 % of draws below 0.515)" in out
    assert "verdict: ok" in out and "piles" not in out


def test_scans_appended_twice_fail_naming_a_copy(data):
    """A file appended to itself: every touch counted twice. The fit was twice as sure as its
    data and said ok; no two real touches agree sample for sample, so copies are named."""
    n = data.step_mm.size
    twice = np.r_[0:n, 0:n]
    dup = dataclasses.replace(data, strain=data.strain[twice], step_mm=data.step_mm[twice], x_mm=data.x_mm[twice],
                              speed_mm_s=data.speed_mm_s[twice])
    problems = data_problems(dup.table(n_grid=16), Plates.of(dup.step_mm), dup.strain)
    assert [q for q in problems if "repeat" in q] == [
        f"plate_sd_mm: {n} of {2 * n} scans repeat an earlier scan sample for sample (e.g. scan {n + 1} = scan 1 in "
        f"file order; no two real touches agree exactly): touches counted twice make the fit surer than its data; "
        f"remove the copies"]
    assert not [q for q in data_problems(data.table(n_grid=16), Plates.of(data.step_mm), data.strain) if "repeat" in q]


def test_a_mislabelled_training_scan_is_named_with_the_plate_it_reads_like(data):
    """A touch of the 0.2 mm plate labelled 0 mm widened the floor plate and passed every
    per-plate check (1 scan in 10 outside the band is chance): verdict ok. Now the scan is
    named, with the plate its reading matches."""
    k = int(np.flatnonzero(data.step_mm == 0.2)[3])
    wrong = data.step_mm.copy()
    wrong[k] = 0.0
    res = _quiet_fit(dataclasses.replace(data, step_mm=wrong))
    lines = [q for q in res.verdict.problems if q.startswith("step_mm:")]
    assert len(lines) == 1 and lines[0].startswith(f"step_mm: {data.scan_names[k]} (labelled 0 mm) lies far "
                                                   "outside the other touches of its plate"), res.verdict.problems
    assert "matches plate 0.2 mm" in lines[0] and "probably mislabelled" in lines[0]
    assert not [q for q in _quiet_fit(data).verdict.problems if q.startswith("step_mm:")]


def test_a_scan_at_ten_times_its_scale_is_named_as_matching_no_plate(data):
    strain = data.strain.copy()
    k = int(np.flatnonzero(data.step_mm == 0.05)[2])
    strain[k] *= 10.0
    res = _quiet_fit(dataclasses.replace(data, strain=strain))
    lines = [q for q in res.verdict.problems if q.startswith("step_mm:")]
    assert len(lines) == 1 and f"{data.scan_names[k]} (labelled 0.05 mm)" in lines[0], res.verdict.problems
    assert "matches no plate: a corrupted scan" in lines[0] and "p < 1e-15" in lines[0]
    # without ids (data built by hand) a scan is named by its place in the file
    nameless = dataclasses.replace(data, strain=strain, scan_names=None)
    assert f"scan {k + 1} in file order (labelled 0.05 mm)" in " ".join(_quiet_fit(nameless).verdict.problems)


def test_clean_training_sets_are_not_called_mislabelled_beyond_the_level():
    """The per-scan check's family-wise level is 0.1 % over all scans: on 30 clean training
    sets of the four-plates scene (10 touches per plate) at most one set may be flagged
    (measured on 200 sets of each of four-plates and the nine hard scenes: none on seven,
    1 on three-exponential, 2 on tilted)."""
    from feeler.calib.neuron.checks import loo_pit
    from feeler.calib.neuron.odd_scans import odd_scan_problems
    from feeler.calib.neuron.window import tau_log_weights

    flagged = 0
    for seed in range(30):
        d = scene_scans(per_plate=10, seed=7000 + seed)[2]
        table, plates = d.table(n_grid=64), Plates.of(d.step_mm)
        noise, _, elpd = choose_noise(table, plates)
        lw = tau_log_weights(elpd, np.random.default_rng(seed))
        flagged += bool(odd_scan_problems(table, plates, loo_pit(table, plates, noise, lw), lw))
    assert flagged <= 1, flagged


def test_odd_scans_beyond_the_worst_are_counted_and_named():
    from feeler.calib.neuron.checks import loo_pit
    from feeler.calib.neuron.odd_scans import odd_scan_problems

    rng = np.random.default_rng(11)
    plates = Plates.of(np.repeat([0.0, 0.05, 0.1], 30))
    p = np.repeat([1.0, 2.0, 3.0], 30) + 0.1 * rng.standard_normal(90)
    p[[3, 40, 70]] += [-0.6, 0.8, 1.0]                      # 6-10 sds outside their plates, the last the furthest
    table, lw = _table(p), np.zeros(2)
    names = tuple(f"scan_id 'T{k}'" for k in range(90))
    (line,) = odd_scan_problems(table, plates, loo_pit(table, plates, "per-plate", lw), lw, names)
    assert line.startswith("step_mm: scan_id 'T70' (labelled 0.1 mm) lies far outside the other touches")
    assert line.endswith("; 2 more scans lie outside their plates too (scan_id 'T40', scan_id 'T3')"), line


def test_a_far_out_scan_hidden_by_a_further_one_is_found_once_that_one_is_set_aside():
    """Two odd scans on one plate: the furthest inflates the plate's spread in the other's
    leave-one-out predictive, so one pass names only the furthest (three mislabels in one
    file showed one at a time). Set aside and tested again, the second is named too."""
    from feeler.calib.neuron.checks import loo_pit
    from feeler.calib.neuron.odd_scans import odd_scan_problems

    rng = np.random.default_rng(11)
    plates = Plates.of(np.repeat([0.0, 0.05, 0.1], 20))
    p = np.repeat([1.0, 2.0, 3.0], 20) + 0.1 * rng.standard_normal(60)
    p[[2, 5]] += [3.0, 0.8]                          # 30 and 8 sds out
    lw = np.zeros(2)
    pit = loo_pit(_table(p), plates, "per-plate", lw)
    (once,) = odd_scan_problems(_table(p), plates, pit, lw)
    assert once.startswith("step_mm: scan 3 in file order (labelled 0 mm)") and "more scan" not in once

    def refit(keep):
        return loo_pit(_table(p[keep]), Plates.of(plates.steps_mm[plates.group[keep]]), "per-plate", lw)

    (line,) = odd_scan_problems(_table(p), plates, pit, lw, refit=refit)
    assert line.startswith("step_mm: scan 3 in file order (labelled 0 mm)")
    assert line.endswith("; 1 more scan lies outside its plate too (scan 6 in file order)"), line


def test_plates_of_two_to_four_scans_fail_the_verdict():
    """Two touches a plate: every leave-one-out check passes (each scan predicted from the
    other), yet over ten training sets of four-plates 0.78 of fresh labels fell inside their
    90 % intervals and 9 of 10 fits said ok. Four a plate: an outside audit's slow scene
    covered 0.81-0.85 with 16 of 20 fits ok. Fewer than 5 a plate now fails, naming the plates."""
    from feeler.calib.neuron.checks import MIN_SCANS_PER_PLATE

    assert MIN_SCANS_PER_PLATE == 5
    two = scene_scans(seed=21, per_plate=2)[2]
    res = _quiet_fit(two, seed=1)
    assert not res.verdict.ok
    line = next(q for q in res.verdict.problems if q.startswith("plate_sd_mm, tau_s: plate(s)"))
    assert "0 mm (2 scans), 0.05 mm (2 scans), 0.1 mm (2 scans), 0.2 mm (2 scans) have fewer than 5" in line
    five = scene_scans(seed=21, per_plate=5)[2]
    table = five.table(n_grid=16)
    assert not any("fewer than" in q for q in data_problems(table, Plates.of(five.step_mm)))   # 5 a plate
    keep = np.flatnonzero((five.step_mm != 0.1) | (np.cumsum(five.step_mm == 0.1) <= 4))       # 0.1 mm: 4
    four = data_problems(PeakTable(log_tau=table.log_tau, peak=table.peak[keep]), Plates.of(five.step_mm[keep]))
    assert any(q.startswith("plate_sd_mm, tau_s: plate(s) 0.1 mm (4 scans) have fewer than 5") for q in four)
