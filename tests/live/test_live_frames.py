"""LiveDecoder.push_frame / push_areas: a recorded campaign's frames decode exactly as the
displacements `feeler acquire` derived from them; a bad frame is a one-line error that
leaves the decoder as it was."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from feeler.calib.neuron.live import LiveDecoder
from feeler.errors import ArgumentError, InputError

TINY = Path(__file__).parents[1] / "hardware" / "data" / "tiny-plan.toml"


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """An emulated campaign of the tiny plan (virtual camera; every frame in video/)."""
    from feeler.hardware.acquire import acquire

    out = tmp_path_factory.mktemp("frames") / "run"
    acquire(TINY, out, emulate=True)
    return out


@pytest.fixture(scope="module")
def pipeline(run):
    from feeler.hardware.camera import FramePipeline

    return FramePipeline.of_plan(run / "scene.toml")


def _frames(run, scan_id, pipeline):
    """The scan's recorded frames the campaign used: the video holds every try, so a
    frame the extractor refused is skipped as the campaign skipped it."""
    from feeler.hardware.acquire.cameras import video_path
    from feeler.hardware.camera.source import FrameReader

    return [f for _, f in FrameReader(video_path(run, scan_id), reject_frozen=False) if pipeline(f)[1] is None]


def test_recorded_frames_decode_as_the_acquired_displacements(small_fit, run, pipeline):
    _, fit = small_fit
    samples = pd.read_csv(run / "samples.csv")
    frame_dec, u_dec = LiveDecoder(fit, camera=pipeline), LiveDecoder(fit)
    probs = []
    for scan_id, g in samples.groupby("scan_id"):
        frames = _frames(run, scan_id, pipeline)
        assert len(frames) == len(g)
        frame_dec.reset(), u_dec.reset()
        for frame, row in zip(frames, g.itertuples()):
            a = frame_dec.push_frame(row.t_s, frame, x_mm=row.x_mm)
            b = u_dec.push(row.t_s, (row.ux_mm, row.uy_mm, row.uz_mm), x_mm=row.x_mm)
            np.testing.assert_allclose(a.prob, b.prob, rtol=1e-9, atol=1e-300)
            assert a.z_mm == pytest.approx(b.z_mm, rel=1e-9, abs=1e-12)
        a, b = frame_dec.finish(), u_dec.finish()
        np.testing.assert_allclose(a.prob, b.prob, rtol=1e-9, atol=1e-300)
        assert a.flags == b.flags and a.decision == b.decision
        probs.append(a.prob)
    assert np.ptp(np.array(probs)[:, -1]) > 0       # the plates' scans decode differently: not a constant


def test_areas_read_as_the_campaign_recorded_them(small_fit, run, pipeline):
    _, fit = small_fit
    samples = pd.read_csv(run / "samples.csv")
    g = samples[samples.scan_id == samples.scan_id.iloc[-1]]
    area_dec, u_dec = LiveDecoder(fit, camera=pipeline), LiveDecoder(fit)
    for row in g.itertuples():
        areas = [getattr(row, f"area{i}_px2") for i in range(4)]
        r = pipeline.reading(areas)
        np.testing.assert_allclose(r.u_mm, [row.ux_mm, row.uy_mm, row.uz_mm], rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(r.force_n, [row.fx_n, row.fy_n, row.fz_n], rtol=1e-12, atol=1e-15)
        a = area_dec.push_areas(row.t_s, areas)
        b = u_dec.push(row.t_s, row.uy_mm)
        np.testing.assert_allclose(a.prob, b.prob, rtol=1e-9, atol=1e-300)


def _one_line(exc) -> str:
    text = str(exc.value)
    assert "\n" not in text and isinstance(exc.value, InputError)
    return text


def test_bad_frames_are_one_line_errors_and_change_nothing(small_fit, run, pipeline):
    from feeler.hardware.camera import FrameRejected

    _, fit = small_fit
    dec = LiveDecoder(fit, camera=pipeline)
    good = _frames(run, 0, pipeline)[0]
    before = dec.push_frame(0.0, good)
    h, w = good.shape
    for bad, says in ((good.astype(np.uint16), "uint16 array of shape"),
                      (good[:, : w // 2], f"shape ({h}, {w // 2})"),
                      (good.astype(float), "float64"),
                      (good.tolist(), "list")):
        with pytest.raises(ArgumentError) as exc:
            dec.push_frame(0.5, bad)
        assert says in _one_line(exc) and f"{w}×{h} px" in _one_line(exc)
    blob = good.copy()
    blob[:6, :6] = 255                               # a bright blob outside every feeler window
    with pytest.raises(FrameRejected) as exc:
        dec.push_frame(0.5, blob)
    assert "bright blob outside the feeler windows" in _one_line(exc)
    with pytest.raises(ArgumentError) as exc:
        dec.push_areas(0.5, [1.0, 2.0, 3.0])
    assert "4 areas" in _one_line(exc)
    with pytest.raises(ArgumentError) as exc:
        dec.push_areas(0.5, [np.nan, 2.0, 3.0, 4.0])
    assert "finite areas" in _one_line(exc)
    assert dec.sums.n == before.n == 1                # nothing pushed by the refused samples
    assert dec.push_frame(0.5, good).n == 2


def test_frames_need_a_camera(small_fit, run, pipeline):
    _, fit = small_fit
    dec = LiveDecoder(fit)
    with pytest.raises(ArgumentError) as exc:
        dec.push_frame(0.0, _frames(run, 0, pipeline)[0])
    assert "camera" in _one_line(exc)
    with pytest.raises(ArgumentError) as exc:
        dec.push_areas(0.0, [150.0] * 4)
    assert "FramePipeline" in _one_line(exc)
