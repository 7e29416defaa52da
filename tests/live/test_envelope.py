"""The training envelope: each check flags what lies outside, names unit mistakes, and
stays quiet inside (one case per branch)."""

import numpy as np
import pytest

from feeler.calib.neuron.live.envelope import Envelope, training_speed_mm_s
from feeler.errors import ArgumentError

ENV = Envelope(period_s=0.5, duration_s=20.0, speed_mm_s=0.5, p_lo=np.array([0.01, 0.02]),
               p_hi=np.array([0.05, 0.1]))


def test_inside_is_quiet():
    t = np.arange(41) * 0.5
    assert ENV.problems(t, [0.03, 0.05], x_mm=t * 0.5, speed_mm_s=0.5) == []


def test_each_check_flags_and_names_units():
    assert "sampling period" in ENV.period(1.0) and "ms" in ENV.period(500.0)
    assert ENV.period(0.55) is None
    assert "speed 2 mm/s, 4×" in ENV.speed(2.0)
    assert "x probably in um" in ENV.speed(500.0, labelled=0.5)
    assert "times probably in min" in ENV.speed(30.0, labelled=0.5)          # t_s in minutes: 60× (it said x in um)
    assert "times probably in ms" in ENV.speed(0.0005, labelled=0.5)
    assert "speed_mm_s probably in mm/min" in ENV.speed(0.5, labelled=30.0)    # a Grbl feed rate: 60×
    assert "did not move" in ENV.speed(0.0)
    assert ENV.duration(30.0, final=False) and ENV.duration(5.0, final=False) is None
    assert ENV.duration(5.0, final=True)
    assert "um" in ENV.response([50.0, 100.0], final=False)
    assert ENV.response([0.001, 0.002], final=False) is None and ENV.response([0.001, 0.002], final=True)
    assert "no response" in ENV.response([0.0, 0.0], final=True)
    assert "U_y probably in m" in ENV.response([1e-5, 2e-5], final=True)
    assert ENV.response([1e-5, 2e-5], final=True, short=True) == "response 0.001× the smallest training scan's"


def test_a_short_scan_names_no_unit_and_one_sample_is_no_scan():
    """Two samples of a 20 s scan: it ended before its step, so its small response is
    no sign of U_y in m (classify refused the file for 'U_y probably in m'). One sample
    has no change to sum at all (it read 'no response (U_y constant)')."""
    q = ENV.problems(np.array([0.0, 0.5]), [1e-5, 2e-5])
    assert q[0].startswith("scan of 0.5 s, 0.025× the fit's 20 s") and not any("probably in" in r for r in q)
    assert ENV.problems(np.array([0.0]), [0.0, 0.0]) == ["1 sample: a scan needs samples over the fit's 20 s to be "
                                                         "decoded"]
    assert ENV.problems_of(1, 0.0, 0.0, [0.0, 0.0], final=False) == []          # a stream's first sample: wait
    assert Envelope(0.5, 20.0, None, ENV.p_lo, ENV.p_hi).speed(2.0) is None       # no recorded speed


def test_stream_summary_equals_whole_scan_check():
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.2, 1.4, 30))
    x = t * 1.3
    whole = ENV.problems(t, [0.2, 0.3], x_mm=x)
    assert whole == ENV.problems_of(t.size, t[0], t[-1], [0.2, 0.3], x_ends_mm=(x[0], x[-1]))
    assert len(whole) == 3          # period, speed, response (24 s is within 1.25× of 20 s)


def test_scene_speed_and_bad_factors():
    assert training_speed_mm_s({"scene_toml": "[motion]\nspeed_mm_s = 0.5\n"}) == 0.5
    assert training_speed_mm_s({"scene_toml": "[scan]\nspeed_mm_s = 10\n"}) == 10.0
    assert training_speed_mm_s({"scene_toml": "not toml ["}) is None and training_speed_mm_s({}) is None
    assert training_speed_mm_s({"scan_speed_mm_s": 0.25}) == 0.25          # a bare CSV's fit: its scans' labels
    assert training_speed_mm_s({"scene_toml": "[motion]\nspeed_mm_s = 0.5\n", "scan_speed_mm_s": 0.25}) == 0.5
    with pytest.raises(ArgumentError):
        Envelope(0.5, 20.0, 0.5, ENV.p_lo, ENV.p_hi, slack=1.0)


def test_a_reading_far_from_every_plate_is_a_step_not_trained_on():
    assert ENV.plates(4.9, 0.2, 0.21) is None
    line = ENV.plates(27.4, 0.2, 0.3)
    assert line.startswith("decoded height 0.3 mm lies 27 sds from the nearest trained plate (0.2 mm)")
    assert "not trained on" in line
    with pytest.raises(ArgumentError, match="plate_sds"):
        Envelope(0.5, 20.0, None, ENV.p_lo, ENV.p_hi, plate_sds=1.0)


def test_readout_noise_is_the_white_noise_whatever_the_step_and_drift():
    """The robust second-difference estimate recovers σ of white noise on a flat scan, and
    the same σ under a 0.1 mm snap, a 3 s ride and a slow creep (each touches only a few
    second differences); closed form: MAD of N(0, 6σ²) × 1.4826 / √6 = σ."""
    from feeler.calib.neuron.live.envelope import readout_noise_mm

    rng = np.random.default_rng(4)
    t = np.arange(4001) * 0.5
    noise = 0.002 * rng.standard_normal(t.size)
    flat = readout_noise_mm(noise)
    assert abs(flat / 0.002 - 1) < 0.05
    snap = 0.1 * (t >= 1000.0)
    ride = 0.1 * np.clip((t - 1000.0) / 3.0, 0, 1)
    for shape in (snap, ride, snap + 0.0002 * t):
        assert abs(readout_noise_mm(noise + shape) / flat - 1) < 0.01
    assert readout_noise_mm(np.zeros(100)) == 0.0 and np.isnan(readout_noise_mm([1.0, 2.0, 3.0, 4.0]))


def test_a_scan_or_a_batch_noisier_than_training_is_flagged():
    train = np.random.default_rng(5).lognormal(np.log(0.001), 0.2, 96)        # 1 um, ±20 % per scan
    env = Envelope(0.5, 20.0, 0.5, ENV.p_lo, ENV.p_hi, noise_mm=train)
    top = train.max()
    assert env.noise(1.49 * top) is None and env.noise(0.1 * top) is None    # less noise: not flagged
    line = env.noise(1.6 * top)
    assert line.startswith(f"read-out noise {1.6 * top * 1e3:.3g} um, 1.6× the noisiest training scan's")
    # noise-free training scans (a fit used with --accept-failed): no ratio to give ('0.887 um the noisiest
    # training scan's 0 um'), and a plate of no spread puts a reading 1e14 sds away
    quiet = Envelope(0.5, 20.0, 0.5, ENV.p_lo, ENV.p_hi, noise_mm=np.zeros(8))
    assert quiet.noise(0.000887) == ("read-out noise 0.887 um where the training scans had none (noise-free: the "
                                     "plates were learned without noise)")
    assert "lies more than 10^4 sds from the nearest trained plate (0 mm)" in ENV.plates(1.5e14, 0.0, 0.00648)
    assert "lies 7 sds from" in ENV.plates(7.2, 0.05, 0.08)
    # a response below the lowest plate decodes to its height (the scale stops at 0): said so, as the
    # bare "decoded height 0 mm lies 6 sds from the nearest trained plate (0 mm)" contradicted itself
    assert ("decoded height 0 mm lies 6 sds from the nearest trained plate (0 mm; its response lies beyond that "
            "plate's band, where the height scale ends)") in ENV.plates(6.1, 0.0, 0.0)
    assert "plate's band" not in ENV.plates(7.2, 0.05, 0.08)
    same = np.random.default_rng(6).lognormal(np.log(0.001), 0.2, 40)
    assert env.batch_noise(same) is None and env.batch_noise(same / 2) is None
    line = env.batch_noise(same * 1.5)
    assert line.startswith("these 40 scans' read-out noise (median 1.") and "the training scans' (" in line
    assert env.batch_noise(same[:4] * 3) is None                    # too few scans for a median: per scan only
    assert env.batch_noise(np.r_[same * 1.5, 0.0]) is not None      # a constant scan among them changes nothing
    assert Envelope(0.5, 20.0, 0.5, ENV.p_lo, ENV.p_hi).batch_noise(same * 3) is None      # an older fit
    # quieter: a third or less is another set-up; a fifth or less, U_y in a larger unit (cm: 0.1)
    assert env.batch_noise(same / 4).endswith("a quieter set-up, so the plates learned at more noise do not "
                                              "describe them (refit on such scans)")
    assert "U_y probably in cm or inches (expected mm)" in env.batch_noise(same / 10)
    assert env.batch_noise(same[:4] / 10) is None
    t = np.arange(41) * 0.5
    uy = 0.05 + 0.1 * (t >= 10) + 0.005 * np.random.default_rng(7).standard_normal(41)
    assert any(q.startswith("read-out noise") for q in env.problems(t, [0.03, 0.05], x_mm=t * 0.5, uy_mm=uy))
    with pytest.raises(ArgumentError, match="noise_factor"):
        Envelope(0.5, 20.0, None, ENV.p_lo, ENV.p_hi, noise_factor=1.0)


def test_a_single_sample_spike_is_a_glitch_a_snap_or_a_ride_is_not():
    """A spike jumps off both neighbours, which agree; a snap steps and stays, a ride ramps.
    Clean whole scans reach 12.4 noise sds on this statistic (58 750 of 53 scenes), a
    stream's prefixes 13.5; 15 flags a whole scan, 20 a stream so far."""
    from feeler.calib.neuron.live.envelope import SPIKE_SDS, SPIKE_SDS_STREAM, spike_of, spike_problem

    rng = np.random.default_rng(9)
    t = np.arange(41) * 0.5
    noise = 0.001 * rng.standard_normal(41)
    snap = 0.05 + 0.2 * (t >= 10) + noise
    ride = 0.05 + 0.2 * np.clip((t - 9) / 3, 0, 1) + noise
    assert spike_of(snap) is None and spike_of(ride) is None and spike_of(noise) is None
    glitch = snap.copy()
    glitch[30] += 0.5
    k, size, sds = spike_of(glitch)
    assert k == 30 and abs(size - 0.5) < 0.01 and sds > SPIKE_SDS
    assert spike_problem(glitch, t).startswith("U_y jumps +")
    assert "at t = 15 s and back at the next sample" in spike_problem(glitch, t)
    down = snap.copy()
    down[5] -= 0.05                                                   # a drop-out: a spike downwards
    assert spike_of(down)[0] == 5 and spike_of(down)[1] < 0
    quantised = np.round(glitch, 2)                                   # no read-out noise to compare with
    assert spike_of(np.round(snap, 2)) is None and spike_of(quantised) is None
    assert any(q.startswith("U_y jumps") for q in ENV.problems(t, [0.03, 0.05], x_mm=t * 0.5, uy_mm=glitch))
    # a spike of 17.5 sds by this measure on a flat scan: at 20 sds, 2 of 8 spikes of 15 um on
    # flat scans of 1 um noise were caught and the rest read as 0.05 mm at p 0.999 (an outside
    # audit); a whole scan is judged at 15
    flat = 0.05 + noise
    flat[25] += 0.01
    flat[25] += 0.01 * (17.5 / spike_of(flat, sds=0.0)[2] - 1.0)          # the excursion grows with the size
    _, _, sds = spike_of(flat, sds=0.0)
    assert SPIKE_SDS < sds < SPIKE_SDS_STREAM
    assert spike_of(flat)[0] == 25 and spike_of(flat, sds=SPIKE_SDS_STREAM) is None
    assert spike_problem(flat, t) is not None and spike_problem(flat, t, sds=SPIKE_SDS_STREAM) is None


def test_clean_fresh_scans_show_no_spike():
    """The whole-scan threshold against 500 fresh clean scans of the noisy hard scene at a
    seed no check used, and at twice its stage speed (21-sample scans, whose noise rests on
    16 second differences: the heaviest tail): none flagged, the largest well inside."""
    from feeler.calib.neuron.live.envelope import SPIKE_SDS, spike_of
    from feeler.calib.neuron.synth import HARD_SCENES, scene_scans

    noisy = HARD_SCENES / "noisy.toml"
    largest = []
    for speed in (None, 1.0):
        scene, _, data = scene_scans(noisy, seed=31_337, per_plate=50 if speed else 75, speed_mm_s=speed)
        uy = data.strain * scene.neuron.length_mm
        assert not any(spike_of(u) for u in uy)
        largest.append(max((spike_of(u, sds=0.0) or (0, 0.0, 0.0))[2] for u in uy))
    assert 3.0 < min(largest) and max(largest) < 0.8 * SPIKE_SDS, largest


def test_an_early_glitch_holds_until_the_spike_check_can_judge():
    """Before 20 samples the noise is unknown, so a one-sample excursion of half the rise
    without it is held as a possible glitch; a snap, a ride or noise alone is not, nor a
    small excursion on a large rise, and from 20 samples on :func:`spike_of` judges."""
    from feeler.calib.neuron.live.envelope import SPIKE_MIN_DIFFERENCES, early_spike

    rng = np.random.default_rng(3)
    t = np.arange(19) * 0.5
    noise = 0.001 * rng.standard_normal(t.size)
    snap = 0.05 + 0.2 * (t >= 5) + noise
    ride = 0.05 + 0.2 * np.clip((t - 4) / 3, 0, 1) + noise
    assert not any(early_spike(u) for u in (snap, ride, noise, noise[:3], noise[:2]))
    glitch = 0.05 + noise
    glitch[5] += 0.03                                   # 30 noise sds, on a flat stretch
    assert early_spike(glitch) and early_spike(glitch[:7]) and not early_spike(glitch[:6])   # needs its next sample
    on_rise = ride.copy()
    on_rise[2] += 0.03                                  # 0.03 on a 0.2 rise: not what sets the peak
    assert not early_spike(on_rise)
    big = ride.copy()
    big[2] += 0.12
    assert early_spike(big)
    longer = np.concatenate([glitch, 0.05 + 0.001 * rng.standard_normal(SPIKE_MIN_DIFFERENCES + 5)])
    assert not early_spike(longer)                      # long enough: spike_of's to judge


def test_a_scan_that_falls_as_a_touch_rises_is_flagged(small_fit):
    """U_y reversed in time or with its sign flipped: the window sums follow how much U_y
    changes, so such a scan still read as its plate, at p 0.999, with intervals holding for
    59-60 % (an outside audit). A scan that falls by more than half its range, within a
    fifth of a training scan, by 8 read-out noise sds or more, while read as a riser, is flagged.
    Not flagged: every training scan as it is; a flat plate drifting down (read as plate 0);
    a step down when the fit has steps below 0."""
    from feeler.calib.neuron.classify import classify

    data, res = small_fit
    length = float(res.posterior["posterior"].attrs["length_mm"])
    u = data.strain * length
    c = classify(res, data.strain, data.t_s, rng=np.random.default_rng(0))
    env = Envelope.of_fit(res, c.tau_s)
    riser = data.step_mm > 0
    assert not any(env.falling(u[k], c.plates_mm, c.height_mm[k]) for k in range(len(u)))
    for turned in (u[:, ::-1], -u):
        r = classify(res, turned / length, data.t_s, rng=np.random.default_rng(0))
        said = [env.falling(turned[k], r.plates_mm, r.height_mm[k]) for k in range(len(u))]
        assert all(s is not None and s.startswith("U_y falls by ") for s, up in zip(said, riser) if up)
        assert not any(s for s, up in zip(said, riser) if not up)            # a flat plate has no step to turn
    t = np.asarray(data.t_s)
    drifting = u[~riser][0] - 0.002 * t                                      # 40 um down over a flat plate
    assert env.falling(drifting, c.plates_mm, 0.0) is None
    assert env.falling(-u[riser][0], np.r_[-0.1, c.plates_mm], 0.1) is None     # steps down were trained
    calls = []
    assert env.falling(u[riser][0], c.plates_mm, lambda: calls.append(1) or 0.1) is None and not calls
