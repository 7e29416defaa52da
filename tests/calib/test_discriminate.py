"""M3: 2AFC probabilities from the forward model of the fit's scene and an M2 posterior,
with the Monte Carlo error of the simulated touches in every interval."""
import warnings

import numpy as np
import pytest

from feeler.calib.neuron import fit_neuron
from feeler.calib.neuron.discriminate import Discriminator, Interval, _crossing, proportion_correct
from feeler.calib.neuron.synth import FOUR_PLATES, scene_scans
from feeler.errors import ArgumentError


@pytest.fixture(scope="module")
def fit():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fit_neuron(scene_scans()[2], seed=4, draws=500, scene_toml=FOUR_PLATES.read_text(),
                          scene_path=str(FOUR_PLATES))


@pytest.fixture(scope="module")
def disc(fit):
    return Discriminator(fit, n_scans=200, n_draws=60, seed=9)


def test_equal_heights_give_one_half(disc):
    for height in (0.0, 0.1):
        p = disc.pc(height, height)
        print(f"\nP(correct) at {height} vs {height} mm: {p.mean:.3f} [{p.lo95:.3f}, {p.hi95:.3f}], MC se {p.mcse:.3f}")
        # the truth is 0.5; finite touch sets differ from it by their MC error, which the interval carries
        assert abs(p.mean - 0.5) < 3 * p.mcse and (p.hi95 - p.lo95) / 2 > 1.5 * p.mcse


def test_proportion_correct_grows_with_the_increment(disc):
    means = [disc.pc(0.1, 0.1 + d).mean for d in (0.0, 0.002, 0.004, 0.008, 0.05)]
    print("\nP(correct) vs increment:", np.round(means, 3))
    assert np.all(np.diff(means) > 0) and means[-1] > 0.99


def test_threshold_weber_and_a_threshold_reported_as_a_bound(disc):
    from feeler.commands.discriminate import threshold_text
    th = disc.threshold(0.1)
    d = th.delta75_mm
    print(f"\ndelta75 {threshold_text(th)}, Weber {th.weber.mean:.3f}")
    assert th.found == 1.0 and not th.is_bound and 0 < d.lo95 <= d.mean <= d.hi95 < 0.025
    np.testing.assert_allclose(th.weber.draws, d.draws / 0.1)
    assert disc.pc(0.1, 0.1 + d.mean).mean == pytest.approx(0.75, abs=0.06)
    short = disc.threshold(0.1, max_delta_mm=0.001, n_steps=4)           # searched far too short
    text = threshold_text(short)
    print(text)
    assert short.is_bound and short.found < 0.5 and text.startswith("> 1.00 um (") and "% of draws" in text


def test_more_than_a_fortieth_of_draws_unreached_makes_the_upper_end_a_bound():
    """3 of 100 draws never reach 75 % within the searched 0.08 mm while the resamples all
    do: the 97.5 % point of the posterior lies past the search, so the upper end prints
    as a bound; 2 of 100 keep a finite one."""
    from feeler.calib.neuron.discriminate import Threshold
    from feeler.commands.discriminate import threshold_text

    def th(unreached):
        v = np.r_[np.linspace(0.01, 0.02, 100 - unreached), np.full(unreached, np.inf)]
        d = Interval.of(v, np.linspace(0.01, 0.07, 100))
        return Threshold(reference_mm=0.1, delta75_mm=d, weber=d, found=d.found, searched_mm=0.08)
    assert np.isfinite(th(3).delta75_mm.hi95)
    assert th(3).is_bound and ", > 80.00] um (3 % of draws" in threshold_text(th(3))
    assert not th(2).is_bound and "> 80" not in threshold_text(th(2))


def test_a_bound_whose_draws_all_reach_says_it_is_their_resamples_that_do_not():
    """Every draw reaches 75 % on the touches as simulated, but more than 2.5 % of their
    resamples do not: the upper end is a bound, and the text says why instead of "0 % of
    draws do not reach" (an outside audit). A share of 0.3 % or 99.7 % never prints as 0 or
    100."""
    from feeler.calib.neuron.discriminate import Threshold
    from feeler.commands.discriminate import share_text, threshold_text

    v = np.linspace(0.01, 0.02, 100)
    d = Interval.of(v, np.r_[np.linspace(0.01, 0.02, 95), np.full(5, np.inf)])
    th = Threshold(reference_mm=0.1, delta75_mm=d, weber=d, found=d.found, searched_mm=0.025)
    text = threshold_text(th)
    assert th.found == 1 and th.is_bound and ", > 25.00] um (every draw reaches 75 %" in text
    assert "0 % of draws" not in text and "resampled" in text
    assert (share_text(0.003), share_text(0.997), share_text(0.5), share_text(1.0)) == ("under 1", "over 99", "50", "100")


def test_a_threshold_around_a_small_reference_is_found(disc):
    """Around 2 µm the threshold (several µm: it does not shrink with the reference near
    the noise floor) lies far beyond a quarter of the reference, where the search used to
    stop, so every draw was a bound ("> 0.50 um (100 % of draws ...)"). The default search
    reaches four of the decoder's widest plate sds, and the threshold is found."""
    quarter = disc.threshold(0.002, max_delta_mm=0.0005)
    assert quarter.found < 0.05
    th = disc.threshold(0.002)
    print(f"\naround 2 um: searched to {th.searched_mm * 1e3:.1f} um, delta75 {th.delta75_mm.mean * 1e3:.2f} "
          f"[{th.delta75_mm.lo95 * 1e3:.2f}, {th.delta75_mm.hi95 * 1e3:.2f}] um, found {th.found:.2f}")
    assert th.searched_mm == pytest.approx(4 * disc.spread_mm) and th.found == 1.0 and not th.is_bound
    assert 0.0005 < th.delta75_mm.mean < th.searched_mm
    assert disc.pc(0.002, 0.002 + th.delta75_mm.mean).mean == pytest.approx(0.75, abs=0.06)
    assert disc.search_top_mm(0.1) == pytest.approx(max(0.025, 4 * disc.spread_mm))     # the default reference
    assert disc.search_top_mm(4.99) == pytest.approx(0.01)              # the scene's highest allowed step: 5 mm
    # the PSE likewise: 0-4 um around 2 um held none at another speed; at the same speed it is the reference
    lo, hi = disc.pse_range_mm(0.002)
    assert lo == 0.0 and hi == pytest.approx(0.002 + 4 * disc.spread_mm)
    assert disc.pse_range_mm(0.1) == pytest.approx((0.0, 0.2))         # the default reference: ± itself
    p = disc.pse(0.002, 0.5, 0.5, n_steps=12)
    print(f"PSE around 2 um at equal speeds: {p.mean * 1e3:.2f} [{p.lo95 * 1e3:.2f}, {p.hi95 * 1e3:.2f}] um")
    assert p.found == 1.0 and abs(p.mean - 0.002) < 3 * p.mcse + 0.001
    assert 0.0 <= p.lo95 <= p.mean <= p.hi95     # a resample at ½ already at 0 crosses at 0 (was -inf)


def test_pse_at_equal_speeds_is_the_reference(disc):
    p = disc.pse(0.1, 0.5, 0.5, span_mm=0.03, n_steps=12)
    print(f"\nPSE at equal speeds: {p.mean:.4f} [{p.lo95:.4f}, {p.hi95:.4f}] mm")
    assert abs(p.mean - 0.1) < 3 * p.mcse + 1e-4 and abs(p.mean - 0.1) < 0.005


def test_reruns_with_other_seeds_agree_within_their_intervals(fit):
    """10 seeds (posterior draws and resamples): each estimate inside at least 9 of the 9
    other intervals (the touches are the scene's; see the next test for other touches)."""
    ivs = [Discriminator(fit, n_scans=150, n_draws=40, seed=s).pc(0.1, 0.104) for s in range(10)]
    inside = [sum(o.lo95 <= iv.mean <= o.hi95 for o in ivs if o is not iv) for iv in ivs]
    print("\nestimates", np.round([iv.mean for iv in ivs], 4), "inside of the other 9:", inside)
    assert min(inside) >= 9


def test_intervals_include_the_simulation_error_of_the_touches(fit):
    """Other touches (10 touch seeds, 150 touches): the large-sample value lies inside at
    least 8 of the 10 intervals (P = 0.99 at 95 %), while intervals from the posterior
    spread alone — what feeler reported before — miss it most of the time."""
    ref = Discriminator(fit, n_scans=3000, n_draws=40, seed=0, touch_seed=777).pc(0.1, 0.104).mean
    ivs = [Discriminator(fit, n_scans=150, n_draws=40, seed=s, touch_seed=100 + s).pc(0.1, 0.104) for s in range(10)]
    honest = sum(iv.lo95 <= ref <= iv.hi95 for iv in ivs)
    posterior_only = sum(np.quantile(iv.draws, 0.025) <= ref <= np.quantile(iv.draws, 0.975) for iv in ivs)
    print(f"\nlarge-sample {ref:.4f}; inside {honest}/10 intervals, posterior-only {posterior_only}/10; "
          f"MC se {np.mean([iv.mcse for iv in ivs]):.4f}")
    assert honest >= 8 and posterior_only <= 6


def test_proportion_correct_exact_counts():
    lo = np.array([[1.0, 2.0, 3.0]])
    hi = np.array([[2.0, 4.0]])
    # pairs (hi > lo): 2>1, 4>1,2,3 = 4 wins, one tie (2 = 2): (4 + 0.5) / 6
    assert proportion_correct(lo, hi)[0] == pytest.approx(4.5 / 6)


def test_crossing_and_intervals_with_unreached_values():
    x = np.array([0.0, 1.0, 2.0, 3.0])
    curve = np.array([[0.5, 0.6, 0.8, 0.9], [0.8, 0.9, 0.9, 0.9], [0.5, 0.6, 0.7, 0.7]])
    out = _crossing(x, curve, 0.75)
    assert out[0] == pytest.approx(1.75) and out[1] == -np.inf and out[2] == np.inf
    iv = Interval.of([1.0, 2.0, np.inf, np.inf], [1.1, 2.1, np.inf, np.inf])
    assert np.isnan(iv.mean) and iv.found == 0.5 and iv.hi95 == np.inf and np.isfinite(iv.lo95)


def test_the_estimate_never_lies_outside_its_interval():
    """Near 1 a few low draws pull the mean below the 2.5 % point of the resampled values:
    'pc 0.99900 [0.99951, 0.99999]' (an outside audit, six plates of five touches). The
    median is printed then; a mean inside its interval still is."""
    values = np.r_[np.full(190, 0.9999), np.full(10, 0.982)]
    resampled = np.r_[np.full(195, 0.99995), np.full(5, 0.9999)]
    iv = Interval.of(values, resampled)
    assert iv.mean < iv.lo95 and iv.estimate == iv.median and iv.lo95 <= iv.estimate <= iv.hi95
    inside = Interval.of(np.linspace(0.8, 0.9, 200), np.linspace(0.79, 0.91, 200))
    assert inside.estimate == inside.mean


def test_the_fit_scene_is_used_and_checked(fit, tmp_path):
    from feeler.calib.fit import FitResult
    d = Discriminator(fit, n_scans=4, n_draws=3)
    assert d.scene_path == FOUR_PLATES                                     # the recorded scene, as recorded
    tree = fit.posterior.copy()
    tree["posterior"].attrs.pop("scene_toml")
    bare = FitResult(tree, fit.summary, fit.verdict)
    with pytest.raises(ArgumentError, match="--scene"):
        Discriminator(bare, n_scans=4, n_draws=3)
    other = tmp_path / "other.toml"
    other.write_text(FOUR_PLATES.read_text().replace("length_mm = 3.0", "length_mm = 2.0"))
    with pytest.raises(ArgumentError, match="length_mm = 3 mm"):
        Discriminator(fit, scene_path=other, n_scans=4, n_draws=3)
    moved = fit.posterior.copy()
    moved["posterior"].attrs["scene_path"] = str(tmp_path / "gone.toml")    # the file moved: its text is used
    assert Discriminator(FitResult(moved, fit.summary, fit.verdict), n_scans=4, n_draws=3).scene_path.is_file()


def test_bad_arguments(disc, fit):
    with pytest.raises(ArgumentError, match="reference_mm"):
        disc.threshold(0.0)
    with pytest.raises(ArgumentError, match="max_delta_mm"):
        disc.threshold(0.1, max_delta_mm=0.0)
    with pytest.raises(ArgumentError, match="n_scans"):
        Discriminator(fit, n_scans=1)


def test_a_threshold_from_few_touches_is_never_below_zero(fit):
    """With 3 touches per height a draw's curve can start at 75 % at Δ = 0 (where it is ½
    but for the simulation error); that crossing was −inf, printed "[-inf, 9.25] um"."""
    th = Discriminator(fit, n_scans=3, n_draws=200, seed=0).threshold(0.1)
    d = th.delta75_mm
    assert np.all(d.draws[np.isfinite(d.draws)] >= 0)
    assert d.lo95 == 0.0 and th.weber.lo95 == 0.0      # the case arose (in resampled touches): crossed at Δ = 0


def test_touches_that_never_overlap_keep_the_bound_of_their_number(fit):
    """0 vs 0.2 mm: every touch of one height lies above every touch of the other, so every
    resample gives 1 and the interval was "[1.0000, 1.0000]" with MC se 0, from 3 touches a
    height as from 1000. n disjoint pairs all correct bound P(correct) ≥ 0.025^(1/n)."""
    for n in (3, 40):
        p = Discriminator(fit, n_scans=n, n_draws=50, seed=1).pc(0.0, 0.2)
        assert p.mean == 1.0 and p.hi95 == 1.0 and np.isnan(p.mcse)
        assert p.lo95 == pytest.approx(0.025 ** (1 / n))                  # 0.292 at 3, 0.912 at 40
    # the bound holds: with P(correct) = 0.9 the n = 40 interval's end 0.912 would be passed
    # by all-correct sets at most 0.9 ** 40 = 1.5 % of the time (disjoint pairs alone)
    rng = np.random.default_rng(0)
    low, high = rng.normal(0, 1, (20000, 40)), rng.normal(1.8124, 1, (20000, 40))  # P(high > low) = 0.9
    assert np.mean(low.max(axis=1) < high.min(axis=1)) <= 0.9 ** 40
    near = Discriminator(fit, n_scans=200, n_draws=50, seed=1).pc(0.1, 0.104)        # overlapping: as before
    assert np.isfinite(near.mcse) and near.lo95 < near.mean < near.hi95 < 1


def test_a_reference_outside_the_trained_plates_is_noted(disc):
    assert disc.outside_note(0.1) is None and disc.outside_note(0.0) is None and disc.outside_note(0.2) is None
    assert disc.outside_note([0.0, 0.05, 0.2], option="--pair") is None
    assert disc.outside_note([0.1, 0.3], option="--pair") == (
        "note: pair height 0.3 mm lies outside the plates the fit was trained on (0-0.2 mm): their P(correct) "
        "extrapolates the calibration (--pair)")
    assert disc.outside_note([0.3, -0.01, 0.3], option="--pair").startswith("note: pair heights -0.01, 0.3 mm lie")
    note = disc.outside_note(0.3)
    assert note.startswith("note: reference 0.3 mm lies outside the plates the fit was trained on (0-0.2 mm)")


def test_a_forward_scene_of_other_touches_is_named(fit, tmp_path):
    """--scene at 4x the trained stage speed and 5x its read-out noise: the note names both
    changes; other heights, repeats or seed are discriminate's own business (no note)."""
    from feeler.calib.neuron.scene_record import scene_note

    text = FOUR_PLATES.read_text()
    assert "speed_mm_s = 0.5" in text and "uy_sd_mm = 0.001" in text
    fast = tmp_path / "fast.toml"
    fast.write_text(text.replace("speed_mm_s = 0.5", "speed_mm_s = 2.0")
                    .replace("uy_sd_mm = 0.001", "uy_sd_mm = 0.005"))
    note = scene_note(fit, fast)
    assert note.startswith(f"note: --scene {fast} differs") and "motion.speed_mm_s 0.5 -> 2.0" in note
    assert "noise.uy_sd_mm 0.001 -> 0.005" in note and note.count("->") == 2
    same = tmp_path / "same.toml"
    same.write_text(text.replace("scans_per_plate = 24", "scans_per_plate = 5").replace("seed = 20040501", "seed = 7")
                    .replace("heights_mm = [0.0, 0.05, 0.1, 0.2]", "heights_mm = [0.0, 0.3]"))
    assert same.read_text() != text and scene_note(fit, same) is None and scene_note(fit, None) is None


def test_a_bare_csv_fit_names_a_scene_at_another_speed(tmp_path):
    """A fit of scans without a scene (a bare CSV) recorded nothing to compare --scene with,
    and an audit's 0.25 mm/s scene simulated a 0.5 mm/s fit's touches without a word. It
    keeps its scans' speed labels; a scene at their speed gives no note."""
    from feeler.calib.neuron.scene_record import scene_note

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        bare = fit_neuron(scene_scans(per_plate=6)[2], seed=4, draws=100)
    attrs = bare.posterior["posterior"].attrs
    assert "scene_toml" not in attrs and attrs["scan_speed_mm_s"] == 0.5
    slow = tmp_path / "slow.toml"
    slow.write_text(FOUR_PLATES.read_text().replace("speed_mm_s = 0.5", "speed_mm_s = 0.25"))
    assert scene_note(bare, slow) == (
        f"note: --scene {slow} moves the stage at 0.25 mm/s, the fit's training scans at 0.5 mm/s (their speed "
        "labels): its touches are not the kind the decoder learned, so P(correct), the threshold and the PSE "
        "describe it reading touches it was not trained on")
    assert scene_note(bare, FOUR_PLATES) is None and scene_note(bare, None) is None


def test_mc_se_column_says_never_only_when_no_draw_overlaps():
    """discriminate printed "touches never overlap" for a pair whose P(correct) was 0.9999983:
    a few draws' touches overlapped, though the interval's 2.5 % point was 1."""
    from feeler.commands.discriminate import mcse_text
    nan = float("nan")
    assert mcse_text(Interval(1.0, 0.99, 1.0, np.ones(400), mcse=nan)) == "-  (touches never overlap)"
    assert mcse_text(Interval(0.0, 0.0, 0.01, np.zeros(400), mcse=nan)) == "-  (touches never overlap)"
    few = np.ones(400)
    few[:3] = 0.9995
    assert mcse_text(Interval(few.mean(), 0.99, 1.0, few, mcse=nan)) == "-  (touches overlap in 0.8 % of draws)"
    one = np.ones(4000)
    one[0] = 0.99
    assert mcse_text(Interval(one.mean(), 0.99, 1.0, one, mcse=nan)) == "-  (touches overlap in under 0.1 % of draws)"
    assert mcse_text(Interval(0.8, 0.7, 0.9, np.full(10, 0.8), mcse=0.01234)) == "0.0123"
