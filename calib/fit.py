"""The trust layer every model returns: posterior + summary + verdict, saved and loaded.

A :class:`FitResult` holds the ArviZ ``DataTree`` posterior, the tidy summary (one row
per parameter entry, see :data:`feeler.calib.diagnostics.SUMMARY_COLUMNS`), the
:class:`Verdict`, the priors as stated to the user, the backend name and the wall time.
``save(out_dir)`` writes ``posterior.nc`` (priors, backend and seconds go in its
attributes), ``summary.csv`` and ``verdict.json``; :func:`load` reads them back and turns
any unreadable file into a one-line :class:`DataFileError` naming it. Downstream code
calls :func:`require_ok` before using a posterior.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import pandas as pd

from feeler.calib.diagnostics import (SUMMARY_COLUMNS, DiagnosticWarning, Thresholds, Verdict,
                                      diagnose, summarize)
from feeler.calib.posterior import entry_names, flat_draws, posterior_from_draws
from feeler.errors import CalibrationFailed, DataFileError
from feeler.rundir import prepare_out_dir, write_json

__all__ = ["FitResult", "Verdict", "DiagnosticWarning", "Thresholds", "make_result", "load",
           "require_ok", "diagnose", "summarize", "posterior_from_draws", "flat_draws",
           "FIT_FILES", "read_csv_columns"]

FIT_FILES = ("posterior.nc", "summary.csv", "verdict.json")


@dataclass(frozen=True)
class FitResult:
    """One fitted model.

    Attributes:
        posterior (xarray.DataTree): ArviZ 1.x layout (posterior, sample_stats,
            observed_data, posterior_predictive, ...).
        summary (pandas.DataFrame): a row per parameter entry (``C[0,1]``, ``a``, ...).
        verdict (Verdict): diagnostics outcome.
        priors (dict[str, str]): each parameter's prior, in words with units.
        backend (str): "exact", "nuts", "emcee", ...
        seconds (float): wall time of the fit, s.
    """
    posterior: object
    summary: pd.DataFrame
    verdict: Verdict
    priors: dict = field(default_factory=dict)
    backend: str = ""
    seconds: float = 0.0

    def save(self, out_dir: str | Path, *, force: bool = False) -> Path:
        """Write ``posterior.nc``, ``summary.csv``, ``verdict.json`` into ``out_dir``,
        ``verdict.json`` last: a directory without it holds a save that was interrupted
        (Ctrl-C between the files), which is overwritten without ``force``."""
        interrupted = not (Path(out_dir) / FIT_FILES[-1]).exists()
        out = prepare_out_dir(out_dir, FIT_FILES, force=force or interrupted)
        tree = self.posterior.copy()
        tree["posterior"].attrs.update({"priors": json.dumps(self.priors),
                                        "backend": self.backend, "seconds": float(self.seconds)})
        from feeler.calib.lazy_dask import writing_without_dask
        with writing_without_dask():
            tree.to_netcdf(out / "posterior.nc", engine="h5netcdf")
        self.summary.to_csv(out / "summary.csv", index=False)
        write_json(out / "verdict.json", self.verdict.as_dict())
        return out

    def draws(self) -> dict:
        """``dict[name] -> ndarray (chain, draw)`` per parameter entry."""
        return flat_draws(self.posterior)


def make_result(posterior, *, backend: str, priors: Mapping[str, str], seconds: float,
                bounds: Mapping[str, tuple[float, float]] | None = None,
                thresholds: Thresholds = Thresholds(), checks: Sequence[str] = ()) -> FitResult:
    """Summarise and diagnose ``posterior`` and wrap everything in a :class:`FitResult`.

    ``checks``: the model's own problems (identifiability, units, posterior predictive
    and prior–data conflict checks), one line each; any of them fails the verdict."""
    summary = summarize(posterior)
    verdict = diagnose(posterior, summary, backend=backend, bounds=bounds, thresholds=thresholds,
                       checks=checks)
    return FitResult(posterior=posterior, summary=summary, verdict=verdict,
                     priors=dict(priors), backend=backend, seconds=float(seconds))


def load(directory: str | Path) -> FitResult:
    """Read a :class:`FitResult` written by :meth:`FitResult.save`.

    Raises:
        DataFileError: a missing or corrupt ``posterior.nc``, ``summary.csv`` or
            ``verdict.json`` (the message names the file).
    """
    import xarray as xr

    from feeler.calib.lazy_dask import install
    install()
    d = Path(directory)
    if d.name in FIT_FILES and d.is_file():      # the fit's own posterior.nc (or summary.csv) given: its directory
        d = d.parent
    for name in FIT_FILES:
        if not (d / name).is_file():
            from feeler.rundir import what_it_is
            hint = what_it_is(d, expected="posterior.nc") if name == FIT_FILES[0] else ""
            raise DataFileError(d / name, "missing; expected a fit directory written by --out"
                                + (f"; {hint}" if hint else ""))
    try:
        with xr.open_datatree(d / "posterior.nc", engine="h5netcdf") as src:
            tree = src.load()
        tree["posterior"]
    except Exception as exc:  # h5py/xarray raise many types for a corrupt file
        raise DataFileError(d / "posterior.nc", f"not a readable NetCDF posterior ({type(exc).__name__})") from None
    attrs = tree["posterior"].attrs
    try:
        priors = json.loads(attrs.get("priors", "{}"))
    except json.JSONDecodeError:
        raise DataFileError(d / "posterior.nc", "attribute 'priors' is not valid JSON") from None
    summary = _read_summary(d / "summary.csv", entry_names(tree))
    verdict = _read_verdict(d / "verdict.json")
    return FitResult(posterior=tree, summary=summary, verdict=verdict, priors=priors,
                     backend=str(attrs.get("backend", "")), seconds=float(attrs.get("seconds", 0.0)))


def require_ok(result: FitResult, *, accept_failed: bool = False, what: str = "calibration") -> FitResult:
    """Return ``result`` if its verdict is ok or ``accept_failed``; else raise. A failed fit
    accepted is used, but never silently: a :class:`DiagnosticWarning` names its first problem
    (a fit in the wrong units gave P(correct) 0.5000 [0.5000, 0.5000] with exit 0 and nothing
    said it had failed; an outside audit).

    Raises:
        CalibrationFailed: carrying the verdict.
    """
    if not result.verdict.ok:
        if not accept_failed:
            raise CalibrationFailed(result.verdict, what)
        import warnings

        problems = result.verdict.problems
        warnings.warn(f"{what} failed its diagnostics ({len(problems)} problem{'s' if len(problems) != 1 else ''}; "
                      f"the first: {problems[0] if problems else 'none recorded'}); --accept-failed uses it anyway, "
                      f"so what follows comes from a fit its verdict refused", DiagnosticWarning, stacklevel=2)
    return result


def read_csv_columns(path: str | Path, columns, *, text: str | None = None) -> pd.DataFrame:
    """A CSV that must have ``columns``; unreadable or incomplete → one-line DataFileError.
    ``text``: the file's text, when the caller has read it already."""
    from feeler.datasets import missing_columns_problem, read_csv_file

    table = read_csv_file(path, text=text)
    problem = missing_columns_problem(table, columns)
    if problem:
        raise DataFileError(path, problem)
    return table


_LISTED = 4                                   # entries named in the error, at most


def _read_summary(path: Path, entries: list[str]) -> pd.DataFrame:
    """summary.csv with a row for each of the posterior's ``entries``, every row complete.

    A file cut short (an interrupted copy, a full disk) kept its header and read as a
    table of one or two parameters: the report then failed on a KeyError traceback (M1)
    or showed a table of two rows as the fit's (M2).

    Raises:
        DataFileError: a column or an entry's row is missing, or a row has fewer fields
            than the header.
    """
    import csv

    from feeler.datasets import csv_dialect, csv_text, header_line

    text = csv_text(path)                    # read once: the table, and its rows' widths
    table = read_csv_columns(path, SUMMARY_COLUMNS, text=text)
    sep, _ = csv_dialect(header_line(text))
    rows = [r for r in csv.reader(text.splitlines(), delimiter=sep) if r and not r[0].lstrip().startswith("#")]
    width = len(rows[0])
    short = next((i for i, r in enumerate(rows[1:], 1) if len(r) < width), None)
    if short is not None:
        raise DataFileError(path, f"data row {short} has {len(rows[short])} of the header's {width} fields; "
                                  "expected complete rows, as the fit writes them (a file cut short?)")
    have = set(table["name"].astype(str))
    missing = [e for e in entries if e not in have]
    if missing:
        named = ", ".join(missing[:_LISTED]) + (f" and {len(missing) - _LISTED} more" if len(missing) > _LISTED else "")
        raise DataFileError(path, f"no row for {named} ({len(missing)} of the posterior's {len(entries)} entries); "
                                  "expected one row per posterior entry, as the fit writes it (a file cut short?)")
    return table


def _read_verdict(path: Path) -> Verdict:
    try:
        raw = json.loads(path.read_text(encoding="utf-8"))
        return Verdict.from_dict(raw)
    except (json.JSONDecodeError, UnicodeDecodeError, KeyError, TypeError) as exc:
        raise DataFileError(path, f'not a verdict {{"ok": bool, "problems": [...]}} '
                                  f"({type(exc).__name__})") from None
