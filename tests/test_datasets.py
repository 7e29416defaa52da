"""scans.csv reading (validated) and the per-scan features, against hand-computed cases."""
import numpy as np
import pytest

from feeler.datasets import (COLUMNS, Scans, csv_dialect, jump_uy_mm, peak_rate_uy_mm_s, proportion_correct, read_scans,
                             scan_features, strain)
from feeler.errors import DataFileError


def write_csv(path, rows, columns=COLUMNS):
    lines = [",".join(columns)] + [",".join(str(v) for v in row) for row in rows]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def good_rows():
    rows = []
    for scan in (0, 1):
        for k in range(4):
            rows.append([scan, 0.05 * scan, 0.5, 0.5 * k, 0.25 * k, -0.01, 0.05 + 0.01 * k * scan, 0.0])
    return rows


def test_round_trip_of_a_small_file(tmp_path):
    scans = read_scans(write_csv(tmp_path / "scans.csv", good_rows()))
    assert scans.t_s.shape == (2, 4)
    np.testing.assert_array_equal(scans.scan_id, [0, 1])
    np.testing.assert_array_equal(scans.step_mm, [0.0, 0.05])
    np.testing.assert_allclose(scans.uy_mm[1], [0.05, 0.06, 0.07, 0.08])
    assert read_scans(tmp_path).uy_mm.shape == (2, 4)          # a run directory works too


def test_the_displacements_no_reader_uses_may_be_left_out(tmp_path):
    """U_x and U_z: the neuron reads U_y alone, so a file without them reads, with them 0
    (an outside audit's scans of t, x, U_y, step and speed were refused for lacking them)."""
    cols = [c for c in COLUMNS if c not in ("ux_mm", "uz_mm")]
    rows = [[r[COLUMNS.index(c)] for c in cols] for r in good_rows()]
    scans = read_scans(write_csv(tmp_path / "scans.csv", rows, cols))
    np.testing.assert_allclose(scans.uy_mm[1], [0.05, 0.06, 0.07, 0.08])
    assert not scans.ux_mm.any() and not scans.uz_mm.any()


@pytest.mark.parametrize("mutate, words", [
    (lambda rows: ([r[:4] + r[5:] for r in rows], COLUMNS[:4] + COLUMNS[5:]), "missing column(s) x_mm"),
    (lambda rows: (rows[:3] + [rows[3][:6] + ["nan"] + rows[3][7:]] + rows[4:], COLUMNS), "column uy_mm"),
    (lambda rows: (rows[:5] + [rows[5][:6] + ["inf"] + rows[5][7:]] + rows[6:], COLUMNS),
     "column uy_mm: inf at data row 6; values must be finite"),
    (lambda rows: (rows[:1] + [rows[1][:4] + ["-inf"] + rows[1][5:]] + rows[2:], COLUMNS), "column x_mm: -inf at data row 2"),
    (lambda rows: (rows[:2] + [rows[2][:3] + ["abc"] + rows[2][4:]] + rows[3:], COLUMNS), "column t_s"),
    (lambda rows: (rows[:2] + [rows[2][:3] + [0.25] + rows[2][4:]] + rows[3:], COLUMNS), "column t_s: not strictly"),
    (lambda rows: (rows[:7], COLUMNS), "column scan_id: scans have unequal lengths [3, 4] (scan 0 has 4 samples, "
                                       "1 of 2 have 3); a fit needs scans of one length: trim them to 3 samples"),
    (lambda rows: (rows[:1] + [rows[1][:1] + [0.2] + rows[1][2:]] + rows[2:], COLUMNS), "column step_mm"),
    (lambda rows: ([], COLUMNS), "no rows"),
])
def test_malformed_files_name_file_and_column(tmp_path, mutate, words):
    rows, columns = mutate(good_rows())
    path = write_csv(tmp_path / "scans.csv", rows, columns)
    with pytest.raises(DataFileError) as info:
        read_scans(path)
    assert words in str(info.value) and str(path) in str(info.value)


def test_scans_of_unequal_length_at_two_speeds_are_not_told_to_trim(tmp_path):
    """The same traverse at 0.5 and 1 mm/s: 'trim them to 2 samples' would cut the slow
    scans' traverse in half; the line names the speeds and says to fit each on its own."""
    rows = [[0, 0.0, 0.5, 0.5 * k, 0.25 * k, 0.0, 0.05, 0.0] for k in range(4)]
    rows += [[1, 0.0, 1.0, 0.5 * k, 0.5 * k, 0.0, 0.05, 0.0] for k in range(2)]
    path = write_csv(tmp_path / "scans.csv", rows)
    with pytest.raises(DataFileError) as info:
        read_scans(path)
    assert str(info.value).endswith("at speeds 0.5, 1 mm/s; a fit needs scans of one length, and trimming would cut "
                                    "the slower ones' traverse short: fit each speed on its own (classify and decode "
                                    "take scans of any length)") and "trim them to" not in str(info.value)


def test_missing_file(tmp_path):
    with pytest.raises(DataFileError, match="no such file"):
        read_scans(tmp_path / "nothing.csv")


def test_jump_and_rate_on_a_hand_made_step():
    t = np.arange(20) * 0.5
    uy = np.where(t >= 4.0, 0.1, 0.0) + 0.02                    # jump of 0.1 mm between t = 3.5 and 4.0
    assert jump_uy_mm(uy, t, gap_s=1.0, span_s=2.0) == pytest.approx(0.1)
    assert jump_uy_mm(-uy, t, gap_s=1.0, span_s=2.0) == pytest.approx(-0.1)
    ramp = 0.02 + 0.1 * np.clip((t - 3.0) / 2.0, 0, 1)          # rise over 2 s, 0.025 mm per sample
    assert peak_rate_uy_mm_s(ramp, t) == pytest.approx(0.05)
    assert jump_uy_mm(ramp, t, gap_s=2.0, span_s=1.5) == pytest.approx(0.1)
    with pytest.raises(ValueError, match="longer than the scan"):
        jump_uy_mm(uy, t, gap_s=8.0, span_s=2.0)


def test_peak_z_is_the_largest_window_sum_of_strain_changes():
    """Independent reference: uniform sampling and tau = 6 dt -> sum of the last 6 |Δε|."""
    rng = np.random.default_rng(2)
    t = np.arange(41) * 0.5
    uy = np.cumsum(rng.normal(0, 0.01, size=(3, 41)), axis=1)
    scans = Scans(np.arange(3), np.zeros(3), np.full(3, 0.5), np.tile(t, (3, 1)), np.tile(t, (3, 1)),
                  uy, uy, uy)
    f = scan_features(scans, a=2.0, tau_s=3.0, h=0.001, length_mm=4.0, gap_s=1.0, span_s=1.0)
    d = np.abs(np.diff(strain(uy, 4.0), axis=1))
    c = np.concatenate([np.zeros((3, 1)), np.cumsum(d, axis=1)], axis=1)
    windows = c[:, 6:] - c[:, :-6]
    ref = np.maximum(2.0 * np.maximum(windows.max(axis=1), c[:, 1:6].max(axis=1)) - 0.001, 0)
    np.testing.assert_allclose(f.peak_z, ref, rtol=1e-9)
    np.testing.assert_allclose(f.peak_rate_uy_mm_s, np.abs(np.diff(uy, axis=1)).max(axis=1) / 0.5)


def test_proportion_correct_exact():
    assert proportion_correct([1, 2], [3, 4]) == 1.0
    assert proportion_correct([3, 4], [1, 2]) == 0.0
    assert proportion_correct([1, 3], [2, 2]) == 0.5
    assert proportion_correct([1], [1]) == 0.5


def spreadsheet_export(path, rows, columns=COLUMNS, *, sep=";", bom=False):
    """``rows`` as a spreadsheet in a decimal-comma locale exports them: ``sep`` between
    columns, ``,`` as the decimal mark."""
    lines = [sep.join(columns)] + [sep.join(str(v).replace(".", ",") for v in row) for row in rows]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8-sig" if bom else "utf-8")
    return path


@pytest.mark.parametrize("sep, bom", [(";", False), (";", True), ("\t", False)])
def test_a_decimal_comma_export_reads_as_the_comma_file(tmp_path, sep, bom):
    plain = read_scans(write_csv(tmp_path / "plain.csv", good_rows()))
    other = read_scans(spreadsheet_export(tmp_path / "eu.csv", good_rows(), sep=sep, bom=bom))
    for name in ("scan_id", "step_mm", "speed_mm_s", "t_s", "x_mm", "ux_mm", "uy_mm", "uz_mm"):
        np.testing.assert_array_equal(getattr(other, name), getattr(plain, name), err_msg=name)
    np.testing.assert_allclose(other.uy_mm[1], [0.05, 0.06, 0.07, 0.08])     # decimals kept, not dropped


def test_a_byte_order_mark_and_semicolons_with_decimal_points_read_too(tmp_path):
    path = tmp_path / "semi.csv"
    path.write_text("\n".join([";".join(COLUMNS)] + [";".join(str(v) for v in r) for r in good_rows()]) + "\n",
                    encoding="utf-8-sig")
    np.testing.assert_array_equal(read_scans(path).uy_mm, read_scans(write_csv(tmp_path / "p.csv", good_rows())).uy_mm)


def test_a_bad_entry_in_a_decimal_comma_file_is_named(tmp_path):
    rows = good_rows()
    rows[2][6] = "abc"
    with pytest.raises(DataFileError, match="column uy_mm: missing or non-numeric value at data row 3"):
        read_scans(spreadsheet_export(tmp_path / "eu.csv", rows))


def test_a_header_read_as_one_column_says_which_separators_are_read(tmp_path):
    path = tmp_path / "spaces.csv"
    path.write_text(" ".join(COLUMNS) + "\n" + "\n".join(" ".join(str(v) for v in r) for r in good_rows()) + "\n")
    with pytest.raises(DataFileError, match=r"the header is one column, 'scan_id step_mm.*separate columns by "
                                            r"commas, semicolons or tabs"):
        read_scans(path)


@pytest.mark.parametrize("header, expected", [
    ("a,b,c", (",", ".")), ("a;b;c", (";", ",")), ("a\tb\tc", ("\t", ",")), ("abc", (",", ".")),
    ("name;note, with comma;x", (";", ",")), ("a,b;c,d", (",", ".")),
])
def test_csv_dialect_from_the_header(header, expected):
    assert csv_dialect(header) == expected


def test_scan_ids_that_start_again_on_each_plate_are_named(tmp_path):
    """A lab file numbering scans afresh per plate: both readers (the fit's and classify's)
    say that several scans share an id, with their steps, before any length check (plates
    with unequal counts would otherwise read as scans of unequal length)."""
    from feeler.calib.neuron.live.scan_csv import read_scan_records

    rows = []
    for step, n in ((0.0, 2), (0.05, 1)):                   # two scans on plate 0, one on plate 1: ids 0, 1 then 0
        for sid in range(n):
            rows += [[sid, step, 0.5, 0.5 * i, 0.25 * i, -0.01, 0.05 + step * i, 0.0] for i in range(4)]
    path = write_csv(tmp_path / "scans.csv", rows)
    words = ("column scan_id: t_s restarts 1 time(s) within scan_id 0, with steps 0, 0.05 mm: about 2 scans share "
             "this id; give every scan its own scan_id across the file")
    for read in (read_scans, read_scan_records):
        with pytest.raises(DataFileError) as info:
            read(path)
        assert str(info.value) == f"{path}: {words} (ids that start again on each plate are not unique)"
    clock = [[r[0], r[1], r[2], r[3] + 10 * k, *r[4:]] for k, r in enumerate(rows)]   # one clock for the file
    path = write_csv(tmp_path / "clock.csv", clock)
    for read in (read_scans, read_scan_records):
        with pytest.raises(DataFileError) as info:
            read(path)
        assert str(info.value) == (f"{path}: column step_mm: must be constant within each scan; scan_id 0 holds "
                                   "0, 0.05 (if these rows are several scans, give each its own scan_id)")


@pytest.mark.parametrize("col, value, words", [
    (6, "inf", "column uy_mm: inf at data row 6; values must be finite numbers"),
    (4, "-inf", "column x_mm: -inf at data row 6; values must be finite numbers"),
    (1, "inf", "column step_mm: inf at data row 6; values must be finite numbers"),
    (1, "abc", "column step_mm: missing or non-numeric value at data row 6"),
    (6, "1e300", "column uy_mm: 1e+300 at data row 6; values must lie within ±1e+12 (no measurement in these "
                 "units comes near)"),                # squared, it overflowed into numpy warnings and a traceback
])
def test_both_scan_readers_name_a_value_that_is_not_a_finite_number(tmp_path, col, value, words):
    """The fit's reader and classify's/decode's read the same file to the same one line,
    naming the file, the column and the row; classify's used to let inf through to the
    decoder ("argument strain='inf at index (0, 3)'", after "decoding 96 scans ...")."""
    from feeler.calib.neuron.live.scan_csv import read_scan_records

    rows = good_rows()
    rows[5][col] = value
    path = write_csv(tmp_path / "scans.csv", rows)
    for read in (read_scans, read_scan_records):
        with pytest.raises(DataFileError) as info:
            read(path)
        assert str(info.value) == f"{path}: {words}"


def test_classify_reads_blank_labels_as_unlabelled_scans(tmp_path):
    """A label column left blank (scans nobody labelled) is not an error for classify's
    reader: those scans carry no step; the labelled one keeps its own."""
    from feeler.calib.neuron.live.scan_csv import read_scan_records

    rows = [[*r[:1], "" if r[0] == 1 else r[1], *r[2:]] for r in good_rows()]
    records = read_scan_records(write_csv(tmp_path / "scans.csv", rows))
    assert [r.step_mm for r in records] == [0.0, None]


@pytest.mark.parametrize("names", [["touch-b", "touch-a"], ["1.2", "1.1"]])
def test_scan_ids_written_as_names_are_numbered_in_order_of_appearance(tmp_path, names):
    """Lab software names its scans ('touch-01', or '2.1' for plate 2's first touch): both
    readers number them 0, 1, ... as they first appear (not by sorting), classify's
    records keep each name, and an error names the scan as the file wrote it."""
    from feeler.calib.neuron.live.scan_csv import read_scan_records

    rows = [[names[int(r[0])], *r[1:]] for r in good_rows()]
    path = write_csv(tmp_path / "scans.csv", rows)
    numbered = read_scans(write_csv(tmp_path / "numbered.csv", good_rows()))
    scans = read_scans(path)
    np.testing.assert_array_equal(scans.scan_id, [0, 1])
    np.testing.assert_array_equal(scans.uy_mm, numbered.uy_mm)
    np.testing.assert_array_equal(scans.step_mm, numbered.step_mm)
    records = read_scan_records(path)
    assert [(r.scan_id, r.name) for r in records] == [(0, names[0]), (1, names[1])]
    assert [r.name for r in read_scan_records(tmp_path / "numbered.csv")] == [None, None]
    rows[6][3] = rows[5][3]                                                 # scan 1 repeats a time
    path = write_csv(tmp_path / "bad.csv", rows)
    for read in (read_scans, read_scan_records):
        with pytest.raises(DataFileError, match=f"not strictly increasing within scan_id '{names[1]}'"):
            read(path)
    rows = [r if k != 2 else ["", *r[1:]] for k, r in enumerate(rows)]
    with pytest.raises(DataFileError, match="column scan_id: missing value at data row 3"):
        read_scans(write_csv(tmp_path / "blank.csv", rows))


def test_a_spreadsheets_leftover_rows_and_columns_are_not_data(tmp_path):
    """Saved from Excel after rows were deleted: CRLF lines, two empty unnamed columns, and
    rows of separators only after the data. They read as the clean file (it was 'column
    scan_id: missing or non-numeric value at data row 9'); a separator row inside the data
    is still named."""
    from feeler.calib.matrix.data import read_calibration_csv
    from feeler.calib.neuron.live.scan_csv import read_scan_records

    clean = write_csv(tmp_path / "clean.csv", good_rows())
    lines = clean.read_text().splitlines()
    messy = tmp_path / "messy.csv"
    empty = "," * (len(COLUMNS) + 1)                                        # the row's fields, all empty
    messy.write_bytes(("\r\n".join([ln + ",," for ln in lines] + [empty] * 3) + "\r\n").encode())
    a, b = read_scans(clean), read_scans(messy)
    np.testing.assert_array_equal(a.uy_mm, b.uy_mm)
    np.testing.assert_array_equal(a.scan_id, b.scan_id)
    assert [r.scan_id for r in read_scan_records(messy)] == [0, 1]
    inside = tmp_path / "inside.csv"
    inside.write_text("\n".join(lines[:3] + ["," * (len(COLUMNS) - 1)] + lines[3:]) + "\n")
    with pytest.raises(DataFileError, match="column scan_id: missing or non-numeric value at data row 3"):
        read_scans(inside)
    cal = tmp_path / "calibration.csv"
    cal.write_text("point_id,ux_mm,uy_mm,uz_mm,fx_n,fy_n,fz_n,\n" + "".join(
        f"{k},0,{0.05 * (k + 1)},0,0.1,{k + 1},0.2,\n" for k in range(5)) + ",,,,,,,\n" * 2)
    assert read_calibration_csv(cal).n == 5


def test_files_joined_with_their_headers_name_the_repeated_header_line(tmp_path):
    """``cat a.csv b.csv``: every user CSV reader (scans, calibration.csv, trials) names the
    line where the header comes again, instead of a non-numeric value in some column."""
    from feeler.calib.fit import read_csv_columns
    from feeler.psydata import read_trials

    words = ("line 6 repeats the header (2 repeat(s): files joined with their headers?); delete the repeated "
             "header lines")
    scans = write_csv(tmp_path / "scans.csv", good_rows())
    lines = scans.read_text().splitlines()
    scans.write_text("\n".join(lines[:5] + lines[:5] + [" " + lines[0] + " \r"] + lines[5:]) + "\n")
    trials = tmp_path / "trials.csv"
    head = "subject,standard_um,standard_speed_mm_s,comparison_um,comparison_speed_mm_s,n_trials,n_comparison_higher"
    row = "S1,10,20,{},20,20,{}"
    trials.write_text("\n".join(["# joined", head, row.format(8, 3), row.format(9, 6), row.format(11, 14), head,
                                 row.format(12, 17), head]) + "\n")
    for read, path in ((read_scans, scans), (lambda p: read_csv_columns(p, COLUMNS), scans), (read_trials, trials)):
        with pytest.raises(DataFileError) as info:
            read(path)
        assert str(info.value) == f"{path}: {words}"
    assert read_scans(write_csv(tmp_path / "ok.csv", good_rows())).t_s.shape == (2, 4)


# --- a directory of one CSV file per scan, as lab software writes them ---------------------------------------

def _one_file_per_scan(directory, rows, *, names=None, drop_id=True):
    """Each scan of ``rows`` in its own file (``names`` per scan; scan_id column dropped)."""
    import pandas as pd

    frame = pd.DataFrame(rows, columns=COLUMNS)
    directory.mkdir(exist_ok=True)
    for k, (_, g) in enumerate(frame.groupby("scan_id", sort=True)):
        (g.drop(columns="scan_id") if drop_id else g).to_csv(directory / (names[k] if names else f"scan_{k}.csv"),
                                                             index=False)
    return directory


def _rows(n_scans, n_time=4):
    return [[s, 0.05 * (s % 2), 0.5, 0.5 * k, 0.25 * k, -0.01, 0.05 + 0.01 * k * s, 0.0]
            for s in range(n_scans) for k in range(n_time)]


def test_a_directory_of_scan_files_reads_as_one_file_of_its_scans_in_name_order(tmp_path):
    """Natural order: scan_2 before scan_10 (as a lab numbers them, without zero padding)."""
    rows = _rows(12)
    whole = read_scans(write_csv(tmp_path / "scans.csv", rows))
    per = _one_file_per_scan(tmp_path / "lab", rows)
    (per / "notes.csv").write_text("what,value\noperator,A\n")           # a CSV that is not a scan: ignored
    got = read_scans(per)
    for name in ("scan_id", "step_mm", "speed_mm_s", "t_s", "x_mm", "ux_mm", "uy_mm", "uz_mm"):
        np.testing.assert_array_equal(getattr(got, name), getattr(whole, name), err_msg=name)
    from feeler.datasets import scan_files
    assert [f.name for f in scan_files(per)][:3] == ["scan_0.csv", "scan_1.csv", "scan_2.csv"]
    assert scan_files(tmp_path) == []                              # a run directory (scans.csv) is not one


def test_scan_files_keep_their_own_ids_when_they_are_distinct(tmp_path):
    rows = _rows(3)
    own = _one_file_per_scan(tmp_path / "own", [[r[0] + 100] + r[1:] for r in rows], drop_id=False)
    assert read_scans(own).scan_id.tolist() == [100, 101, 102]
    same = tmp_path / "same"
    same.mkdir()
    for name, sid, k in (("a.csv", 0, 0), ("b.csv", 5, 1), ("c.csv", 0, 2)):      # two files say 0
        write_csv(same / name, [[sid] + r[1:] for r in rows[4 * k:4 * k + 4]])
    assert read_scans(same).scan_id.tolist() == [0, 1, 2]         # numbered in name order


def test_scan_files_are_checked_each_by_its_name(tmp_path):
    rows = _rows(3)
    rows[5][3] = 0.0                                               # scan 1's second time repeats its first
    per = _one_file_per_scan(tmp_path / "lab", rows)
    with pytest.raises(DataFileError, match=r"lab/scan_1.csv: column t_s: not strictly increasing"):
        read_scans(per)
    short = _one_file_per_scan(tmp_path / "short", _rows(3)[:-1])
    with pytest.raises(DataFileError, match=r"short: scan files have unequal lengths \[3, 4\] \(scan_2.csv has 3 "
                                            r"samples, 2 of 3 have 4\); a fit needs scans of one length"):
        read_scans(short)
    several = _one_file_per_scan(tmp_path / "several", _rows(2), drop_id=False)
    write_csv(several / "scan_9.csv", _rows(2))                    # two scans in one file of the directory
    with pytest.raises(DataFileError, match=r"scan_9.csv: holds 2 scan ids: a directory of scan files takes one "
                                            r"scan per file"):
        read_scans(several)


def test_excel_unicode_text_and_windows_1252_files_read_as_the_utf8_file(tmp_path):
    """Excel's "Unicode Text" (UTF-16 with a byte order mark, tabs, CRLF) and its "CSV" on
    Windows (Windows-1252: a "µ" or "ü" is not UTF-8; it read "cannot read: 'utf-8' codec ...")."""
    plain = read_scans(write_csv(tmp_path / "scans.csv", good_rows()))
    header = "\t".join(COLUMNS) + "\tBemerkung"
    body = ["\t".join(str(v) for v in row) + "\tPlatte für 20 µm" for row in good_rows()]
    (tmp_path / "unicode.txt.csv").write_bytes("\r\n".join([header, *body]).encode("utf-16"))
    (tmp_path / "cp1252.csv").write_bytes("\n".join(ln.replace("\t", ",") for ln in [header, *body]).encode("cp1252"))
    for name in ("unicode.txt.csv", "cp1252.csv"):
        got = read_scans(tmp_path / name)
        for col in ("scan_id", "step_mm", "t_s", "uy_mm"):
            np.testing.assert_array_equal(getattr(got, col), getattr(plain, col), err_msg=f"{name} {col}")
    (tmp_path / "broken.csv").write_bytes(b"\xff\xfe" + "\t".join(COLUMNS).encode("utf-16-le") + b"\x00")
    with pytest.raises(DataFileError, match="broken.csv: not a readable CSV"):
        read_scans(tmp_path / "broken.csv")


def test_an_empty_file_says_so(tmp_path):
    """An empty scans.csv said pandas' "not a readable CSV: No columns to parse from file"."""
    (tmp_path / "scans.csv").write_text("\n \n")
    with pytest.raises(DataFileError, match="scans.csv: empty: no header and no rows$"):
        read_scans(tmp_path / "scans.csv")


def test_a_binary_file_is_not_read_as_windows_1252_text(tmp_path):
    (tmp_path / "scans.csv").write_bytes(b"\x00\xff\xfe" + ",".join(COLUMNS).encode())
    with pytest.raises(DataFileError, match="not a readable CSV: .*a NUL byte: not a text file"):
        read_scans(tmp_path / "scans.csv")


@pytest.mark.parametrize("header, missing, hint", [
    (["scan", "t [s]", "Uy (mm)"], ["t_s", "uy_mm"], "; the header has 't [s]', 'Uy (mm)': rename them t_s, uy_mm"),
    (["Scan_ID", "T_S"], ["scan_id", "t_s"], "; the header has 'Scan_ID', 'T_S': rename them scan_id, t_s"),
    (["speed (mm/sec)"], ["speed_mm_s"], "; the header has 'speed (mm/sec)': rename it speed_mm_s"),
    (["t [ms]", "uy [um]"], ["t_s", "uy_mm"],
     "; 't [ms]' is in ms: t_s is in s (convert it); 'uy [um]' is in µm: uy_mm is in mm (convert it)"),
    (["Fy (mN)"], ["fy_n"], "; 'Fy (mN)' is in mN: fy_n is in N (convert it)"),
    (["t_ms", "uy_um", "x_mm"], ["t_s", "uy_mm"],
     "; 't_ms' is in ms: t_s is in s (convert it); 'uy_um' is in µm: uy_mm is in mm (convert it)"),
    (["participant", "comparison_um"], ["subject"], "; the header has 'participant': rename it subject"),
    (["time", "displacement"], ["t_s", "uy_mm"], ""),                  # nothing to guess from
    (["ty [s]"], ["t_s"], ""),                                         # another name, not a spelling of t
])
def test_a_missing_column_written_with_its_unit_is_named(header, missing, hint):
    from feeler.datasets import renamed_hint
    assert renamed_hint(header, missing) == hint


def test_scans_with_units_in_the_header_say_which_columns_to_rename(tmp_path):
    header = ["scan_id", "step (mm)", "speed_mm_s", "t [s]", "x_mm", "ux_mm", "Uy (mm)", "uz_mm"]
    path = write_csv(tmp_path / "scans.csv", good_rows(), header)
    with pytest.raises(DataFileError, match=r"missing column\(s\) step_mm, t_s, uy_mm; required: .*; the header has "
                                            r"'step \(mm\)', 't \[s\]', 'Uy \(mm\)': rename them step_mm, t_s, uy_mm"):
        read_scans(path)


def test_a_labs_notes_above_the_header_are_comments_not_a_parse_error(tmp_path):
    """'# sensor 12, 2026-11-20' above the header (as feeler's own trial files carry) was
    "not a readable CSV: Error tokenizing data. C error: Expected 1 fields in line 3, saw 9"
    for scans: only the readers that asked skipped '#' lines. Now every CSV reader does,
    and keeps them."""
    from feeler.datasets import read_csv_file

    plain = read_scans(write_csv(tmp_path / "scans.csv", good_rows()))
    text = (tmp_path / "scans.csv").read_text()
    noted = tmp_path / "noted.csv"
    noted.write_text("# sensor element 12, 2026-11-20\n  # operator AB\n" + text)
    got = read_scans(noted)
    for col in ("scan_id", "step_mm", "t_s", "uy_mm"):
        np.testing.assert_array_equal(getattr(got, col), getattr(plain, col))
    assert read_csv_file(noted).attrs["comments"] == ["sensor element 12, 2026-11-20", "operator AB"]
    assert "comments" not in read_csv_file(tmp_path / "scans.csv").attrs


def _shuffled(rows):
    rng = np.random.default_rng(3)
    return [rows[i] for i in rng.permutation(len(rows))]


@pytest.mark.parametrize("edit, words", [
    (lambda r: r[:8] + [r[7]] + r[8:],                  # scan 1's sample at 0.5 s written twice (data rows 8, 9)
     "column t_s: not strictly increasing within scan_id 1: t_s 0.5 twice, at data rows 8 and 9 (a sample written "
     "twice?)"),
    (lambda r: r[:8] + [r[9], r[8]] + r[10:],           # two of scan 1's rows swapped
     "column t_s: not strictly increasing within scan_id 1: t_s 1.5 at data row 9, then 1 at data row 10; sort the "
     "rows by scan_id, then t_s, or correct that time"),
    (lambda r: _shuffled(_rows(2, 12)),                 # rows shuffled: the first scan in the file's order is named
     "column t_s: not strictly increasing within scan_id 1: t_s 0.5 at data row 1, then 0 at data row 2; sort the "
     "rows by scan_id, then t_s, or correct that time"),
    # every time of scan 1 the same (an outside audit: it read as 'several scans share this id')
    (lambda r: r[:6] + [row[:3] + [0.0] + row[4:] for row in r[6:]],
     "column t_s: scan_id 1 has one time, 0 s, in all its 6 samples (data rows 7-12): t_s must rise sample after "
     "sample (a column filled with one value?)"),
    (lambda r: sorted([[0] + row[1:] for row in r], key=lambda row: row[3]),   # one id for both, sorted by time
     "column scan_id: scan_id 0 holds each of its times about 2 times: several scans share this id; give every scan "
     "its own scan_id across the file"),
])
def test_times_out_of_order_or_written_twice_are_named_with_their_rows(tmp_path, edit, words):
    """Both readers (the fit's and classify's) name a sample written twice by its data
    rows, rows out of time order by the two rows and what to do (they used to read as
    scans of unequal length, 'trim them to 6 samples', or as scans sharing an id), and a
    scan_id shared by several scans whose rows were sorted by time."""
    from feeler.calib.neuron.live.scan_csv import read_scan_records

    path = write_csv(tmp_path / "scans.csv", edit(_rows(2, 6)))
    for read in (read_scans, read_scan_records):
        with pytest.raises(DataFileError) as info:
            read(path)
        assert str(info.value).startswith(f"{path}: {words}")
        assert "unequal lengths" not in str(info.value) and "restarts" not in str(info.value)


def test_a_scan_missing_a_sample_in_its_middle_is_told_apart_from_a_short_one(tmp_path):
    """One sample missing in the middle of a scan: the line names the jump and does not
    tell the user to trim every scan; a scan cut short still gets the trim advice."""
    rows = _rows(3, 6)
    path = write_csv(tmp_path / "gap.csv", rows[:9] + rows[10:])          # scan 1 misses t = 1.5 s
    with pytest.raises(DataFileError) as info:
        read_scans(path)
    assert str(info.value) == (f"{path}: column scan_id: scans have unequal lengths [5, 6] (scan 1 has 5 samples, "
                               "2 of 3 have 6): its times jump from 1 to 2 s where its other samples lie 0.5 s apart "
                               "(a sample missing there?); a fit needs scans of one length: restore that sample or "
                               "leave the scan out (classify and decode take scans of any length)")
    path = write_csv(tmp_path / "short.csv", rows[:-1])
    with pytest.raises(DataFileError, match="trim them to 5 samples"):
        read_scans(path)


def test_an_acquisition_stopped_before_its_first_scan_says_so(tmp_path):
    """report and decode of a run interrupted during its first scan said only 'scans.csv:
    no rows' (an outside audit): a run directory's journal says it is an acquisition."""
    write_csv(tmp_path / "scans.csv", [])
    with pytest.raises(DataFileError, match=r"scans.csv: no rows$"):
        read_scans(tmp_path / "scans.csv")
    (tmp_path / "journal.jsonl").write_text('{"event": "run"}\n')
    with pytest.raises(DataFileError, match=r"no rows: no complete scan yet \(an acquisition stopped before its first "
                                            r"scan finished; `feeler acquire ... --resume` with the same --out"):
        read_scans(tmp_path / "scans.csv")
