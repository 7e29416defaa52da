"""Which sections a run directory can fill, and which expected files are missing.

The run layout (``feeler demo`` writes all of it; any part may be absent)::

    four-plates/          scene.toml scans.csv [truth.json]        feeler simulate
    robot_table.json                                                feeler demo
    sensor-calibration/   scene.toml calibration.csv [truth.json]  feeler simulate
    m1/ m2/ m4/           posterior.nc summary.csv verdict.json     calibrate / fit
    classify/             classification.csv                        feeler classify
    discriminate/         discrimination.json                       feeler discriminate
    psychophysics/        trials.csv [scene.toml truth.json]       feeler simulate
    m4/                   thresholds.csv                            feeler fit psychophysics
    finger-route/         tau_report.json + fit files               feeler fit finger-route
    finger/ benchmarks/   *.csv                                     skin ladder, benchmarks

Any other sub-directory holding ``verdict.json`` is reported as a fit too.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

__all__ = ["SectionSpec", "SPECS", "Inventory", "discover", "FIT_FILES"]

FIT_FILES = ("posterior.nc", "summary.csv", "verdict.json")


@dataclass(frozen=True)
class SectionSpec:
    """A report section and the run-relative files it needs (all) and may use."""
    key: str
    title: str
    required: tuple[str, ...]
    optional: tuple[str, ...] = ()


def _fit(name: str, title: str, optional: tuple[str, ...] = ()) -> SectionSpec:
    return SectionSpec(f"fit:{name}", title, tuple(f"{name}/{f}" for f in FIT_FILES), optional)


#: the expected sections, in report order (failed fits are moved to the top)
SPECS: tuple[SectionSpec, ...] = (
    SectionSpec("robot", "Robot scans over the four plates (paper Figs 7–9)",
                ("four-plates/scene.toml", "four-plates/scans.csv"),
                ("robot_table.json", "four-plates/truth.json")),
    _fit("m1", "M1: sensor force→displacement matrix", ("sensor-calibration/calibration.csv",)),
    _fit("m2", "M2: neuron (a, τ, h) and decoder noise", ("m2/ppc.json",)),
    SectionSpec("classify", "Classification of held-out scans", ("classify/classification.csv",)),
    SectionSpec("psychometric", "Robot and human discrimination side by side",
                ("discriminate/discrimination.json", "psychophysics/trials.csv", "m4/thresholds.csv")),
    _fit("m4", "M4: human psychometric functions", ("m4/thresholds.csv",)),
    SectionSpec("fig6", "Accepted against presented step height (paper Fig. 6)",
                ("finger-route/tau_report.json", "m4/thresholds.csv", "psychophysics/trials.csv")),
    _fit("finger-route", "Finger route: τ and decision noise σ_d", ("finger-route/tau_report.json",)),
    SectionSpec("finger", "Skin: strain histories and the fidelity ladder", ("finger",)),
    SectionSpec("benchmarks", "Speed and accuracy tables", ("benchmarks",)),
)

_ANY_OF = {"psychometric"}   # sections shown when any one of their files exists


@dataclass(frozen=True)
class Inventory:
    """What a run directory holds.

    Attributes:
        run_dir (Path): the run directory.
        present (tuple[SectionSpec, ...]): sections that can be shown, in report order.
        missing (tuple[tuple[str, tuple[str, ...]], ...]): (section title, missing files)
            for every section whose required files are not all there.
    """
    run_dir: Path
    present: tuple[SectionSpec, ...]
    missing: tuple[tuple[str, tuple[str, ...]], ...]

    def has(self, rel: str) -> bool:
        return (self.run_dir / rel).exists()


def _extra_fits(run_dir: Path, known: set[str]) -> list[SectionSpec]:
    found = sorted(p.parent.name for p in run_dir.glob("*/verdict.json"))
    return [_fit(name, f"Fit: {name}") for name in found if f"fit:{name}" not in known]


def discover(run_dir: str | Path) -> Inventory:
    """Sort the expected sections of ``run_dir`` into present and missing.

    Raises:
        DataFileError: ``run_dir`` is not a directory.
    """
    from feeler.errors import DataFileError

    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise DataFileError(run_dir, "not a directory; expected a run directory")
    specs = list(SPECS) + _extra_fits(run_dir, {s.key for s in SPECS})
    present, missing = [], []
    for spec in specs:
        lacking = tuple(f for f in spec.required if not _usable(run_dir / f))
        shown = len(lacking) < len(spec.required) if spec.key in _ANY_OF else not lacking
        if shown:
            present.append(spec)
        if lacking:
            missing.append((spec.title, lacking))
    return Inventory(run_dir=run_dir, present=tuple(present), missing=tuple(missing))


def _usable(path: Path) -> bool:
    """A file, or a directory holding at least one CSV."""
    return path.is_file() or (path.is_dir() and any(path.glob("*.csv")))
