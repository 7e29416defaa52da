"""Forced-choice trial tables: the CSV schemas for human (or synthetic) psychophysics data.

Four layouts, told apart by their columns (order free, extra columns ignored, ``#``
lines are comments: the synthetic datasets say so there). Every layout has

    subject, standard_um, standard_speed_mm_s, comparison_um, comparison_speed_mm_s

and then either counts, one row per (subject, standard, comparison) cell::

    n_trials, n_comparison_higher     comparison design ("which step is higher")
    n_trials, n_correct               nAFC proportion correct (fit with --nafc N)

or one row per trial, as experiment software writes it (aggregated on reading)::

    comparison_higher                 1/0 (also true/false, yes/no)
    correct                           1/0: nAFC

In nAFC the standard is the height the odd stimulus is told apart from (0 = a flat
plate: detection). Rows with ``n_trials = 0`` are allowed (they contribute nothing), as
are cells where every answer was right or every answer wrong; a table without a single
trial is refused.

A fifth layout is psignifit's data matrix, as a lab that used psignifit has its data: three
columns per row, the comparison's height (µm), the number of "correct" (nAFC) or "higher"
answers and the number of trials, with or without a header line, separated by commas,
semicolons, tabs or spaces (``numpy.savetxt``, MATLAB ``save -ascii``). It holds no design,
so the subject, standard and speeds come from a :class:`MatrixDesign` (the command line's
``--subject``, ``--standard-um``, ``--speed-mm-s``); a matrix read without one is refused
with a line saying what to give. psignifit's "equal asymptote" experiments are feeler's
comparison design, its "2AFC" (nAFC) experiments ``--nafc 2`` (N).
"""
from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from feeler.datasets import (MAX_MAGNITUDE, SEPARATORS, comment_lines, csv_dialect, natural_key, read_text,
                             renamed_hint, repeated_header_problem)
from feeler.errors import DataFileError, InputError

__all__ = ["TRIAL_COLUMNS", "NAFC_COLUMNS", "KEY_COLUMNS", "RESPONSES", "read_trials", "write_trials",
           "synthetic_note", "count_column", "MatrixDesign"]

KEY_COLUMNS = ("subject", "standard_um", "standard_speed_mm_s", "comparison_um", "comparison_speed_mm_s")
TRIAL_COLUMNS = KEY_COLUMNS + ("n_trials", "n_comparison_higher")
NAFC_COLUMNS = KEY_COLUMNS + ("n_trials", "n_correct")
#: response column of a trial-by-trial file → count column of the aggregated table
RESPONSES = {"comparison_higher": "n_comparison_higher", "correct": "n_correct"}
_TRUE, _FALSE = {"1", "true", "yes", "y", "1.0"}, {"0", "false", "no", "n", "0.0"}


@dataclass(frozen=True)
class MatrixDesign:
    """The design that a psignifit data matrix leaves out, for every row of it.

    Attributes:
        subject (str | None): the subject's name (None: the file name's stem).
        standard_um (float | None): the standard's height, µm (0 allowed in nAFC: detection).
        speed_mm_s (float | None): the scan speed of the standard, mm/s.
        comparison_speed_mm_s (float | None): the comparison's (None: ``speed_mm_s``).
        nafc (bool): column 2 counts correct answers (nAFC), not "comparison higher".
    """
    subject: str | None = None
    standard_um: float | None = None
    speed_mm_s: float | None = None
    comparison_speed_mm_s: float | None = None
    nafc: bool = False

    #: the command-line option of each field, for messages
    OPTIONS = {"standard_um": "--standard-um", "speed_mm_s": "--speed-mm-s"}

    def missing(self) -> list[str]:
        """The options a matrix still needs."""
        return [opt for name, opt in self.OPTIONS.items() if getattr(self, name) is None]

    def check(self) -> "MatrixDesign":
        """Itself, or ArgumentError naming the option whose value is not allowed: heights
        finite and ≥ 0 (> 0 for a comparison design's standard), speeds finite and > 0."""
        from feeler.errors import ArgumentError

        for opt, value, zero in (("--standard-um", self.standard_um, self.nafc),
                                 ("--speed-mm-s", self.speed_mm_s, False),
                                 ("--comparison-speed-mm-s", self.comparison_speed_mm_s, False)):
            if value is not None and not (math.isfinite(value) and (value >= 0 if zero else value > 0)):
                raise ArgumentError(opt, value, f"a finite number {'>= 0' if zero else '> 0'}"
                                    + (" (0 only in nAFC: detection)" if opt == "--standard-um" and not zero else ""))
        if self.subject is not None and not self.subject.strip():
            raise ArgumentError("--subject", self.subject, "a non-empty name")
        return self


def _matrix_rows(lines: list[tuple[int, str]], sep: str, decimal: str) -> tuple[list[list[str]], bool] | None:
    """(fields of every line, whether the first line is a header) when the lines are a
    psignifit data matrix: three fields per line, every line after the first numeric
    (the first too, or a header of three names); else None. Fields are split at ``sep``,
    or at runs of spaces when the first line holds no separator."""
    def fields(line: str) -> list[str]:
        return [f.strip() for f in (line.split(sep) if any(c in lines[0][1] for c in SEPARATORS) else line.split())]

    def numeric(row: list[str]) -> bool:
        try:
            return all(math.isfinite(float(f.replace(decimal, "."))) for f in row)
        except ValueError:
            return False

    rows = [fields(line) for _, line in lines]
    if any(len(r) != 3 for r in rows) or not all(numeric(r) for r in rows[1:]):
        return None
    head = not numeric(rows[0])
    if head and any(c in rows[0] for c in KEY_COLUMNS):      # a table's header, cut short: not a matrix
        return None
    return rows, head


def _matrix_problem(design: MatrixDesign | None) -> str:
    need = MatrixDesign().missing() if design is None else design.missing()
    return (f"a psignifit data matrix (height µm, n correct or higher, n trials per row) holds no design: give "
            f"{' and '.join(need)} (and --subject, --comparison-speed-mm-s, --nafc N as they apply), or write "
            f"the columns {', '.join(KEY_COLUMNS)}, n_trials and n_correct or n_comparison_higher")


def _read_matrix(path: Path, lines, rows: list[list[str]], head: bool, decimal: str,
                 design: MatrixDesign) -> pd.DataFrame:
    """The aggregated table of a psignifit data matrix under ``design`` (rows of the same
    height summed, as binomial counts may be)."""
    body = list(zip(lines[1:], rows[1:])) if head else list(zip(lines, rows))
    if not body:
        raise DataFileError(path, "no data rows")
    _refuse_a_doubled_table(path, [line for line, _ in body], [row for _, row in body])
    count = "n_correct" if design.nafc else "n_comparison_higher"
    names = ("1 (height)", f"2 ({'n correct' if design.nafc else 'n higher'})", "3 (n trials)")
    data: dict[str, list] = {c: [] for c in KEY_COLUMNS + ("n_trials", "k")}
    subject = design.subject or path.stem
    speed_c = design.speed_mm_s if design.comparison_speed_mm_s is None else design.comparison_speed_mm_s
    for (lineno, _), row in body:
        row = [f.replace(decimal, ".") for f in row]
        if _is_number(row[0]) and float(row[0]) < 0:      # psignifit levels are often signed differences
            raise DataFileError(path, f"line {lineno}, column {names[0]}: {row[0].strip()!r} is negative: column 1 "
                                      f"is the comparison's height, not its difference from the standard (height = "
                                      f"{design.standard_um:g} µm + difference)")
        height = _number(path, lineno, names[0], row[0])
        n = _count(path, lineno, names[2], row[2])
        try:
            k = _count(path, lineno, names[1], row[1])
        except DataFileError as exc:
            share = float(row[1]) if _is_number(row[1]) else math.nan
            if 0 < share < 1:                  # a proportion: psignifit's matrix holds counts
                raise DataFileError(path, f"line {lineno}, column {names[1]}: {row[1].strip()!r} looks like a "
                                          f"proportion; the matrix holds counts (n correct = proportion × n trials, "
                                          f"here {share * n:g})") from None
            raise
        if k > n:
            raise DataFileError(path, f"line {lineno}, column {names[1]}: {k} > column {names[2]} {n} (psignifit's "
                                      f"order is height, n correct, n trials)")
        for col, value in zip(KEY_COLUMNS, (subject, design.standard_um, design.speed_mm_s, height, speed_c)):
            data[col].append(value)
        data["n_trials"].append(n)
        data["k"].append(k)
    frame = _aggregate(_frame(data, count))
    if frame["n_trials"].sum() == 0:
        raise DataFileError(path, "no trials: every row has n trials = 0")
    return frame


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def count_column(trials: pd.DataFrame) -> str:
    """``n_correct`` for nAFC tables, else ``n_comparison_higher``."""
    return "n_correct" if "n_correct" in trials.columns else "n_comparison_higher"


def _layout(path, header: list[str], lineno: int) -> tuple[str, str]:
    """(count or response column, "counts" | "trials") from the header."""
    counts = [c for c in RESPONSES.values() if c in header]
    responses = [c for c in RESPONSES if c in header]
    missing = [c for c in KEY_COLUMNS if c not in header]
    if "n_trials" in header and len(counts) == 1 and not missing:
        return counts[0], "counts"
    if "n_trials" not in header and len(responses) == 1 and not counts and not missing:
        return responses[0], "trials"
    if len(counts) > 1 or len(responses) > 1:
        raise DataFileError(path, f"line {lineno}: both {' and '.join(counts or responses)}; "
                                  f"a table counts one kind of response")
    if "n_trials" in header and not counts:
        missing.append("n_comparison_higher or n_correct")
    elif not counts and not responses:
        missing.append("n_trials with n_comparison_higher or n_correct (or, one row per trial, "
                       "comparison_higher or correct)")
    from feeler.rundir import what_it_is

    hint = what_it_is(path, header=header, expected="trials.csv")
    if hint:
        raise DataFileError(path, f"line {lineno}: not a trial table: {hint}")
    raise DataFileError(path, f"line {lineno}: missing column(s) {', '.join(missing)}; required: "
                              f"{', '.join(KEY_COLUMNS)} and counts or responses"
                              + renamed_hint(header, [c for c in missing if " " not in c])
                              + (_proportion_hint(header) if not counts and not responses else ""))


_PROPORTION = re.compile(r"^(p|prop|proportion|pc|percent|pct|fraction|rate)([_ ].*)?$|.*(proportion|percent)",
                         re.IGNORECASE)


def _proportion_hint(header: list[str]) -> str:
    """"; 'p_higher' looks like a proportion: ..." for a table of proportions without counts
    (the fit needs how many trials each proportion came from)."""
    found = [h for h in header if h and _PROPORTION.match(h.strip())]
    if not found:
        return ""
    return (f"; {found[0]!r} looks like a proportion: the fit needs counts, n_comparison_higher (or n_correct) = "
            f"proportion × n_trials, with n_trials the trials behind each proportion")


def _refuse_a_doubled_table(path, lines, rows) -> None:
    """A table of counts whose rows repeat earlier rows, every field the same, for at least
    half of it (and 3 rows): a file appended to itself, whose copies would count as more
    trials. Two sessions of one condition share a row only by chance (mostly 0 or all
    'higher' at the extreme levels), and a trial-by-trial file repeats rows by nature."""
    seen: dict[tuple, int] = {}
    repeats = []
    for (lineno, _), row in zip(lines, rows):
        key = tuple(v.strip() for v in row)
        if key in seen:
            repeats.append((lineno, seen[key]))
        else:
            seen[key] = lineno
    if len(repeats) >= max(3, len(rows) / 2):
        raise DataFileError(path, f"{len(repeats)} of {len(rows)} rows repeat an earlier row in every field (e.g. "
                                  f"line {repeats[0][0]} = line {repeats[0][1]}): the file was probably appended to "
                                  f"itself, and the copies would count as more trials; keep each row once")


def read_trials(path: str | Path, *, design: MatrixDesign | None = None, matrix_use: str = "") -> pd.DataFrame:
    """Read, validate and (for trial-by-trial files) aggregate a trial table.

    Args:
        design: the subject, standard and speeds of a psignifit data matrix (and whether
            it counts nAFC answers); refused (ArgumentError) for a file with its own design.
        matrix_use: why a caller that takes no matrix cannot use one (its message names
            it); "" for a caller that reads matrices with their design.

    Returns:
        DataFrame with ``TRIAL_COLUMNS`` (comparison design) or ``NAFC_COLUMNS``:
        ``subject`` str, heights and speeds float64 (µm, mm/s), counts int64;
        ``attrs["comments"]`` holds the ``#`` lines, ``attrs["trial_rows"]`` the number
        of trial rows aggregated (0 for a file of counts).
    Raises:
        DataFileError: missing file or columns, empty table, non-numeric value, negative
            or non-integer count, a count above n_trials, a response that is not 1/0, a
            non-positive height or speed (a standard may be 0 in nAFC), no trial at all,
            a table of counts appended to itself, a psignifit data matrix without a
            design (one line naming the file, the line and the column).
        ArgumentError: a ``design`` for a file that has the design columns.
    """
    path = Path(path)
    if path.is_dir():
        if (path / "trials.csv").is_file():          # a run directory (`feeler simulate`, or a lab's own)
            return read_trials(path / "trials.csv", design=design, matrix_use=matrix_use)
        if not matrix_use:
            return _read_matrix_directory(path, design)
        from feeler.rundir import what_it_is

        hint = what_it_is(path, expected="trials.csv")
        raise DataFileError(path, "a directory without trials.csv: give the trial table (a CSV file, or a run "
                                  "directory that holds trials.csv)" + (f"; {hint}" if hint else ""))
    try:
        text = read_text(path)             # a byte order mark dropped; UTF-16 and Windows-1252 read too
    except FileNotFoundError:
        raise DataFileError(path, "no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DataFileError(path, f"cannot read: {exc}") from None
    lines = [(i, line) for i, line in enumerate(text.splitlines(), start=1)     # a line of separators only is
             if line.strip(" \t,;") and not line.lstrip().startswith("#")]         # a spreadsheet's empty row
    if not lines:
        raise DataFileError(path, "no header line; expected columns " + ", ".join(TRIAL_COLUMNS))
    sep, decimal = csv_dialect(lines[0][1])
    matrix = _matrix_rows(lines, sep, decimal)
    if matrix is not None:
        if matrix_use:
            raise DataFileError(path, f"a psignifit data matrix (height, n correct or higher, n trials per row): "
                                      f"{matrix_use}")
        if design is None or design.missing():
            raise DataFileError(path, _matrix_problem(design))
        frame = _read_matrix(path, lines, *matrix, decimal, design.check())
        frame.attrs["comments"] = comment_lines(text)
        frame.attrs["trial_rows"] = 0
        return frame
    if design is not None:
        from feeler.errors import ArgumentError

        given = [(opt, getattr(design, name)) for name, opt in (*MatrixDesign.OPTIONS.items(),
                                                                ("comparison_speed_mm_s", "--comparison-speed-mm-s"),
                                                                ("subject", "--subject"))
                 if getattr(design, name) is not None]
        raise ArgumentError(*(given[0] if given else ("--standard-um", None)), f"only for a psignifit data matrix "
                            f"(height, n correct, n trials); {path.name} has its own design columns (subject, "
                            f"standard_um, ...): drop the option")
    rows = list(csv.reader([line for _, line in lines], delimiter=sep))
    header = [h.strip() for h in rows[0]]
    count, layout = _layout(path, header, lines[0][0])
    if len(rows) == 1:
        raise DataFileError(path, "no data rows")
    nafc = count in ("n_correct", "correct")
    index = {c: header.index(c) for c in header}
    data: dict[str, list] = {c: [] for c in KEY_COLUMNS + ("n_trials", "k")}
    repeats = [lineno for (lineno, _), row in zip(lines[1:], rows[1:]) if [h.strip() for h in row] == header]
    if repeats:
        raise DataFileError(path, repeated_header_problem(repeats))
    if layout == "counts":
        _refuse_a_doubled_table(path, lines[1:], rows[1:])
    for (lineno, _), row in zip(lines[1:], rows[1:]):
        if len(row) != len(header):
            raise DataFileError(path, f"line {lineno}: {len(row)} fields, header has {len(header)}")
        subject = row[index["subject"]].strip()
        if not subject:
            raise DataFileError(path, f"line {lineno}, column subject: empty")
        data["subject"].append(subject)
        field = {col: row[i].replace(decimal, ".") for col, i in index.items()}     # a decimal comma read as a point
        for col in KEY_COLUMNS[1:]:
            data[col].append(_number(path, lineno, col, field[col], allow_zero=nafc and col == "standard_um"))
        if layout == "counts":
            n, k = (_count(path, lineno, col, field[col]) for col in ("n_trials", count))
            if k > n:
                raise DataFileError(path, f"line {lineno}, column {count}: {k} > n_trials {n}")
        else:
            n, k = 1, _response(path, lineno, count, row[index[count]])
        data["n_trials"].append(n)
        data["k"].append(k)
    frame = _frame(data, RESPONSES.get(count, count))
    if layout == "trials":
        frame = _aggregate(frame)
    if frame["n_trials"].sum() == 0:
        raise DataFileError(path, "no trials: every row has n_trials = 0")
    frame.attrs["comments"] = comment_lines(text)
    frame.attrs["trial_rows"] = len(rows) - 1 if layout == "trials" else 0
    return frame


#: file name endings read as psignifit data matrices in a directory of them
MATRIX_SUFFIXES = (".csv", ".txt", ".dat", ".tsv")


def _read_matrix_directory(directory: Path, design: MatrixDesign | None) -> pd.DataFrame:
    """A directory of psignifit data matrices, one per subject named after its file (in
    natural name order), under one ``design``."""
    import dataclasses

    if design is None or design.missing():
        need = " and ".join((design or MatrixDesign()).missing())
        raise DataFileError(directory, "a directory: fit psychophysics reads a trial table, or a directory of psignifit "
                                       f"data matrices (one per subject, named after its file) with {need}")
    if design.subject is not None:
        from feeler.errors import ArgumentError

        raise ArgumentError("--subject", design.subject, f"one file's subject; in {directory.name}/ each file's "
                                                         "subject is its name: drop the option")
    files = sorted((f for f in directory.iterdir() if f.is_file() and f.suffix.lower() in MATRIX_SUFFIXES),
                   key=lambda f: natural_key(f.name))
    if not files:
        raise DataFileError(directory, f"holds no data matrices (files ending {', '.join(MATRIX_SUFFIXES)})")
    frames = []
    for f in files:
        try:
            frames.append(read_trials(f, design=dataclasses.replace(design, subject=f.stem)))
        except InputError as exc:
            if isinstance(exc, DataFileError):
                raise
            raise DataFileError(f, "not a psignifit data matrix (height, n correct or higher, n trials per row), as "
                                   f"the other files of {directory.name}/ are; move it out") from None
    subjects = [f.stem for f in files]
    twice = sorted({s for s in subjects if subjects.count(s) > 1})
    if twice:
        raise DataFileError(directory, f"two files name subject {twice[0]!r} (e.g. {twice[0]}.csv and {twice[0]}.txt); "
                                       "keep one file per subject")
    out = pd.concat(frames, ignore_index=True)
    out.attrs["comments"] = [c for fr in frames for c in fr.attrs.get("comments", [])]
    out.attrs["trial_rows"] = 0
    return out


def _frame(data: dict, count: str) -> pd.DataFrame:
    data = dict(data)
    data[count] = data.pop("k")
    cols = list(KEY_COLUMNS) + ["n_trials", count]
    frame = pd.DataFrame(data, columns=cols)
    return frame.astype({c: "float64" for c in KEY_COLUMNS[1:]} | {"n_trials": "int64", count: "int64"}
                        | {"subject": str})


def _aggregate(trials: pd.DataFrame) -> pd.DataFrame:
    """One row per (subject, standard, comparison, speeds), first-appearance order."""
    keys = list(KEY_COLUMNS)
    out = trials.groupby(keys, sort=False, as_index=False)[[c for c in trials.columns if c not in keys]].sum()
    return out.reset_index(drop=True)


def synthetic_note(trials: pd.DataFrame) -> str:
    """The file's comment lines when they say the data are synthetic, else ""."""
    comments = trials.attrs.get("comments", [])
    return "\n".join(comments) if any("synthetic" in c.lower() for c in comments) else ""


def _number(path, lineno: int, col: str, text: str, *, allow_zero: bool = False) -> float:
    try:
        value = float(text)
    except ValueError:
        raise DataFileError(path, f"line {lineno}, column {col}: {text.strip()!r} is not a "
                                  f"number") from None
    if not math.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        raise DataFileError(path, f"line {lineno}, column {col}: {value!r} must be finite "
                                  f"and {'>= 0' if allow_zero else '> 0'}")
    if value > MAX_MAGNITUDE:               # 1e300 µm ended in a scipy traceback (an outside audit)
        raise DataFileError(path, f"line {lineno}, column {col}: {value:g} must be at most {MAX_MAGNITUDE:g} "
                                  f"(no height in µm or speed in mm/s comes near)")
    return value


def _count(path, lineno: int, col: str, text: str) -> int:
    try:
        value = float(text)
    except ValueError:
        raise DataFileError(path, f"line {lineno}, column {col}: {text.strip()!r} is not a "
                                  f"number") from None
    if not math.isfinite(value) or value < 0 or value != int(value):
        raise DataFileError(path, f"line {lineno}, column {col}: {text.strip()!r} must be a "
                                  f"whole number >= 0")
    return int(value)


def _response(path, lineno: int, col: str, text: str) -> int:
    word = text.strip().lower()
    if word in _TRUE:
        return 1
    if word in _FALSE:
        return 0
    raise DataFileError(path, f"line {lineno}, column {col}: {text.strip()!r} must be 1 or 0 "
                              f"(or true/false, yes/no)")


def write_trials(path: str | Path, trials: pd.DataFrame, *, comment: str = "") -> None:
    """Write an aggregated table as CSV, ``comment`` lines first as ``# ...``."""
    path = Path(path)
    count = count_column(trials)
    with path.open("w", encoding="utf-8", newline="") as fh:
        for line in comment.splitlines():
            fh.write(f"# {line}\n")
        out = trials.loc[:, list(KEY_COLUMNS) + ["n_trials", count]].copy()
        for col in ("n_trials", count):
            out[col] = np.asarray(out[col], dtype=np.int64)
        out.to_csv(fh, index=False, float_format="%.6g", lineterminator="\n")
