"""Calibrated confidence on scenes nobody built: random robot-scan scenes from a seeded generator.

The confidence benchmark's scenes (:mod:`test_bench_confidence`) were each built by hand,
and a model is tested only by scenes it was not tuned on. Here :func:`random_scene`
draws ``SCENES`` scenes from the shipped four-plates (its comments and the parameters not
drawn stay as they are): 3-6 plates, the lowest at 0 (60 %) or 5-30 um, steps 8-30 um
apart; a read-out of 1-4 um; a neuron window of 1-8 s with a boxcar or exponential
kernel; 0.25, 0.5 or 1 mm/s; frames of 0.25, 0.5 or 1 s; 0-80 % snapping touches; a
1-2.5 mm pad pressed 0.04-0.1 mm, tilted by up to 3 deg; 6-15 touches a plate. Each scene
is evaluated as the hand-built ones (``evaluate``: ``REPLICATES`` training sets, each
classifying ``FRESH`` fresh touches a plate), and the goals of issue 14 (ECE ≤ 0.03,
coverage 0.85-0.95 on every plate, log-loss below the plug-in's) are counted over the
scenes whose accuracy lies in 0.6-0.95, the range they were set for. Nothing is asserted
but that the generator makes some such scenes: the counts are the measurement.

32 training sets a scene: a scene's ECE varies more between training sets than between
fresh touches, and over 8 sets its jackknife standard error reached 0.021, as large as
the 0.03 it is judged against (random-02: 0.054 over sets 1-8, 0.025 over sets 1-32).
``FEELER_FULL=1``: 40 scenes, 200 fresh touches a plate. Under ``make bench-load`` the
scenes run 8 sets each: that run measures time, and its counts are those of sets 1-8.

The family (``SEED``) is the one the decoder's changes since session 42 were measured on.
``FEELER_OPEN_WORLD_SEED=N`` draws another. On family 20261129, which no change was tuned on
(16 sets a scene), 5 of its 10 scenes in the range had ECE <= 0.03 (mean 0.027, largest
0.043), 38 of 43 plates were covered 0.85-0.95 (0.82-0.95), and log-loss was below the
plug-in's in 10 of 10. Of its five misses (ECE 0.031-0.043), three are over-confident
(accuracy 0.63-0.68, mean confidence 0.02-0.04 above it; the rides of two of them read at
chance) and two under-confident (accuracy 0.80 and 0.91, confidence 0.02-0.03 below).
Before session 47, when ln γ had one prior sd (0.35) on both sides
(:mod:`feeler.calib.neuron.recalibrate`), it was 4 of 10 (mean 0.028, largest 0.048), and
family 20261128's figures were 14 of 16 (mean 0.0184, largest 0.043) and 64 of 64. Family
20261130 (8 sets a scene, untuned too): 7 of 10 (mean 0.024, largest 0.056; three misses,
all over-confident at accuracy 0.61-0.66), 43 of 47 plates covered (0.85-0.955).
"""
import os
import re
from pathlib import Path

import numpy as np
import pytest

from _ratios import FULL, record_ratio
from test_bench_confidence import evaluate

#: the family of scenes; FEELER_OPEN_WORLD_SEED=N draws another (one nobody tuned the decoder on)
SEED = int(os.environ.get("FEELER_OPEN_WORLD_SEED", "20261128"))
SCENES = 40 if FULL else 20
UNDER_LOAD = bool(os.environ.get("FEELER_BENCH_UNDER_LOAD"))
REPLICATES = 8 if UNDER_LOAD else 32
FRESH = 200 if FULL else 100
TEMPLATE = Path(__file__).resolve().parents[1] / "datasets-synthetic" / "four-plates.toml"
ROWS = []


def random_scene(rng: np.random.Generator, name: str) -> str:
    """The text of one random robot-scan scene (see the module docstring)."""
    n = int(rng.integers(3, 7))
    low = 0.0 if rng.random() < 0.6 else round(float(rng.uniform(0.005, 0.03)), 4)
    heights = np.round(low + np.concatenate([[0.0], np.cumsum(rng.uniform(0.008, 0.03, n - 1))]), 4)
    values = {"name": f'"{name}"', "seed": int(rng.integers(1, 10 ** 6)),
              "heights_mm": "[" + ", ".join(f"{h:g}" for h in heights) + "]",
              "uy_sd_mm": round(float(rng.uniform(0.001, 0.004)), 4), "tau_s": round(float(rng.uniform(1, 8)), 2),
              "speed_mm_s": float(rng.choice([0.25, 0.5, 1.0])), "dt_s": float(rng.choice([0.25, 0.5, 1.0])),
              "snap_prob": round(float(rng.uniform(0, 0.8)), 2), "scans_per_plate": int(rng.integers(6, 16)),
              "tilt_sd_deg": round(float(rng.uniform(0, 3)), 2), "pad_width_mm": round(float(rng.uniform(1, 2.5)), 2),
              "kernel": f'"{rng.choice(["boxcar", "exponential"])}"',
              "uy0_mean_mm": round(float(rng.uniform(0.04, 0.1)), 3)}
    text = TEMPLATE.read_text(encoding="utf-8")
    for key, value in values.items():
        text, found = re.subn(rf"^{key} = [^#\n]*", f"{key} = {value}  ", text, count=1, flags=re.M)
        assert found == 1, f"{TEMPLATE.name} has no '{key} = ' line"
    return text


@pytest.fixture(scope="module")
def scene_paths(tmp_path_factory) -> list[Path]:
    """The ``SCENES`` random scenes, written once for the module."""
    directory, rng = tmp_path_factory.mktemp("open-world"), np.random.default_rng(SEED)
    paths = [directory / f"random-{i:02d}.toml" for i in range(SCENES)]
    for path in paths:
        path.write_text(random_scene(rng, path.stem), encoding="utf-8")
    return paths


@pytest.mark.parametrize("index", range(SCENES), ids=[f"random-{i:02d}" for i in range(SCENES)])
def test_random_scene(benchmark, scene_paths, index):
    path = scene_paths[index]
    row = benchmark.pedantic(lambda: evaluate(path, REPLICATES, FRESH), rounds=1, iterations=1)
    row["hard"] = bool(0.6 <= row["accuracy"] <= 0.95)
    ROWS.append(row)
    refused = f" ({row['n_refused']} refused by classify)" if row["n_refused"] else ""
    heights = re.search(r"^heights_mm = (.*?) *$", path.read_text(encoding="utf-8"), flags=re.M).group(1)
    print(f"\n{row['scene']} {heights}: acc {row['accuracy']:.3f}{'' if row['hard'] else ' (outside 0.6-0.95)'} "
          f"(mean confidence {row['confidence']:.3f})  "
          f"ECE {row['ece']:.4f} (se {row['ece_se']:.4f}; floor {row['ece_floor']:.4f})  log-loss "
          f"{row['log_loss']:.3f} (plug-in {row['log_loss_plugin']:.3f})  gamma {row['sharpness_median']:.2f}  "
          f"verdict ok {row['n_ok']} of {REPLICATES}{refused}  coverage " + " ".join(f"{c:.2f}" for c in row["coverage"]))
    benchmark.extra_info.update({"training_sets": REPLICATES, "accuracy": row["accuracy"], "ece": row["ece"],
                                 "ece_se": row["ece_se"], "log_loss": row["log_loss"],
                                 "log_loss_plugin": row["log_loss_plugin"],
                                 "coverage": [float(c) for c in row["coverage"]]})


def test_summary(benchmark):
    """The goals counted over the random scenes in the 0.6-0.95 accuracy range."""
    hard = [r for r in ROWS if r["hard"]]
    if not hard:
        pytest.skip("no random scene ran (run the whole module)")
    ece_ok = sum(r["ece"] <= 0.03 for r in hard)
    plates = np.concatenate([r["coverage"] for r in hard])
    covered = int(np.sum((plates >= 0.85) & (plates <= 0.95)))
    beats = sum(r["log_loss"] < r["log_loss_plugin"] for r in hard)
    benchmark.pedantic(lambda: None, rounds=1, iterations=1)
    record_ratio(benchmark, "random scenes with ECE <= 0.03 (share)", ece_ok / len(hard), "1")
    record_ratio(benchmark, "plates covered 0.85-0.95 (share)", covered / plates.size, "1")
    record_ratio(benchmark, "log-loss below the plug-in's (share)", beats / len(hard), "1")
    under = sum(r["confidence"] < r["accuracy"] for r in hard if r["ece"] > 0.03)
    print(f"\nfamily {SEED}, {REPLICATES} training sets a scene. "
          f"{len(hard)} of {len(ROWS)} random scenes in the 0.6-0.95 accuracy range: ECE <= 0.03 in {ece_ok} "
          f"(mean {np.mean([r['ece'] for r in hard]):.4f}, largest {max(r['ece'] for r in hard):.4f}); "
          f"{covered} of {plates.size} plates covered 0.85-0.95 (range {plates.min():.2f}-{plates.max():.2f}); "
          f"log-loss below the plug-in's in {beats}; of the {len(hard) - ece_ok} over 0.03, {under} under-confident "
          "(mean confidence below accuracy)")
    assert len(hard) >= len(ROWS) // 3, "the generator made too few scenes in the range the goals are for"
