"""Robot scan datasets: read ``scans.csv`` back, and compute the per-scan features.

A run directory written by ``feeler simulate`` (or by an acquisition run) holds
``scans.csv`` in long format, one row per sample, with at least the columns
:data:`COLUMNS`. :func:`read_scans` validates it and returns a :class:`Scans` of
arrays ``(n_scans, n_time)``; a directory of one CSV file per scan, as lab software often
writes them, reads as the scans of its files in name order (:func:`scan_files`).
:func:`scan_features` turns scans into the features later issues use: the neuron's peak
pulse density (strain = U_y / representative length, paper §5.2), the ΔU_y jump (Fig. 7)
and the raw U̇_y peak (Fig. 8).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from feeler.errors import DataFileError

__all__ = ["COLUMNS", "Scans", "Features", "csv_dialect", "header_line", "read_text", "csv_text", "read_csv_file",
           "missing_columns_problem", "renamed_hint", "shared_scan_id_problem", "scan_time_problem", "starts_again",
           "varying_label_problem", "repeated_header_problem", "read_scans", "scan_files", "header_columns",
           "scan_file_frames", "natural_key", "strain", "jump_uy_mm", "peak_rate_uy_mm_s", "scan_features",
           "proportion_correct"]

COLUMNS = ("scan_id", "step_mm", "speed_mm_s", "t_s", "x_mm", "ux_mm", "uy_mm", "uz_mm")
#: the largest magnitude a data value may have: far beyond any measurement in the files'
#: units (10⁹ km in mm, 30 000 years in s), and small enough that squares and sums of
#: squares of a few thousand values stay finite in float64 (1e300 overflowed into numpy
#: warnings and a traceback: an outside audit)
MAX_MAGNITUDE = 1e12
#: columns a scans file may leave out: no scan reader uses them (the neuron reads U_y); absent, they read as 0
UNREAD_COLUMNS = ("ux_mm", "uz_mm")


@dataclass(frozen=True)
class Scans:
    """Scans of equal length.

    Attributes:
        scan_id (ndarray[n_scans] int), step_mm, speed_mm_s (ndarray[n_scans]): per-scan labels.
        t_s, x_mm, ux_mm, uy_mm, uz_mm (ndarray[n_scans, n_time]): samples (s, mm); each
            scan's own sample times (simulated scans share one row, acquired scans record
            when each sample was taken).
        labels (tuple[str, ...] | None): how a message names each scan when its number is
            not what the user wrote: ``scan_id 'touch-04'`` for ids written as names,
            ``scan file scan_03.csv`` for a directory of scan files; None: ``scan_id N``.
    """

    scan_id: np.ndarray
    step_mm: np.ndarray
    speed_mm_s: np.ndarray
    t_s: np.ndarray
    x_mm: np.ndarray
    ux_mm: np.ndarray
    uy_mm: np.ndarray
    uz_mm: np.ndarray
    labels: tuple[str, ...] | None = None

    def label(self, k: int) -> str:
        """How a message names scan ``k`` (0-based place)."""
        return self.labels[k] if self.labels is not None else f"scan_id {self.scan_id[k]}"


@dataclass(frozen=True)
class Features:
    """Per-scan features (ndarray[n_scans] each): peak z (V), ΔU_y jump (mm), peak |U̇_y| (mm/s)."""

    peak_z: np.ndarray
    jump_uy_mm: np.ndarray
    peak_rate_uy_mm_s: np.ndarray


SEPARATORS = (",", ";", "\t")


def csv_dialect(header: str) -> tuple[str, str]:
    """(separator, decimal mark) of a CSV from its header line.

    feeler writes ``,`` with ``.`` decimals. A spreadsheet in a locale whose decimal mark
    is a comma (German, French, ...) exports ``;`` instead, with ``,`` decimals; tabs
    come from copy-and-paste. The separator is whichever of ``,``, ``;`` and a tab the
    header holds most of (``,`` on a tie or when it holds none); the decimal mark is ``,``
    unless the separator is."""
    counts = [header.count(sep) for sep in SEPARATORS]
    sep = SEPARATORS[int(np.argmax(counts))] if max(counts) else ","
    return sep, ("." if sep == "," else ",")


def read_text(path: Path) -> str:
    """A text file as lab software saves it: UTF-8 (a byte order mark dropped), UTF-16 with
    its byte order mark (Excel's "Unicode Text"), else Windows-1252 (Excel's "CSV" on
    Windows in a western locale: a comment with "ü" or "µ" is not UTF-8), whose bytes all
    decode. OSError (FileNotFoundError) passes, and UnicodeDecodeError for broken UTF-16
    or a NUL byte outside UTF-16 (a binary file)."""
    raw = Path(path).read_bytes()
    if raw[:2] in (b"\xff\xfe", b"\xfe\xff"):
        return raw.decode("utf-16")
    nul = raw.find(b"\x00")
    if nul >= 0:                                  # no 8-bit text holds one: a binary or broken file
        raise UnicodeDecodeError("utf-8", raw, nul, nul + 1, "a NUL byte: not a text file")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("cp1252", errors="replace")


def header_line(text: str) -> str:
    """The first line that is neither blank nor a ``#`` comment ("" if none)."""
    return next((ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")), "")


def repeated_header_problem(lines: list[int], *, why: str | None = None) -> str:
    """The line for a header repeated at ``lines`` (1-based line numbers of a whole file),
    or, given ``why``, at the one line ``lines[0]`` of a file still being read."""
    why = why or f"{len(lines)} repeat(s): files joined with their headers?"
    return f"line {lines[0]} repeats the header ({why}); delete the repeated header lines"


def _repeated_header(text: str, header: str) -> list[int]:
    """Line numbers (1-based) of the lines after the header that repeat it."""
    import re

    if not header.strip():
        return []
    start = text.find(header) + len(header)
    pattern = re.compile(r"^[ \t]*" + re.escape(header.strip()) + r"[ \t\r]*$", re.MULTILINE)
    before = text.count("\n", 0, start) + 1
    out, line, pos = [], before, start
    for m in pattern.finditer(text, start):
        line += text.count("\n", pos, m.start())
        out.append(line)
        pos = m.start()
    return out


def csv_text(path: Path) -> str:
    """The text of the CSV at ``path`` (:func:`read_text`); DataFileError naming it when
    missing or unreadable."""
    path = Path(path)
    try:
        return read_text(path)
    except FileNotFoundError:
        raise DataFileError(path, "no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DataFileError(path, f"not a readable CSV: {exc}") from None


def read_csv_file(path: Path, *, comment: str | None = None, text: str | None = None):
    """The CSV at ``path`` as a DataFrame; DataFileError naming it when missing or unreadable.

    Separated by commas, semicolons or tabs (:func:`csv_dialect`); in a file separated by
    semicolons or tabs a decimal comma is read as a point (``0,05`` → 0.05). A UTF-8 byte
    order mark (spreadsheets write one) is dropped. ``comment``: lines starting with it
    are skipped, and kept (without it) in ``attrs["comments"]``; lines starting with ``#``
    are always skipped so (a lab's notes above the header: sensor, date, operator), as
    they were only for the readers that asked. The header repeated further down (files
    joined with ``cat``) is an error naming its line. ``text``: the file's text, when the
    caller has read it already (:func:`csv_text`)."""
    import io

    import pandas as pd

    path = Path(path)
    text = csv_text(path) if text is None else text
    header = header_line(text)
    sep, decimal = csv_dialect(header)
    repeats = _repeated_header(text, header)
    if repeats:
        raise DataFileError(path, repeated_header_problem(repeats))
    if not text.strip():                          # pandas says "No columns to parse from file"
        raise DataFileError(path, "empty: no header and no rows")
    remarks = comment_lines(text)
    data = "\n".join(ln for ln in text.splitlines() if not ln.lstrip().startswith("#")) if remarks else text
    try:
        frame = pd.read_csv(io.StringIO(data), sep=sep, comment=comment,
                            dtype=None if decimal == "." else str)
    except (ValueError, pd.errors.ParserError) as exc:
        raise DataFileError(path, f"not a readable CSV: {' '.join(str(exc).split())}") from None
    frame.columns = [str(c).strip() for c in frame.columns]
    # what a spreadsheet leaves behind: rows of separators only after the data (rows deleted
    # in Excel), and empty columns without a header (cells once used): not data
    empty = frame.isna().all(axis=1).to_numpy()
    last = len(empty) - int(np.argmin(empty[::-1])) if not empty.all() else 0
    frame = frame.iloc[:last]
    frame = frame.drop(columns=[c for c in frame.columns if c.startswith("Unnamed: ") and frame[c].isna().all()])
    if decimal != ".":
        for col in frame.columns:
            given = frame[col].str.strip()
            pointed = given.str.replace(",", ".", regex=False)
            values = pd.to_numeric(pointed, errors="coerce")
            if values.notna().sum() == given.notna().sum():                # every given value a number
                frame[col] = values
            elif values.notna().sum() > given.notna().sum() / 2:           # a number column with a bad entry:
                frame[col] = pointed                                       # its reader names the entry
    if comment and comment != "#":
        frame.attrs["comments"] = [ln.lstrip()[len(comment):].strip() for ln in text.splitlines()
                                   if ln.lstrip().startswith(comment)]
    elif comment or remarks:
        frame.attrs["comments"] = remarks
    return frame


def comment_lines(text: str) -> list[str]:
    """The ``#`` lines of a CSV's ``text``, without the ``#`` and surrounding blanks."""
    return [ln.lstrip()[1:].strip() for ln in text.splitlines() if ln.lstrip().startswith("#")]


_UNIT = re.compile(r"^(?P<base>.*?)\s*[\[(]\s*(?P<unit>[^\])]*?)\s*[\])]\s*$")     # "t [s]", "Uy (mm)"
_UNIT_SUFFIX = re.compile(r"^(?P<base>.+?)_(?P<unit>ms|us|um|µm|μm|m|cm|mn|kn|n|s|mm)$", re.IGNORECASE)    # "t_ms"
_SPELLINGS = {"um": "µm", "μm": "µm", "micron": "µm", "microns": "µm", "sec": "s", "mm/sec": "mm/s"}
_SUFFIXES = (("_mm_s", "mm/s"), ("_mm", "mm"), ("_um", "µm"), ("_n", "n"), ("_s", "s"))


#: other names experiment software gives a column (PsychoPy's "participant")
_SYNONYMS = {"participant": "subject", "observer": "subject", "subj": "subject", "subjectid": "subject",
             "participantid": "subject"}


def _squeezed(name: str) -> str:
    return name.lower().replace("_", "").replace(" ", "").replace("-", "")


def renamed_hint(header, missing) -> str:
    """"; the header has 't [s]', 'Uy (mm)': rename them t_s, uy_mm" for header names that
    are a missing column with its unit in brackets or in another case; "; 't [ms]' is in
    ms: t_s is in s (convert it)" for one in another unit; "" when there is none."""
    found, other = [], []
    for col in missing:
        base, unit = next(((col[:-len(sfx)], u) for sfx, u in _SUFFIXES if col.endswith(sfx)), (col, ""))
        for name in header:
            text = str(name).strip()
            m = _UNIT.match(text) or _UNIT_SUFFIX.match(text)
            if m and _squeezed(m["base"]) == _squeezed(base):
                given = _SPELLINGS.get(m["unit"].lower(), m["unit"])
                if not unit or given.lower() == unit:
                    found.append((text, col))
                else:
                    other.append((text, col, given, unit))
                break
            if not m and text != col and (_squeezed(text) == _squeezed(col)
                                          or _SYNONYMS.get(_squeezed(text)) == col):
                found.append((text, col))
                break
    out = ""
    if found:
        out += (f"; the header has {', '.join(repr(t) for t, _ in found)}: rename "
                f"{'it' if len(found) == 1 else 'them'} {', '.join(c for _, c in found)}")
    for text, col, given, unit in other:
        out += f"; {text!r} is in {given}: {col} is in {'N' if unit == 'n' else unit} (convert it)"
    return out


def missing_columns_problem(frame, columns) -> str | None:
    """"missing column(s) …; required: …" when ``frame`` lacks any of ``columns``, else None;
    a header read as one column is shown, with the separators that are read."""
    missing = [c for c in columns if c not in frame.columns]
    if not missing:
        return None
    out = f"missing column(s) {', '.join(missing)}; required: {', '.join(columns)}" + renamed_hint(frame.columns,
                                                                                                  missing)
    if len(frame.columns) == 1:
        out += (f" (the header is one column, {str(frame.columns[0])[:60]!r}: separate columns by "
                "commas, semicolons or tabs)")
    return out


#: columns that make a CSV in a directory a file of one scan (:func:`scan_files`)
SCAN_FILE_COLUMNS = ("t_s", "uy_mm")


def scan_files(directory: str | Path) -> list[Path]:
    """The CSV files of single scans in ``directory``: every ``*.csv`` whose header holds
    :data:`SCAN_FILE_COLUMNS`, in natural name order (``scan_2`` before ``scan_10``; ids:
    :func:`scan_file_frames`). Empty when there are none (or a ``scans.csv``
    or ``samples.csv``, the files of a run directory, is there)."""
    directory = Path(directory)
    if not directory.is_dir() or any((directory / n).exists() for n in ("scans.csv", "samples.csv")):
        return []
    out = [f for f in directory.glob("*.csv") if all(c in header_columns(f) for c in SCAN_FILE_COLUMNS)]
    return sorted(out, key=lambda f: natural_key(f.name))


def header_columns(path: Path) -> list[str]:
    """The column names of a CSV's header line ([] when it cannot be read as text)."""
    try:
        first = header_line(read_text(path))
    except (OSError, UnicodeDecodeError):
        return []
    return [c.strip() for c in first.strip().split(csv_dialect(first)[0])] if first.strip() else []


def natural_key(name: str) -> list:
    """Sort key of a file name with its numbers as numbers: ``scan_2`` before ``scan_10``."""
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", name)]


def scan_file_frames(files: list[Path]) -> list:
    """The rows of each file of one scan (:func:`scan_files`), each with its ``scan_id``:
    the file's own when every file holds one and no two share it, else the file's place
    in name order (0, 1, …). DataFileError naming a file that holds several scan ids."""
    import pandas as pd

    frames, own = [], []
    for path in files:
        frame = read_csv_file(path)
        ids = (pd.to_numeric(frame["scan_id"], errors="coerce").dropna().unique() if "scan_id" in frame.columns
               else np.empty(0))
        if ids.size > 1:
            raise DataFileError(path, f"holds {ids.size} scan ids: a directory of scan files takes one scan per "
                                      f"file (move this file out, or join every scan into one scans.csv)")
        frames.append(frame)
        own.append(ids[0] if ids.size == 1 and float(ids[0]).is_integer() else None)
    keep = None not in own and len(set(own)) == len(own)
    for k, frame in enumerate(frames):
        frame["scan_id"] = int(own[k]) if keep else k
    return frames


def read_scans(path: str | Path) -> Scans:
    """Read a run directory's ``scans.csv`` (or the CSV itself, or a directory of one file
    per scan: :func:`scan_files`, each file checked on its own first).

    Raises:
        DataFileError: missing file or column, non-numeric, NaN or infinite values, an id
            shared by several scans (its times start again, or its step label changes), t
            not strictly increasing within a scan (a sample written twice, or rows out of
            time order: :func:`scan_time_problem`, naming the rows), or scans of unequal
            length (naming a sample missing mid-scan).
    """
    import pandas as pd

    path = Path(path)
    files = scan_files(path)
    if files:
        frames = scan_file_frames(files)
        for f, frame in zip(files, frames):
            _scans_of(frame.copy(), f)
        return _scans_of(pd.concat(frames, ignore_index=True), path,
                         names={int(fr["scan_id"].iloc[0]): f.name for f, fr in zip(files, frames) if len(fr)})
    if path.is_dir():
        path = path / "scans.csv"
    return _scans_of(read_csv_file(path), path)


def _scans_of(frame, path: Path, names: dict[int, str] | None = None) -> Scans:
    """:func:`read_scans` of a frame (``path`` names it in errors; ``names``: the file of
    each scan id, for a directory of scan files)."""
    problem = missing_columns_problem(frame, [c for c in COLUMNS if c not in UNREAD_COLUMNS])
    if problem:
        raise DataFileError(path, problem)
    for col in UNREAD_COLUMNS:
        if col not in frame.columns:
            frame[col] = 0.0
    if len(frame) == 0:
        if Path(path).name == "scans.csv" and (Path(path).parent / "journal.jsonl").is_file():
            raise DataFileError(path, "no rows: no complete scan yet (an acquisition stopped before its first scan "
                                      "finished; `feeler acquire ... --resume` with the same --out continues it)")
        raise DataFileError(path, "no rows")
    frame, named = named_scan_ids(frame, path)
    for col in COLUMNS:
        frame[col] = numeric_column(frame, col, path)
    groups = frame.groupby("scan_id", sort=False)
    # before lengths: shared ids, a sample written twice or rows out of order make "unequal lengths" too
    late = (groups["t_s"].diff() <= 0).to_numpy()
    if late.any():                              # the first such scan in the file's order, as classify's reader
        flagged = set(frame["scan_id"][late])
        sid = next(v for v in frame["scan_id"].drop_duplicates() if v in flagged)
        rows = (frame["scan_id"] == sid).to_numpy()
        raise DataFileError(path, scan_time_problem(scan_id_text(sid, named), frame.loc[rows, "t_s"].to_numpy(float),
                                                    np.flatnonzero(rows) + 1, frame.loc[rows, "step_mm"].to_numpy(float)))
    for col in ("step_mm", "speed_mm_s"):               # before lengths too, for the same reason
        varying = groups[col].transform("nunique").to_numpy() > 1
        if varying.any():
            sid = frame["scan_id"].iloc[int(np.flatnonzero(varying)[0])]
            raise DataFileError(path, varying_label_problem(col, scan_id_text(sid, named),
                                                            frame.loc[frame["scan_id"] == sid, col]))
    lengths = groups.size()
    if lengths.nunique() != 1:
        common = int(lengths.mode().iloc[0])
        odd = lengths[lengths != common]
        which = (f"scan {scan_id_text(odd.index[0], named)}" if names is None
                 else names.get(int(odd.index[0]), f"scan {odd.index[0]}"))
        head = (f"{'column scan_id: scans' if names is None else 'scan files'} have unequal lengths "
                f"{sorted(set(lengths))} ({which} has {int(odd.iloc[0])} samples, {len(lengths) - len(odd)} of "
                f"{len(lengths)} have {common})")
        speeds = np.unique(groups["speed_mm_s"].first().to_numpy(float))
        if speeds.size > 1:           # trimming would cut the slower scans' traverse short
            raise DataFileError(path, f"{head} at speeds {', '.join(f'{v:g}' for v in speeds)} mm/s; a fit needs "
                                      f"scans of one length, and trimming would cut the slower ones' traverse "
                                      f"short: fit each speed on its own (classify and decode take scans of any "
                                      f"length)")
        gap = missing_sample_problem(frame.loc[frame["scan_id"] == odd.index[0], "t_s"].to_numpy(float))
        if gap and int(odd.iloc[0]) < common:
            raise DataFileError(path, f"{head}: {gap}; a fit needs scans of one length: restore that sample or leave "
                                      f"the scan out (classify and decode take scans of any length)")
        raise DataFileError(path, f"{head}; a fit needs scans of one length: trim them to {int(lengths.min())} "
                                  f"samples (classify and decode take scans of any length)")
    n_scans, n_time = len(lengths), int(lengths.iloc[0])
    ids = np.asarray(lengths.index)
    frame = frame.set_index("scan_id").loc[ids].reset_index()

    def grid(col):
        return frame[col].to_numpy(dtype=float).reshape(n_scans, n_time)

    t = grid("t_s")
    bad = np.flatnonzero(np.any(np.diff(t, axis=1) <= 0, axis=1))
    if bad.size:
        raise DataFileError(path, f"column t_s: not strictly increasing within scan_id "
                                  f"{scan_id_text(ids[bad[0]], named)}")
    labels = None
    if names is not None:
        labels = tuple(f"scan file {names[int(i)]}" if int(i) in names else f"scan_id {i}" for i in ids)
    elif named is not None:
        labels = tuple(f"scan_id {scan_id_text(i, named)}" for i in ids)
    return Scans(scan_id=ids.astype(int), step_mm=grid("step_mm")[:, 0], speed_mm_s=grid("speed_mm_s")[:, 0],
                 t_s=t, x_mm=grid("x_mm"), ux_mm=grid("ux_mm"), uy_mm=grid("uy_mm"), uz_mm=grid("uz_mm"),
                 labels=labels)


def numeric_column(frame, col: str, path, *, blank_ok: bool = False):
    """Column ``col`` of ``frame`` as numbers (a pandas Series, float), or DataFileError
    naming ``path``, the column and the data row of the first value that is not a finite
    number: text, inf, or a blank cell unless ``blank_ok`` (an optional label left empty
    reads as NaN; text in it is still an error)."""
    import pandas as pd

    raw = frame[col]
    values = pd.to_numeric(raw, errors="coerce").astype(float)
    missing = values.isna().to_numpy()
    if blank_ok:
        text = raw.astype("string").str.strip()
        missing = missing & ~(raw.isna() | (text == "")).to_numpy(dtype=bool, na_value=True)
    if missing.any():
        row = int(np.flatnonzero(missing)[0])
        raise DataFileError(path, f"column {col}: missing or non-numeric value at data row {row + 1}")
    infinite = np.isinf(values.to_numpy())
    if infinite.any():
        row = int(np.flatnonzero(infinite)[0])
        raise DataFileError(path, f"column {col}: {values.iloc[row]} at data row {row + 1}; "
                                  f"values must be finite numbers")
    huge = np.abs(values.to_numpy()) > MAX_MAGNITUDE
    if huge.any():
        row = int(np.flatnonzero(huge)[0])
        raise DataFileError(path, f"column {col}: {values.iloc[row]:g} at data row {row + 1}; values must lie "
                                  f"within ±{MAX_MAGNITUDE:g} (no measurement in these units comes near)")
    return values


def named_scan_ids(frame, path: Path):
    """Scan ids written as names (``touch-01``, ``S1T3``, or ``2.1`` for touch 1 of plate 2),
    as lab software often writes them: numbered 0, 1, … in order of first appearance →
    (the frame with those numbers, ``{number: name}``); numeric ids come back unchanged
    with None. DataFileError naming the row of a missing id."""
    import pandas as pd

    col = frame["scan_id"]
    text = col.astype("string").str.strip()
    blank = (text.isna() | (text == "")).to_numpy()
    number = pd.to_numeric(col, errors="coerce").to_numpy(float)[~blank]
    if np.all(np.isfinite(number) & (number == np.round(number))):
        return frame, None                          # whole numbers (a blank is reported by the numeric check)
    if blank.any():
        raise DataFileError(path, f"column scan_id: missing value at data row {int(np.flatnonzero(blank)[0]) + 1}")
    codes, names = pd.factorize(text, sort=False)
    frame = frame.copy()
    frame["scan_id"] = codes
    return frame, {k: str(v) for k, v in enumerate(names)}


def scan_id_text(scan_id, names: dict | None = None) -> str:
    """A scan id as the file wrote it: its name (:func:`named_scan_ids`), else the number
    (text already made is passed through)."""
    if isinstance(scan_id, str):
        return scan_id
    return repr(names[int(scan_id)]) if names and int(scan_id) in names else f"{scan_id:g}"


def shared_scan_id_problem(scan_id, t_s, step_mm=None) -> str:
    """The line for a scan_id whose times start again (fall back to the scan's first time):
    several scans share the id (lab files often number scans afresh on each plate)."""
    t = np.asarray(t_s, float)
    restarts = int(np.sum(starts_again(t)))
    steps = np.unique(np.asarray(step_mm, float)) if step_mm is not None else np.empty(0)
    steps = steps[np.isfinite(steps)]
    held = f", with steps {', '.join(f'{v:g}' for v in steps)} mm" if steps.size > 1 else ""
    return (f"column scan_id: t_s restarts {restarts} time(s) within scan_id {scan_id_text(scan_id)}{held}: "
            f"about {restarts + 1} scans share this id; give every scan its own scan_id across the file (ids that "
            f"start again on each plate are not unique)")


def scan_time_problem(scan_id, t_s, rows, step_mm=None) -> str | None:
    """The line for one scan_id whose times ``t_s`` (in file order, at data rows ``rows``)
    do not rise sample after sample, or None: several scans share the id (each run of rows
    starts its times again), a sample written twice, or rows out of time order (a file
    sorted by another column in a spreadsheet), each with what to do."""
    t = np.asarray(t_s, float)
    d = np.diff(t)
    late = np.flatnonzero(d <= 0)
    if not late.size:
        return None
    drops = d < 0
    if drops.any() and not np.any(drops & ~starts_again(t)):        # increasing runs, each from the start
        return shared_scan_id_problem(scan_id, t, step_mm)
    repeats = t.size - np.unique(t).size
    if repeats == t.size - 1:                                       # one time for all: not several scans
        return (f"column t_s: scan_id {scan_id_text(scan_id)} has one time, {t[0]:g} s, in all its {t.size} samples "
                f"(data rows {rows[0]}-{rows[-1]}): t_s must rise sample after sample (a column filled with one "
                f"value?)")
    if not drops.any() and 2 * repeats >= t.size:                   # sorted, but every time held several times
        return (f"column scan_id: scan_id {scan_id_text(scan_id)} holds each of its times about "
                f"{t.size / (t.size - repeats):.0f} times: several scans share this id; give every scan its own "
                f"scan_id across the file")
    i = int(late[0])
    head = f"column t_s: not strictly increasing within scan_id {scan_id_text(scan_id)}"
    if d[i] == 0:
        return f"{head}: t_s {t[i]:g} twice, at data rows {rows[i]} and {rows[i + 1]} (a sample written twice?)"
    return (f"{head}: t_s {t[i]:g} at data row {rows[i]}, then {t[i + 1]:g} at data row {rows[i + 1]}; sort the rows "
            f"by scan_id, then t_s, or correct that time")


def missing_sample_problem(t_s) -> str | None:
    """"its times jump from 9.5 to 10.5 s, …" for a scan whose one interval is at least
    1.5 times its median sample interval (a sample missing there), else None."""
    t = np.asarray(t_s, float)
    d = np.diff(t)
    if d.size < 3:
        return None
    j, med = int(np.argmax(d)), float(np.median(d))
    if not d[j] >= 1.5 * med > 0:
        return None
    return (f"its times jump from {t[j]:g} to {t[j + 1]:g} s where its other samples lie {med:g} s apart "
            f"(a sample missing there?)")


def varying_label_problem(col: str, scan_id, values) -> str:
    """The line for a label column that changes within one scan."""
    seen = ", ".join(f"{v:g}" for v in dict.fromkeys(np.asarray(values, float).tolist()))
    return (f"column {col}: must be constant within each scan; scan_id {scan_id_text(scan_id)} holds {seen} (if "
            f"these rows are several scans, give each its own scan_id)")


def starts_again(t: np.ndarray) -> np.ndarray:
    """Where one scan's times fall back to its first time or before (ndarray[n − 1] bool)."""
    return (np.diff(t) < 0) & (t[1:] <= t[0])


def strain(uy_mm, length_mm: float) -> np.ndarray:
    """Neuron input strain U_y / representative length (dimensionless; paper §5.2)."""
    return np.asarray(uy_mm, dtype=float) / float(length_mm)


def jump_uy_mm(uy_mm, t_s, *, gap_s: float, span_s: float) -> np.ndarray:
    """ΔU_y jump of each scan: the largest change between the means of two ``span_s`` windows
    ``gap_s`` apart (the gap spans the rise over the step), with its sign.

    Args:
        uy_mm (ndarray[..., n_time]), t_s (ndarray[n_time] or one row per scan): the
            windows are counted in samples of the median interval, so sampling should be
            close to uniform.
    Returns:
        ndarray[...] in mm.
    """
    uy = np.asarray(uy_mm, dtype=float)
    dt = float(np.median(np.diff(t_s)))
    m, g = max(1, int(round(span_s / dt))), int(round(gap_s / dt))
    n = uy.shape[-1]
    if 2 * m + g > n:
        raise ValueError(f"gap_s + 2*span_s = {gap_s + 2 * span_s} s longer than the scan")
    c = np.concatenate([np.zeros(uy.shape[:-1] + (1,)), np.cumsum(uy, axis=-1)], axis=-1)
    means = (c[..., m:] - c[..., :-m]) / m                   # mean of uy[k:k+m], k = 0..n-m
    diff = means[..., m + g:] - means[..., : n - m - (m + g) + 1]
    pick = np.argmax(np.abs(diff), axis=-1)[..., None]
    return np.take_along_axis(diff, pick, axis=-1)[..., 0]


def peak_rate_uy_mm_s(uy_mm, t_s) -> np.ndarray:
    """Raw peak |U̇_y| per scan by backward difference (mm/s), ndarray[...]."""
    return np.max(np.abs(np.diff(uy_mm, axis=-1) / np.diff(t_s)), axis=-1)


def scan_features(scans: Scans, *, a: float, tau_s: float, h: float, length_mm: float,
                  kernel: str = "boxcar", gap_s: float, span_s: float) -> Features:
    """Peak z (via :mod:`feeler.models.neuron`), ΔU_y jump and raw U̇_y peak per scan."""
    from feeler.models import neuron

    t = scans.t_s
    peak_u1 = neuron.per_time_base(lambda s, tt: neuron.peak_window_sum(s, tt, tau=tau_s, kernel=kernel),
                                   strain(scans.uy_mm, length_mm), t)
    return Features(peak_z=np.asarray(neuron.peak_pulse_density(peak_u1, a, h)),
                    jump_uy_mm=jump_uy_mm(scans.uy_mm, t, gap_s=gap_s, span_s=span_s),
                    peak_rate_uy_mm_s=peak_rate_uy_mm_s(scans.uy_mm, t))


def proportion_correct(lower, higher) -> float:
    """2AFC proportion correct over all pairs: P(higher > lower) + ½ P(tie)."""
    lo = np.asarray(lower, dtype=float)[:, None]
    hi = np.asarray(higher, dtype=float)[None, :]
    return float(np.mean(hi > lo) + 0.5 * np.mean(hi == lo))
