"""Which sections a run directory can fill, and what each missing one would need.

The parts of the run (:mod:`feeler.reports.parts`, recognised by their files, under any
directory names) become sections in report order: robot scans (simulated or acquired),
the sensor calibration data, every fit (M1, M2, M4, finger route, others), the
classification, robot against human on one axis, the finger skin (Figs 3–6 and the
fidelity ladder), and the speed/accuracy trade. Each expected section that the run
cannot fill is listed with the command that would produce it.
"""
from __future__ import annotations

import re
import shlex
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from feeler.reports.parts import FIT_FILES, Part, find_parts, unread_files

__all__ = ["SectionSpec", "Missing", "Inventory", "discover", "FIT_FILES", "FIT_TITLES", "EXPECTED"]

FIT_TITLES = {"m1": "M1: sensor force→displacement matrix", "m2": "M2: neuron (a, τ, h) and decoder noise",
              "m4": "M4: human psychometric functions", "finger-route": "Finger route: τ and decision noise σ_d"}
_FIT_ORDER = ("m1", "m2", "m4", "finger-route", "")

#: (title, kinds of which any one fills it, what it would need); {run} is the run directory
EXPECTED: tuple[tuple[str, tuple[str, ...], str], ...] = (
    ("Robot scans over the plates (paper Figs 7–9)", ("robot", "acquisition"),
     "a directory with scans.csv and scene.toml: `feeler simulate datasets-synthetic/four-plates.toml "
     "--out {run}/four-plates` or `feeler acquire ... --out {run}/acquired`"),
    (FIT_TITLES["m1"], ("fit:m1",), "`feeler calibrate sensor DATASET --out {run}/m1` "
     "(DATASET from `feeler simulate datasets-synthetic/sensor-calibration.toml`)"),
    (FIT_TITLES["m2"], ("fit:m2",), "`feeler calibrate neuron SCANS_DIR --out {run}/m2`"),
    ("Classification of held-out scans", ("classify",), "`feeler classify {run}/m2 SCANS_DIR --out {run}/classify`"),
    ("The robot's difference threshold", ("discriminate",), "`feeler discriminate {run}/m2 --out {run}/discriminate`"),
    ("Human 2AFC trials", ("psychophysics",), "trials.csv: `feeler simulate datasets-synthetic/"
     "psychophysics-2afc.toml --out {run}/psychophysics` or a lab's 2AFC CSV"),
    (FIT_TITLES["m4"], ("thresholds",), "`feeler fit psychophysics TRIALS.csv --out {run}/m4`"),
    (FIT_TITLES["finger-route"], ("tau-report",), "`feeler fit finger-route TRIALS.csv --out {run}/finger-route`"),
    ("Finger strain histories (paper Figs 3–6)", ("finger", "skin-figures"),
     "`feeler simulate datasets-synthetic/finger-steps.toml --out {run}/finger`"),
    ("Skin fidelity ladder", ("ladder",), "`feeler skin ladder --out {run}/skin-ladder` (or `feeler demo`)"),
    ("Speed/accuracy tables", ("benchmarks", "speed"), "`make bench` before `feeler demo`, or `feeler demo` "
     "(measures a small version)"),
    ("Live decoder: decision latency against accuracy", ("decoder",),
     "a decoder.csv trade table (columns option, latency_s, accuracy) in {run}/benchmarks or {run}/speed"),
)


@dataclass(frozen=True)
class SectionSpec:
    """A report section: ``builder`` names the function that draws it from ``parts``."""
    key: str
    title: str
    builder: str
    parts: tuple[Part, ...]


@dataclass(frozen=True)
class Missing:
    """An expected section the run cannot fill, and what would produce it."""
    title: str
    needs: str


@dataclass(frozen=True)
class Inventory:
    """What a run directory holds.

    Attributes:
        run_dir (Path): the run directory.
        parts (tuple[Part, ...]): every recognised part, in directory order.
        present (tuple[SectionSpec, ...]): the sections to draw, in report order.
        missing (tuple[Missing, ...]): expected sections the run cannot fill.
        unread (tuple[tuple[str, str], ...]): (run-relative path, what it is) of files
            other commands wrote that the report does not read (named, not shown).
        cache (dict): what sections computed from the run's files, shared between them.
    """
    run_dir: Path
    parts: tuple[Part, ...]
    present: tuple[SectionSpec, ...]
    missing: tuple[Missing, ...]
    unread: tuple[tuple[str, str], ...] = ()
    cache: dict = field(default_factory=dict, compare=False, repr=False)

    def cached(self, key, compute: Callable):
        """``compute()`` once per inventory for ``key`` (several sections use the same numbers)."""
        if key not in self.cache:
            self.cache[key] = compute()
        return self.cache[key]

    def has(self, rel: str) -> bool:
        return (self.run_dir / rel).exists()

    def of(self, kind: str, model: str | None = None) -> list[Part]:
        """The parts of ``kind`` (fits: of ``model`` when given), in directory order."""
        return [p for p in self.parts if p.kind == kind and (model is None or p.model == model)]

    def first(self, kind: str, model: str | None = None, *, prefer: str = "") -> Part | None:
        """The part of ``kind`` in directory ``prefer`` if there is one, else the first."""
        found = self.of(kind, model)
        return next((p for p in found if p.rel.split("/")[-1] == prefer), found[0] if found else None)


def _kinds(parts: list[Part]) -> set[str]:
    kinds = {p.kind for p in parts} | {f"fit:{p.model}" for p in parts if p.kind == "fit"}
    if any(p.kind == "thresholds" or (p.kind == "fit" and p.model == "m4") for p in parts):
        kinds.add("thresholds")
    if any(p.kind == "fit" and p.model == "finger-route" for p in parts):
        kinds.add("tau-report")
    return kinds


def design(run_dir: Path, part: Part) -> str | None:
    """A scan part's scene text without its seed, name and description (None without a scene):
    two parts with the same design differ only in their random touches."""
    path = run_dir / part.path("scene.toml")
    if not path.is_file():
        return None
    text = path.read_text(encoding="utf-8", errors="replace")
    return re.sub(r"(?m)^\s*(seed|name|description)\s*=.*$", "", text)


def _robot_groups(run_dir: Path, parts: list[Part]) -> list[list[Part]]:
    """Scan parts grouped by design (kind and scene up to the seed), first seen first."""
    groups: list[list[Part]] = []
    for p in (p for p in parts if p.kind in ("robot", "acquisition")):
        d = design(run_dir, p)
        same = next((g for g in groups if d is not None and g[0].kind == p.kind and design(run_dir, g[0]) == d), None)
        if same is not None:
            same.append(p)
        else:
            groups.append([p])
    return groups


def _sections(run_dir: Path, parts: list[Part]) -> list[SectionSpec]:
    out = []
    for group in _robot_groups(run_dir, parts):
        p = group[0]
        what = "acquired" if p.kind == "acquisition" else "simulated"
        others = "".join(f", {q.label}" for q in group[1:])
        out.append(SectionSpec(f"robot:{p.rel}", f"Robot scans ({what}, {p.label}{others})", "robot", tuple(group)))
    fits = sorted((p for p in parts if p.kind == "fit"), key=lambda p: _FIT_ORDER.index(p.model))
    for p in [p for p in parts if p.kind == "calibration-data"]:
        if not any(f.model == "m1" for f in fits):
            out.append(SectionSpec(f"calibration-data:{p.rel}", f"Sensor calibration campaign ({p.label})",
                                   "calibration-data", (p,)))
    for p in fits:
        title = FIT_TITLES.get(p.model, f"Fit: {p.rel or run_dir.name}")
        out.append(SectionSpec(f"fit:{p.rel}", f"{title} ({p.label})", "fit", (p,)))
    for p in [p for p in parts if p.kind == "classify"]:
        out.append(SectionSpec(f"classify:{p.rel}", f"Classification of held-out scans ({p.label})", "classify", (p,)))
    human = [p for p in parts if p.kind in ("discriminate", "thresholds", "psychophysics")]
    if human:
        out.append(SectionSpec("compare", "Robot and human discrimination on one axis", "compare", tuple(human)))
    finger = [p for p in parts if p.kind in ("finger", "skin-figures", "ladder")]
    if finger:
        out.append(SectionSpec("finger", "Finger skin: the paper's Figs 3–6 and the fidelity ladder", "finger",
                               tuple(finger)))
    speed = [p for p in parts if p.kind in ("benchmarks", "speed", "ladder")]
    if speed:
        out.append(SectionSpec("speed", "Speed and accuracy", "speed", tuple(speed)))
    return out


def discover(run_dir: str | Path) -> Inventory:
    """The parts of ``run_dir``, the sections they fill and the expected ones missing.

    Raises:
        DataFileError: ``run_dir`` is not a directory.
    """
    from feeler.errors import DataFileError

    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise DataFileError(run_dir, "not a directory; expected a run directory")
    parts = find_parts(run_dir)
    kinds = _kinds(parts)
    if any((run_dir / p.path("decoder.csv")).is_file() for p in parts if p.kind in ("benchmarks", "speed")):
        kinds.add("decoder")
    missing = tuple(Missing(title, needs.replace("{run}", shlex.quote(str(run_dir)))) for title, any_of, needs in EXPECTED
                    if not kinds & set(any_of))
    return Inventory(run_dir=run_dir, parts=tuple(parts), present=tuple(_sections(run_dir, parts)),
                     missing=missing, unread=tuple(unread_files(run_dir)))
