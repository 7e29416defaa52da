"""The live decoder (issue 13): per-sample cost against the sample period, idle and under
load, and the decision latency / accuracy trade over decision thresholds.

Scene: ``datasets-synthetic/hard/close-steps.toml`` (steps 0.05–0.0725 mm, 0.5 s frames;
plates not trivially separable: batch accuracy well below 100 %). One fit on the scene's
training touches (the default grid backend); ``FRESH`` fresh touches per plate (seed + 10⁶)
streamed sample by sample through :class:`~feeler.calib.neuron.live.LiveDecoder` at the
default 400 draws.

- Cost: wall time of every ``push`` (probabilities, decoded z, decision rule, envelope
  flags; the height interval is computed lazily — its cost when read at every sample is
  the second figure), as a fraction of the scene's 0.5 s sample period: median and p99,
  idle and with two busy-loop processes on the two cores. Goals: p99 ≤ 1 % idle; p99
  under load within 2× of idle. Recorded, not asserted (a shared machine's timings).
- Frame pipeline: the same scans rendered as the 16-element sensor's camera frames
  (640×480, the virtual camera's optics and shot noise, the scanning element 5, every other
  element at rest) and pushed through :meth:`LiveDecoder.push_frame` — frame → areas of
  all 16 elements → the scanning element's force → displacement → decode, the reading
  chain of ``feeler acquire`` (:class:`~feeler.hardware.camera.FramePipeline`): wall time
  per sample as a fraction of the period, median and p99, idle and loaded. Goals: p99 ≤
  5 % idle; p99 under load within 2× of idle. The extraction alone (``read``) beside it.
- Arrival: a live decoder is fed at the sample period and waits in between. Every figure
  is measured two ways: ``paced`` — the samples (frames) arrive every :data:`GAP_S`
  (:data:`GAP_FRAME_S`), the decoder sleeping in between as in ``feeler acquire
  --decode`` (a shorter gap than the real 0.5 s, so that a run gathers enough samples for
  a p99) — and ``back to back``, one push after the other, the decoder never sleeping. The
  goals apply to ``paced``: it is what a user's acquisition meets. ``back to back`` is
  the extra column that shows the scheduler: with two busy loops three always-runnable
  processes share two cores, and a push that straddles a preemption waits a time slice
  (a few ms), which p99 catches (measured 6–10× idle when a push took ~1 ms, 0.9–2.4×
  at ~0.3 ms; CPU p99 within 1.15×, unchanged by one BLAS thread, OpenCV's 1 or 2
  threads or the garbage collector off). A decoder that slept until its next sample
  is, most likely, scheduled ahead of the busy loops (the kernel's EEVDF scheduler
  places a task that slept by its lag): paced push p99 loaded/idle measured 0.8–1.0.
  A frame (~2 ms since the extractor reuses its work images; 3–5 ms before) is longer
  than the fair scheduler's base slice (0.75 ms by default), so under two busy loops up to
  one frame in ten waits a scheduler tick (4 ms at HZ = 250) behind a busy loop: paced p99
  loaded/idle 1.5–2.1. Frames are also measured ``paced, --realtime``: the loop at
  real-time priority as ``feeler acquire --realtime`` runs it
  (:mod:`feeler.hardware.realtime`; where the system permits it, else the row says why
  it was not measured): 0.8–1.0. An idle core that slept clocks down with cold caches,
  so paced idle medians are up to ~2× back-to-back's.
- Wall and CPU time: every per-sample figure is given twice, as wall time and as CPU time
  (``CPU …``: this thread's for ``push``, the process's — OpenCV's workers included — for
  the frames). A push takes ~0.3 ms (scipy's logsumexp and np.median, ~0.1 and ~0.04 ms
  of checks a call, replaced by lean equivalents).
- Trade: per fall from the peak ``drop`` in :data:`DROPS` and threshold θ in :data:`THRESHOLDS`, a scan is decided at the first sample
  where its response has passed its peak and the top plate's probability is ≥ θ (the
  decoder's rule, applied to one recorded pass; checked equal to the decoder's own
  decision at one θ). Accuracy = correct decisions / all scans (an undecided scan counts
  as wrong); latency = median over decided scans of the time since the stage passed the
  step (s) and of the travel past it (mm); also the fraction decided and the accuracy of
  the decisions made. After the peak P no longer changes, so a scan below θ then stays
  undecided: θ trades decisions made for their accuracy, ``drop`` trades latency for
  robustness to a second rise. Written to ``runs/benchmarks/decoder.csv`` (columns
  option, drop, threshold, latency_s, latency_mm, accuracy, decided, accuracy_decided —
  the report's speed section draws latency_s against accuracy) and ``decoder.png``.
"""
import contextlib
import os
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

from _ratios import FULL, LOADS, busy_loops, record_ratio
from feeler.calib.neuron import fit_neuron
from feeler.calib.neuron.live import LiveDecoder
from feeler.calib.neuron.live.trade import decision_index, end_row, record_pass, trade_rows
from feeler.calib.neuron.synth import HARD_SCENES, scene_scans
from feeler.hardware.realtime import realtime_priority

FRESH = 150 if FULL else 40
FRAME_SCANS = 24 if FULL else 12       # scans rendered as camera frames (41 frames each)
GAP_S = 0.005                          # s between paced samples (push)
GAP_FRAME_S = 0.015                    # s between paced frames (push_frame, ~2 ms each)
ARRIVALS = {"paced": True, "back to back": False}
#: frames: (gap s, real-time priority as ``feeler acquire --realtime``) per arrival
FRAME_ARRIVALS = {"paced": (GAP_FRAME_S, False), "back to back": (0.0, False),
                  "paced, --realtime": (GAP_FRAME_S, True)}
SCENE = Path(HARD_SCENES) / "close-steps.toml"
THRESHOLDS = (0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 0.99)
DROPS = (0.25, 0.5, 0.75)
OUT = Path(__file__).resolve().parents[1] / "runs" / "benchmarks"
if os.environ.get("FEELER_BENCH_UNDER_LOAD"):
    OUT = OUT / "load"


@pytest.fixture(scope="module")
def setup():
    from feeler.scene import load_scene

    seed = load_scene(SCENE).scene.seed
    scene, _, train = scene_scans(SCENE)
    _, fresh, _ = scene_scans(SCENE, seed=seed + 10 ** 6, per_plate=FRESH)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = fit_neuron(train, seed=1)
    return scene, fresh, fit


def _stream(dec, scans, k, *, height: bool = False, gap: float = 0.0):
    """One scan through ``dec``, a sample every ``gap`` s (0: back to back); per sample
    (wall s, peaked, top p, top plate, t, x, CPU s of this thread)."""
    dec.reset()
    rows = []
    for t, uy, x in zip(scans.t_s[k], scans.uy_mm[k], scans.x_mm[k]):
        if gap:
            time.sleep(gap)
        c0, t0 = time.thread_time(), time.perf_counter()
        s = dec.push(t, uy, x_mm=x)
        if height:
            s.height_mm
        dt, cpu = time.perf_counter() - t0, time.thread_time() - c0
        j = int(np.argmax(s.prob))
        rows.append((dt, s.peaked, float(s.prob[j]), float(dec.plates_mm[j]), t, x, cpu))
    return np.array(rows)


def _record_p99(benchmark, p99, what, label, wall, cpu, goal):
    """Median and p99 of per-sample wall and CPU fractions of the period, under ``label``."""
    for clock, v in (("", wall), ("CPU ", cpu)):
        med, p99[clock + what, label] = float(np.median(v)), float(np.percentile(v, 99))
        benchmark.extra_info[f"{clock}{what} [{label}]: median fraction of period"] = med
        benchmark.extra_info[f"{clock}{what} [{label}]: p99 fraction of period"] = p99[clock + what, label]
        record_ratio(benchmark, f"{clock}{what} p99 / sample period [{label}]", p99[clock + what, label],
                     goal if not clock else "(CPU time: the code's own share)")


def _record_loaded_over_idle(benchmark, p99, whats):
    labels = list(LOADS)
    if len(labels) == 2:
        for what in whats:
            for clock in ("", "CPU "):
                if any((clock + what, lab) not in p99 for lab in labels):
                    continue
                goal = "<= 2" if "[paced" in what else "(extra: back to back)"
                record_ratio(benchmark, f"{clock}{what} p99 loaded / idle",
                             p99[clock + what, labels[1]] / p99[clock + what, labels[0]], goal)


def test_per_sample_cost_against_the_sample_period(benchmark, setup):
    scene, fresh, fit = setup
    period = scene.motion.dt_s
    dec = LiveDecoder(fit, seed=0)
    n = min(fresh.t_s.shape[0], 30)
    p99, whats = {}, []
    for label, n_busy in LOADS.items():
        with busy_loops(n_busy):
            for arrival, paced in ARRIVALS.items():
                cases = [("push", False, n)]
                if paced:      # the height read at every sample only paced: ~7 ms a read
                    cases.append(("push + height", True, max(n // 4, 1)))
                for what, height, m in cases:
                    per = np.concatenate([_stream(dec, fresh, k, height=height, gap=GAP_S if paced else 0.0)
                                          [:, [0, 6]] for k in range(m)]) / period
                    key = f"{what} [{arrival}]"
                    goal = ("push: <= 0.01 (1 %)" if what == "push" and paced
                            else "(the height read every sample)" if height else "(extra: back to back)")
                    _record_p99(benchmark, p99, key, label, per[:, 0], per[:, 1], goal)
                    whats.append(key)
    _record_loaded_over_idle(benchmark, p99, tuple(dict.fromkeys(whats)))
    benchmark.pedantic(lambda: _stream(dec, fresh, 0), rounds=3, iterations=1)


@pytest.fixture(scope="module")
def frames(setup):
    """(FramePipeline, frames uint8[m, n, 480, 640]) of the first :data:`FRAME_SCANS` fresh scans."""
    from feeler.hardware.camera import FramePipeline
    from feeler.models.optics import (CameraParams, OpticsParams, areas_from_force, force_from_displacement,
                                      grid_layout, render_frames)

    _, fresh, _ = setup
    layout, optics, element = grid_layout(), OpticsParams(), 5
    m = min(FRAME_SCANS, fresh.t_s.shape[0])
    u = np.zeros((m, fresh.t_s.shape[1], len(layout.elements), 3))
    u[:, :, element] = np.stack([fresh.ux_mm[:m], fresh.uy_mm[:m], fresh.uz_mm[:m]], axis=-1)
    areas = areas_from_force(force_from_displacement(u, optics.c_matrix), optics)
    rendered = render_frames(areas.reshape(-1, *areas.shape[2:]), layout, CameraParams(), np.random.default_rng(0))
    pipe = FramePipeline(layout, element, optics.c_matrix, optics, blur_sd_px=CameraParams().blur_sd_px)
    return pipe, rendered.reshape(m, -1, *rendered.shape[1:])


def _stream_frames(dec, scans, frames, k, gap: float = 0.0):
    """Scan ``k``'s frames through ``dec.push_frame``, a frame every ``gap`` s (0: back to
    back); per sample (wall s, CPU s of the process: OpenCV's worker threads included)."""
    dec.reset()
    out = np.empty((frames.shape[1], 2))
    for i, (t, x) in enumerate(zip(scans.t_s[k], scans.x_mm[k])):
        if gap:
            time.sleep(gap)
        c0, t0 = time.process_time(), time.perf_counter()
        dec.push_frame(t, frames[k, i], x_mm=x)
        out[i] = time.perf_counter() - t0, time.process_time() - c0
    return out


def _read_times(pipe, frames, gap: float = 0.0):
    """Per frame (wall s, CPU s of the process) of ``pipe.read`` alone, a frame every ``gap`` s."""
    out = np.empty((len(frames), 2))
    for i, f in enumerate(frames):
        if gap:
            time.sleep(gap)
        c0, t0 = time.process_time(), time.perf_counter()
        pipe.read(f)
        out[i] = time.perf_counter() - t0, time.process_time() - c0
    return out


def test_frame_pipeline_cost_against_the_sample_period(benchmark, setup, frames):
    scene, fresh, fit = setup
    pipe, shots = frames
    period = scene.motion.dt_s
    dec = LiveDecoder(fit, seed=0, camera=pipe)
    benchmark.extra_info["opencv threads"] = __import__("cv2").getNumThreads()
    p99, whats = {}, []
    for label, n_busy in LOADS.items():
        with busy_loops(n_busy):
            for arrival, (gap, realtime) in FRAME_ARRIVALS.items():
                with realtime_priority() if realtime else contextlib.nullcontext() as refused:
                    if refused:
                        benchmark.extra_info[f"{arrival} [{label}]"] = f"not measured: {refused}"
                        continue
                    per = np.concatenate([_stream_frames(dec, fresh, shots, k, gap) for k in range(shots.shape[0])])
                    read = _read_times(pipe, shots.reshape(-1, *shots.shape[2:]), gap)
                for what, v, goal in (("push_frame", per, "push_frame: <= 0.05 (5 %)"),
                                      ("read (frame → U)", read, "(its share)")):
                    key = f"{what} [{arrival}]"
                    _record_p99(benchmark, p99, key, label, v[:, 0] / period, v[:, 1] / period,
                                goal if gap else "(extra: back to back)")
                    whats.append(key)
    _record_loaded_over_idle(benchmark, p99, tuple(dict.fromkeys(whats)))
    benchmark.pedantic(lambda: _stream_frames(dec, fresh, shots, 0), rounds=3, iterations=1)


def test_decision_latency_against_accuracy(benchmark, setup):
    import pandas as pd

    scene, fresh, fit = setup
    step_x = scene.surface.position_mm
    rows, passes = [], None
    for drop in DROPS:
        dec = LiveDecoder(fit, seed=0, threshold=0.9, drop=drop)
        passes = [record_pass(dec, fresh.t_s[k], fresh.uy_mm[k], fresh.x_mm[k]) for k in range(fresh.t_s.shape[0])]
        for k in range(3):                   # the decoder's own decision is the rule on the recorded pass
            dec.reset()
            for t, uy in zip(fresh.t_s[k], fresh.uy_mm[k]):
                s = dec.push(t, uy)
            d = dec.finish().decision
            assert (None if d is None else d.index) == decision_index(passes[k], dec.threshold)
        rows += [{**r, "drop": drop} for r in trade_rows(passes, fresh.step_mm, step_x, THRESHOLDS,
                                                          label=f"drop {drop:g}, ")]
    end = end_row(passes, fresh.step_mm, step_x)
    rows.append(end)
    table = pd.DataFrame(rows)
    OUT.mkdir(parents=True, exist_ok=True)
    table.to_csv(OUT / "decoder.csv", index=False)
    _plot(table, OUT / "decoder.png")
    print("\n" + table.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    for r in rows:
        benchmark.extra_info[f"{r['option']}: accuracy"] = r["accuracy"]
        benchmark.extra_info[f"{r['option']}: latency_s"] = r["latency_s"]
    assert 0.3 < end["accuracy"] < 0.99, "the scene must not be trivially separable (the condition of the trade)"
    benchmark.pedantic(lambda: None, rounds=1, iterations=1)


def _plot(table, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5, 3.5))
    t = table.dropna(subset=["latency_s"])
    for drop, g in t.dropna(subset=["drop"]).groupby("drop"):
        ax.plot(g.latency_s, g.accuracy, "o-", label=f"drop {drop:g}")
        for r in g.itertuples():
            ax.annotate(f"θ={r.threshold:g}", (r.latency_s, r.accuracy), fontsize=6, xytext=(3, -7),
                        textcoords="offset points")
    e = t[t["drop"].isna()]
    ax.plot(e.latency_s, e.accuracy, "ks", label="end of scan")
    ax.legend(fontsize=7)
    ax.set_xlabel("decision latency after the step (s, median)")
    ax.set_ylabel("accuracy (undecided = wrong)")
    ax.set_title("Live decoder: latency against accuracy (close steps)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
