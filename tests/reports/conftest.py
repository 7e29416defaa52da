"""One small demo run per session, shared by the report tests, and its report.

The demo runs every stage a user's `feeler demo` runs, at small sizes: four-plates with 6
scans per plate (its name turned into a script tag, to test escaping), the finger-steps
scene with three steps on a coarse mesh, 80 touches per height for the discrimination.
A tiny real acquisition (the emulated Grbl stage and the virtual camera, 2 plates x 1
scan) is made once for the tests that need one.

Under pytest-xdist (``make test`` runs two workers) the demo run is made once for all
workers (:func:`once_per_session`): the tests only read it, or copy what they change.
"""
from __future__ import annotations

import fcntl
import os
import shutil
from pathlib import Path

import pytest

from feeler.cli import main
from tests.small_scenes import small_finger_scene

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "datasets-synthetic"
EVIL = "<script>alert(1)</script>"
TINY_PLAN = ROOT / "tests" / "hardware" / "data" / "tiny-plan.toml"


@pytest.fixture(scope="session")
def evil_name() -> str:
    """The robot scene's name in the report tests: markup that must come out escaped (a
    fixture, not an import: with tests/psy collected too, ``conftest`` is another module)."""
    return EVIL


def small_scenes(tmp: Path) -> tuple[Path, dict]:
    """(four-plates with 6 scans per plate and an evil name, {"finger-steps": a small one})."""
    robot = tmp / "four-plates.toml"                  # the demo files its scans under the file's name
    text = (SCENES / "four-plates.toml").read_text(encoding="utf-8")
    robot.write_text(text.replace('name = "four-plates"', f'name = "{EVIL}"')
                     .replace("scans_per_plate = 24", "scans_per_plate = 6"), encoding="utf-8")
    return robot, {"finger-steps": small_finger_scene(tmp / "finger-small.toml")}


def once_per_session(tmp_path_factory, name: str, build) -> Path:
    """A directory ``build(dir)`` fills once per test session: under pytest-xdist the first
    worker to take the lock builds it in the workers' common temporary root and the others
    wait for it, then reuse it (a build that failed is tried again by the next worker)."""
    if os.environ.get("PYTEST_XDIST_WORKER") is None:
        path = tmp_path_factory.mktemp(name)
        build(path)
        return path
    root = tmp_path_factory.getbasetemp().parent
    path, done = root / name, root / f"{name}.done"
    with open(root / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not done.is_file():
            shutil.rmtree(path, ignore_errors=True)
            path.mkdir()
            build(path)
            done.touch()
    return path


@pytest.fixture(scope="session")
def run_dir(tmp_path_factory) -> Path:
    return once_per_session(tmp_path_factory, "demo-run", _make_demo_run) / "run"


def _make_demo_run(tmp: Path) -> None:
    from feeler.demo import run_demo

    robot, scenes = small_scenes(tmp)
    printed = []
    run_demo(tmp / "run", scene_path=robot, scenes=scenes, discriminate_scans=80, echo=printed.append)
    (tmp / "printed.txt").write_text("\n".join(printed), encoding="utf-8")      # what the demo said


@pytest.fixture(scope="session")
def report(run_dir):
    """The report the demo wrote (its last stage), with its PDF."""
    from feeler.reports.build import MANIFEST

    assert (run_dir / "report.pdf").is_file() and (run_dir / MANIFEST).is_file()
    return run_dir


@pytest.fixture(scope="session")
def acquired(tmp_path_factory) -> Path:
    """A real acquisition: the emulated stage on a pty and the virtual camera."""
    tmp = tmp_path_factory.mktemp("acquired")
    plan = tmp / "plan.toml"
    text = TINY_PLAN.read_text(encoding="utf-8").replace("scans_per_plate = 2", "scans_per_plate = 1")
    plan.write_text(text, encoding="utf-8")
    assert main(["acquire", "--emulate", "--plan", str(plan), "--out", str(tmp / "acq")]) == 0
    return tmp / "acq"


@pytest.fixture
def copy_run(run_dir, tmp_path) -> Path:
    """A fresh copy of the demo run (for tests that damage or remove files)."""
    return Path(shutil.copytree(run_dir, tmp_path / "run", ignore=shutil.ignore_patterns("report*", "logs")))


@pytest.fixture
def part_run(run_dir, tmp_path):
    """``make(*names)``: a fresh run holding only these top-level entries of the demo run."""
    def make(*names: str) -> Path:
        dst = tmp_path / "part"
        dst.mkdir()
        for name in names:
            src = run_dir / name
            (shutil.copytree if src.is_dir() else shutil.copyfile)(src, dst / name)
        return dst
    return make
