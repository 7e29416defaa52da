"""Acquisition campaigns (issue 4 §4, §7): what one sample costs, piece by piece.

A sample of ``feeler acquire --emulate`` is a status query over the pty, a virtual-camera
frame (render 640×480 with 16 elements), the area extraction and a durable append
(write + flush + fsync). Each piece is timed over the same samples in the same run; the
ratios are to the render alone (the virtual camera's own cost) and, for durability, to
the same append without fsync. The shipped plan samples every 0.5 s; the per-sample cost
must leave most of that period free.
"""
from pathlib import Path

import numpy as np
import pytest

from _ratios import best_seconds, record_ratio
from feeler.hardware.acquire import SAMPLE_COLUMNS, RunStore, load_plan
from feeler.hardware.acquire.world import VirtualWorld

PLAN = Path("tests/hardware/data/tiny-plan.toml")
SHIPPED_PERIOD_S = load_plan("datasets-synthetic/plans/four-plates-plan.toml").scan.sample_period_s


@pytest.fixture(scope="module")
def world():
    return VirtualWorld.of_plan(load_plan(PLAN), PLAN)


def test_durable_append(benchmark, tmp_path):
    store = RunStore.create(tmp_path / "run", PLAN)
    row = {c: 0.123456789 for c in SAMPLE_COLUMNS} | {"scan_id": 0, "plate": 0, "repeat": 0, "attempt": 0}
    plain = tmp_path / "plain.csv"
    with open(plain, "a") as f:
        line = ",".join(str(row[c]) for c in SAMPLE_COLUMNS) + "\n"
        no_sync = best_seconds(lambda: (f.write(line), f.flush()), repeat=200)
    benchmark.pedantic(lambda: store.append_sample(row), rounds=50, iterations=1)
    per = benchmark.stats.stats.median
    record_ratio(benchmark, "append+fsync / append without fsync", per / no_sync, "informational")
    record_ratio(benchmark, "append+fsync / shipped sample period", per / SHIPPED_PERIOD_S, "< 0.1")


def test_sample_pieces(benchmark, world):
    from feeler.hardware.acquire.emulated import campaign_emulator
    from feeler.hardware.camera import AreaExtractor
    from feeler.hardware.stage import Stage

    extract = AreaExtractor(world.layout)
    rng = np.random.default_rng(0)
    pos = (-18.0, -10.0, -20.05)                          # mid-stroke over plate 0, pressed
    render = best_seconds(lambda: world.render(0, pos, rng), repeat=20)
    frame = world.render(0, pos, rng)
    extract_s = best_seconds(lambda: extract(frame), repeat=20)
    from feeler.hardware.acquire import load_plan as plan_of
    from feeler.hardware.acquire.emulated import emulated_stage

    with campaign_emulator(emulated_stage(plan_of(PLAN))) as port, Stage.open(port) as stage:
        status_s = best_seconds(stage.status, repeat=20)

        def sample():
            stage.status()
            extract(world.render(0, pos, rng))

        benchmark.pedantic(sample, rounds=20, iterations=1)
    per = benchmark.stats.stats.median
    print(f"\nper sample: render {1e3 * render:.1f} ms, extract {1e3 * extract_s:.1f} ms, "
          f"status query {1e3 * status_s:.1f} ms, all three {1e3 * per:.1f} ms")
    record_ratio(benchmark, "status+render+extract / render alone", per / render, "informational")
    record_ratio(benchmark, "status+render+extract / shipped sample period", per / SHIPPED_PERIOD_S, "< 0.5")
