"""What a directory of a run holds, told by its files (not by its name).

A run directory may be one command's output (a fit, a simulation, an acquisition), the
whole demo, or any mix of them under any names. :func:`find_parts` looks at the run
directory itself and its sub-directories (two levels down) and returns one :class:`Part`
per recognised kind of content:

=================  ==========================================  ============================
kind               files that identify it                      written by
=================  ==========================================  ============================
robot              scans.csv (+ scene.toml)                    feeler simulate (robot scene)
acquisition        scans.csv + journal.jsonl or summary.json   feeler acquire
calibration-data   calibration.csv                             feeler simulate (sensor-calibration)
psychophysics      trials.csv                                  feeler simulate (psychophysics) or a lab
fit                posterior.nc + summary.csv + verdict.json   calibrate sensor|neuron, fit ...
thresholds         thresholds.csv                              feeler fit psychophysics
tau-report         tau_report.json                             feeler fit finger-route
classify           classification.csv                          feeler classify
discriminate       discrimination.json                         feeler discriminate
finger             strain.csv                                  feeler simulate (finger-steps)
skin-figures       fig5_peaks.csv or fig6_accepted.csv         feeler skin figures
ladder             trade.csv                                   feeler skin ladder
benchmarks         ratios.csv or <module>.csv with "benchmark"  make bench
speed              speed.json                                  feeler demo (measured while it ran)
=================  ==========================================  ============================

Files that other commands write and the report does not read — ``decode``'s
decisions.csv, ``validate sbc``'s ranks.csv and sbc.csv, a posterior.nc without the
verdict.json of its fit — are listed by :func:`unread_files`, so that the report names
them instead of passing over them in silence.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

__all__ = ["Part", "find_parts", "walk", "SKIP_DIRS", "FIT_FILES", "fit_model", "unread_files", "UNREAD", "READS"]

FIT_FILES = ("posterior.nc", "summary.csv", "verdict.json")
SKIP_DIRS = {"logs", "video", "frames", "__pycache__"}
_SINGLE = (("calibration-data", "calibration.csv"), ("psychophysics", "trials.csv"),
           ("thresholds", "thresholds.csv"), ("tau-report", "tau_report.json"),
           ("classify", "classification.csv"), ("discriminate", "discrimination.json"),
           ("finger", "strain.csv"), ("ladder", "trade.csv"), ("speed", "speed.json"))
#: files of other commands' outputs that the report does not read -> what they are
UNREAD = {"decisions.csv": "decode output", "ranks.csv": "validate sbc output", "sbc.csv": "validate sbc output"}
#: what the report reads, in words (for the error on a directory holding none of it)
READS = ("scans.csv", "calibration.csv", "trials.csv", "posterior.nc with summary.csv and verdict.json",
         "thresholds.csv", "tau_report.json", "classification.csv", "discrimination.json", "strain.csv",
         "fig5_peaks.csv", "fig6_accepted.csv", "trade.csv", "speed.json", "benchmark tables")


@dataclass(frozen=True)
class Part:
    """One recognised kind of content in directory ``rel`` of the run ("" is the run
    directory itself); ``model`` names a fit's model ("m1", "m2", "m4", "finger-route"
    or "" when not recognised)."""
    kind: str
    rel: str
    files: tuple[str, ...]
    model: str = ""

    def path(self, name: str) -> str:
        """The run-relative path of ``name`` in this part's directory."""
        return f"{self.rel}/{name}" if self.rel else name

    @property
    def label(self) -> str:
        """How the report names the directory: ``m1/`` (or ``./`` for the run itself)."""
        return f"{self.rel}/" if self.rel else "./"


def fit_model(summary_csv: Path) -> str:
    """The model of a fit from the parameter names of its summary.csv ("" if unknown or
    unreadable: the fit section then names the faulty file)."""
    try:
        with open(summary_csv, newline="", encoding="utf-8") as fh:
            names = {row.get("name", "") for row in csv.DictReader(fh)}
    except (OSError, UnicodeDecodeError, csv.Error):
        return ""
    if "C[0,0]" in names:
        return "m1"
    if {"a", "tau_s", "h"} <= names:
        return "m2"
    if "sigma_d_um" in names:
        return "finger-route"
    if any(n.startswith(("pse_all", "pse[")) for n in names):
        return "m4"
    return ""


def _is_bench_table(path: Path) -> bool:
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            return fh.readline().startswith("benchmark,")
    except OSError:
        return False


def _parts_of(directory: Path, rel: str) -> list[Part]:
    names = {p.name for p in directory.iterdir() if p.is_file()}
    found = []
    if "scans.csv" in names:
        acquired = bool({"journal.jsonl", "summary.json"} & names)
        files = tuple(f for f in ("scans.csv", "scene.toml") if f in names)
        found.append(Part("acquisition" if acquired else "robot", rel, files))
    if set(FIT_FILES) & names and "verdict.json" in names:
        found.append(Part("fit", rel, FIT_FILES, fit_model(directory / "summary.csv")))
    for kind, name in _SINGLE:
        if name in names:
            found.append(Part(kind, rel, (name,)))
    figs = tuple(sorted(n for n in ("fig5_peaks.csv", "fig6_accepted.csv") if n in names))
    if figs:
        found.append(Part("skin-figures", rel, figs))
    bench = tuple(sorted(n for n in names if n.endswith(".csv") and _is_bench_table(directory / n)))
    if "ratios.csv" in names or bench:
        found.append(Part("benchmarks", rel, tuple(sorted(set(bench) | ({"ratios.csv"} & names)))))
    return found


def walk(run_dir: Path, depth: int = 2):
    """(directory, run-relative name) of ``run_dir`` and its sub-directories up to
    ``depth`` levels, the run directory first, then sorted names (hidden, ``_`` and
    :data:`SKIP_DIRS` directories left out)."""
    todo = [(run_dir, "", 0)]
    while todo:
        directory, rel, level = todo.pop(0)
        yield directory, rel
        if level < depth:
            subs = sorted(p for p in directory.iterdir() if p.is_dir() and not p.name.startswith((".", "_"))
                          and p.name not in SKIP_DIRS)
            todo += [(p, f"{rel}/{p.name}" if rel else p.name, level + 1) for p in subs]


def find_parts(run_dir: Path, depth: int = 2) -> list[Part]:
    """Every part of ``run_dir`` and its sub-directories up to ``depth`` levels, in
    directory order (the run directory first, then sorted names)."""
    return [part for directory, rel in walk(run_dir, depth) for part in _parts_of(directory, rel)]


def unread_files(run_dir: Path, depth: int = 2) -> list[tuple[str, str]]:
    """(run-relative path, what it is) of every file the report does not read that a
    command wrote (:data:`UNREAD`), and of fit files without their verdict.json."""
    out = []
    for directory, rel in walk(run_dir, depth):
        names = {p.name for p in directory.iterdir() if p.is_file()}
        where = (lambda name: f"{rel}/{name}" if rel else name)
        out += [(where(n), UNREAD[n]) for n in sorted(names & set(UNREAD))]
        if "verdict.json" not in names:
            out += [(where(n), "a fit's file without its verdict.json") for n in FIT_FILES if n in names]
    return out
