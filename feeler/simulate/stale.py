"""``simulate --force`` into a directory holding another run: what the new run leaves behind.

``--force`` overwrites the files the new simulation writes. Before this check, the files
of the earlier run that the new one does not write stayed: a robot-scan simulation
forced over a sensor-calibration one kept its ``calibration.csv``, and ``feeler report``
then showed both runs as one. Now, with ``--force`` and before any work:

- files of an earlier feeler simulation (its ``truth.json`` is there, and its
  ``scene.toml`` is of a kind whose simulation writes them) are removed after the new
  run is written, and so is an earlier report of the directory (``report.html``,
  ``report.pdf`` beside its ``report-manifest.json``): it described the old data;
- so are the per-scan results other commands write beside an earlier robot-scan
  simulation's scans (:data:`DERIVED`: ``decode``'s decisions.csv, its default output,
  and ``classify --out``'s classification.csv): they are of the old scans;
- any other file of a name feeler reads or writes as a run's data or results (a fit, an
  acquisition's files, a ``calibration.csv`` no simulation accounts for, another
  command's results) is refused with one line naming it: feeler never deletes files it
  cannot tell come from the old data (move them away, or choose another ``--out``).

Files of other names are not touched; the command names them as not this run's
(:func:`not_this_run`) and its "wrote" line lists only what it wrote.
"""
from __future__ import annotations

from pathlib import Path

from feeler.errors import OverwriteError

__all__ = ["SIMULATION_FILES", "DERIVED", "outputs_of", "stale_outputs", "remove", "removed_line", "not_this_run"]

#: every file a simulation of some kind writes
SIMULATION_FILES = ("scene.toml", "truth.json", "scans.csv", "features.csv", "sensor.avi", "calibration.csv",
                    "trials.csv", "strain.csv")
_REPORT = ("report.html", "report.pdf", "report-manifest.json")
#: per-scan results other commands write beside a run's scans -> whose (removed with an earlier
#: robot-scan simulation's scans, which they are of; refused otherwise)
DERIVED = {"decisions.csv": "decode's decisions", "classification.csv": "classify's classification"}
#: data and results of other commands, which a report would show as this run's (never removed here)
_OTHERS = ("posterior.nc", "summary.csv", "verdict.json", "samples.csv", "journal.jsonl", "summary.json",
           "layout.toml", "thresholds.csv", "tau_report.json", "discrimination.json", "threshold_curve.csv",
           "fig5_peaks.csv", "fig6_accepted.csv", "trade.csv", "speed.json", "ranks.csv", "sbc.csv")


def outputs_of(scene) -> tuple[str, ...]:
    """The files a simulation of ``scene`` writes (as its kind's simulator does)."""
    kind = scene.scene.kind
    optics = getattr(scene, "optics", None)
    video = ("sensor.avi",) if optics is not None and optics.video and scene.sensor.fidelity == "images" else ()
    if kind == "robot-scan":
        features = ("features.csv",) if "features" in set(scene.scene.outputs) else ()
        return ("scene.toml", "truth.json", "scans.csv") + features + video
    data = {"sensor-calibration": "calibration.csv", "psychophysics-2afc": "trials.csv",
            "finger-steps": "strain.csv"}[kind]
    return (data, "truth.json", "scene.toml") + (video if kind == "sensor-calibration" else ())


def _earlier_simulation(out: Path) -> tuple[str, tuple[str, ...]]:
    """(kind, files) of the feeler simulation that wrote ``out``, or ("", ()) if none did."""
    from feeler.scene import load_scene
    from feeler.simulate import SIMULATORS

    if not (out / "truth.json").is_file() or not (out / "scene.toml").is_file():
        return "", ()
    try:
        scene = load_scene(out / "scene.toml")
    except Exception:                     # not a scene this feeler reads: nothing is accounted for
        return "", ()
    kind = scene.scene.kind
    return (kind, outputs_of(scene)) if kind in SIMULATORS else ("", ())


def stale_outputs(out: str | Path, scene) -> list[Path]:
    """The files in ``out`` an earlier run left that a simulation of ``scene`` does not
    write and that are safe to remove once it has run (see the module doc).

    Raises:
        OverwriteError: ``out`` holds such files that feeler cannot tell it wrote.
    """
    out = Path(out)
    if not out.is_dir():
        return []
    new = set(outputs_of(scene))
    present = [n for n in SIMULATION_FILES + _REPORT + tuple(DERIVED) + _OTHERS if n not in new and (out / n).is_file()]
    kind, earlier = _earlier_simulation(out)
    report = set(_REPORT) if (out / "report-manifest.json").is_file() else set()
    derived = set(DERIVED) if kind == "robot-scan" else set()      # of its scans.csv, which goes
    kept = [n for n in present if n not in set(earlier) | report | derived]
    if kept:
        also = f" (and {', '.join(kept[1:])})" if len(kept) > 1 else ""
        why = f"the earlier {kind} simulation there did not" if kind else "no earlier simulation there did"
        raise OverwriteError(out / kept[0], f"this {scene.scene.kind} simulation does not write it{also}, and feeler "
                                            f"cannot tell it wrote it ({why}), so --force "
                                            "would leave it beside the new run: move it away or choose another --out")
    return [out / n for n in present]


def remove(paths: list[Path]) -> None:
    for path in paths:
        path.unlink(missing_ok=True)


def removed_line(paths: list[Path], out: Path) -> str:
    """The line saying what --force removed: the earlier run's files, then the other
    commands' results on its scans, by whose they are."""
    plain = [p.name for p in paths if p.name not in DERIVED]
    derived = [p.name for p in paths if p.name in DERIVED]
    said = [f"the earlier run's {', '.join(plain)}"] if plain else []
    if derived:
        said.append(" and ".join(f"{DERIVED[n]} ({n})" for n in derived) + " on the earlier run's scans")
    return f"--force: removed {'; '.join(said)} from {out}"


def not_this_run(out: Path, written) -> list[str]:
    """The entries of ``out`` this run did not write (a user's notes, another run's
    directory), sorted; directories end in ``/``."""
    mine = set(written)
    return sorted(p.name + ("/" if p.is_dir() else "") for p in Path(out).iterdir() if p.name not in mine)
