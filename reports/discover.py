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

__all__ = ["SectionSpec", "Missing", "Inventory", "discover", "FIT_FILES", "FIT_TITLES", "EXPECTED", "hint_paths",
           "new_output", "shown_path"]

FIT_TITLES = {"m1": "M1: sensor force→displacement matrix", "m2": "M2: neuron (a, τ, h) and decoder noise",
              "m4": "M4: human psychometric functions", "finger-route": "Finger route: τ and decision noise σ_d"}
_FIT_ORDER = ("m1", "m2", "m4", "finger-route", "")

#: (title, kinds of which any one fills it, what it would need). In what it needs,
#: ``{out:NAME}`` is where a new output goes (:func:`hint_paths`: inside a run directory of
#: several parts, beside one that is a single command's output), ``{m2}``, ``{scans}``,
#: ``{dataset}``, ``{trials}`` the run's own fit, scans, calibration data and trials when it
#: has them (else what the hint above writes, or a placeholder), ``{data}`` the shipped
#: scenes and ``{run}`` the run directory
EXPECTED: tuple[tuple[str, tuple[str, ...], str], ...] = (
    ("Robot scans over the plates (paper Figs 7–9)", ("robot", "acquisition"),
     "a directory with scans.csv and scene.toml: `feeler simulate {data}/four-plates.toml "
     "--out {out:four-plates}` or `feeler acquire ... --out {out:acquired}`"),
    (FIT_TITLES["m1"], ("fit:m1",), "{dataset_first}`feeler calibrate sensor {dataset} --out {out:m1}`"),
    (FIT_TITLES["m2"], ("fit:m2",), "`feeler calibrate neuron {scans} --out {out:m2}`"),
    ("Classification of held-out scans", ("classify",), "`feeler classify {m2} SCANS_DIR --out {out:classify}` "
     "(SCANS_DIR: scans the fit did not see, e.g. `feeler simulate {data}/four-plates.toml --seed 1 "
     "--out {out:held-out}`)"),
    ("The robot's difference threshold", ("discriminate",), "`feeler discriminate {m2} --out {out:discriminate}`"),
    ("Human 2AFC trials", ("psychophysics",), "trials.csv: `feeler simulate {data}/psychophysics-2afc.toml "
     "--out {out:psychophysics}` or a lab's 2AFC CSV"),
    (FIT_TITLES["m4"], ("thresholds",), "`feeler fit psychophysics {trials} --out {out:m4}`"),
    (FIT_TITLES["finger-route"], ("tau-report",), "`feeler fit finger-route {trials} --out {out:finger-route}`"),
    ("Finger strain histories (paper Figs 3–6)", ("finger", "skin-figures"),
     "`feeler simulate {data}/finger-steps.toml --out {out:finger}`"),
    ("Skin fidelity ladder", ("ladder",), "`feeler skin ladder --out {out:skin-ladder}` (or `feeler demo`)"),
    ("Speed/accuracy tables", ("benchmarks", "speed"), "`make bench` before `feeler demo`, or `feeler demo` "
     "(measures a small version)"),
    ("Live decoder: decision latency against accuracy", ("decoder",),
     "a decoder.csv trade table (columns option, latency_s, accuracy) beside `make bench`'s tables or the "
     "speed.json of `feeler demo` (both write one)"),
)

#: the shipped scenes the hints name
DATA = Path(__file__).resolve().parents[1] / "datasets-synthetic"


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
        missing_note (str): where the commands of ``missing`` write, when that is beside the
            run directory (a fit, a simulation, an acquisition holds that output only), and
            how to report them with it; "" when they write inside it.
        unread (tuple[tuple[str, str], ...]): (run-relative path, what it is) of files
            other commands wrote that the report does not read (named, not shown).
        cache (dict): what sections computed from the run's files, shared between them.
    """
    run_dir: Path
    parts: tuple[Part, ...]
    present: tuple[SectionSpec, ...]
    missing: tuple[Missing, ...]
    unread: tuple[tuple[str, str], ...] = ()
    missing_note: str = ""
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
    missing, note = _missing(run_dir, parts, kinds)
    return Inventory(run_dir=run_dir, parts=tuple(parts), present=tuple(_sections(run_dir, parts)),
                     missing=missing, unread=tuple(unread_files(run_dir)), missing_note=note)


def shown_path(path: Path) -> str:
    """``path`` for a command line: relative to the working directory when inside it, quoted."""
    import os

    try:
        rel = os.path.relpath(path)
    except ValueError:                      # another drive
        rel = str(path)
    return shlex.quote(rel if not rel.startswith("..") else str(path))


def hint_paths(run_dir: Path, parts: list[Part]) -> tuple[Path, bool]:
    """(directory where the hints put new outputs, whether that is beside ``run_dir``).

    A run directory whose own files are one command's output (a fit, a simulation, an
    acquisition: a part at its top) holds that output only: a fit's ``m2/m1``, a
    simulation's ``four-plates/m2`` would be written inside another run, and ``simulate
    --force`` over it would meet them. New outputs then go beside it, in its parent. A
    directory of parts in sub-directories (a demo, a mix) takes them inside."""
    if not any(p.rel == "" for p in parts):
        return run_dir, False
    parent = run_dir.parent if run_dir.name not in ("", ".", "..") else run_dir.resolve().parent
    return parent, True


def new_output(base: Path, name: str) -> Path:
    """A new output's directory for a hint: ``base/name``, or ``name-2``... when that exists
    (a command refuses an existing output directory without --force)."""
    k, candidate = 1, base / name
    while candidate.exists():
        k += 1
        candidate = base / f"{name}-{k}"
    return candidate


def _missing(run_dir: Path, parts: list[Part], kinds: set[str]) -> tuple[tuple[Missing, ...], str]:
    """The expected sections the run cannot fill, each with commands that run as printed:
    the run's own parts named where a command reads one, new outputs in directories that
    do not exist yet (:func:`hint_paths`)."""
    base, beside = hint_paths(run_dir, parts)

    def out(name: str) -> Path:
        return new_output(base, name)

    def own(kind: tuple[str, ...], prefer: str, model: str = "") -> Path | None:
        """The directory of the run's part of ``kind`` (in ``prefer`` if there is one)."""
        found = [p for p in parts if p.kind in kind and (not model or p.model == model)]
        part = next((p for p in found if p.rel.split("/")[-1] == prefer), found[0] if found else None)
        return None if part is None else run_dir / part.rel

    m2 = own(("fit",), "m2", "m2")
    scans = own(("robot", "acquisition"), "four-plates")
    dataset = own(("calibration-data",), "sensor-calibration")
    trials = own(("psychophysics",), "psychophysics")
    data = shown_path(DATA)
    values = {       # what the run has, else what the hint above writes (robot scans, trials, M2)
        "run": lambda: shown_path(run_dir), "data": lambda: data,
        "m2": lambda: shown_path(m2 or out("m2")),
        "scans": lambda: shown_path(scans or out("four-plates")),
        "dataset": lambda: shown_path(dataset or out("sensor-calibration")),
        "dataset_first": lambda: "" if dataset else (f"`feeler simulate {data}/sensor-calibration.toml --out "
                                                      f"{shown_path(out('sensor-calibration'))}`, then "),
        "trials": lambda: shown_path((trials or out("psychophysics")) / "trials.csv"),
    }

    def fill(needs: str) -> str:
        return re.sub(r"\{(out:)?([\w-]+)\}", lambda m: shown_path(out(m[2])) if m[1] else values[m[2]](), needs)

    missing = tuple(Missing(title, fill(needs)) for title, any_of, needs in EXPECTED if not kinds & set(any_of))
    note = ""
    if beside and any("--out" in m.needs for m in missing):
        note = (f"these commands write beside {shown_path(run_dir)} (it holds one command's output), in "
                f"{shown_path(base)}; `feeler report {shown_path(base)}` shows them with it")
    return missing, note
