"""`feeler calibrate sensors`: many elements at once, identical on dask and serially."""
import re
from pathlib import Path

import pandas as pd
import pytest

import feeler.calib.matrix as matrix
from feeler.cli import main
from feeler.errors import DataFileError

SCENE = Path(__file__).resolve().parents[2] / "datasets-synthetic" / "sensor-calibration.toml"


@pytest.fixture(scope="module")
def elements(tmp_path_factory):
    root = tmp_path_factory.mktemp("elements")
    paths = []
    for i in (1, 2):
        scene = root / f"s{i}.toml"
        scene.write_text(re.sub(r"(?m)^seed = (\d+)", rf"seed = {i}\1", SCENE.read_text(), count=1))
        assert main(["simulate", str(scene), "--out", str(root / f"elem{i}")]) == 0
        paths.append(str(root / f"elem{i}"))
    return paths


def test_local_cluster_equals_serial(elements, tmp_path, capfd):
    assert main(["calibrate", "sensors", *elements, "--out", str(tmp_path / "serial"),
                 "--scheduler", "serial", "--no-progress"]) == 0
    assert main(["calibrate", "sensors", *elements, "--out", str(tmp_path / "dask"), "--no-progress"]) == 0
    out, err = capfd.readouterr()                # file descriptors: the worker processes' stderr too
    assert out.count(" ok ") >= 4
    assert err == ""                             # no dask log line without -v, from here or a worker
    for name in ("elem1", "elem2"):
        a = pd.read_csv(tmp_path / "serial" / name / "summary.csv")
        b = pd.read_csv(tmp_path / "dask" / name / "summary.csv")
        pd.testing.assert_frame_equal(a, b)
    # the two elements are different sensors: their posteriors differ
    a = pd.read_csv(tmp_path / "serial" / "elem1" / "summary.csv")
    b = pd.read_csv(tmp_path / "serial" / "elem2" / "summary.csv")
    assert not a["mean"].equals(b["mean"])


def test_duplicate_names_and_overwrite_are_refused(elements, tmp_path, capsys):
    assert main(["calibrate", "sensors", elements[0], elements[0], "--out", str(tmp_path / "x"),
                 "--scheduler", "serial"]) == 2
    assert "distinct names" in capsys.readouterr().err
    assert main(["calibrate", "sensors", elements[0], "--out", str(tmp_path / "y"), "--scheduler", "serial",
                 "--no-progress"]) == 0
    assert main(["calibrate", "sensors", elements[0], "--out", str(tmp_path / "y"), "--scheduler", "serial"]) == 2
    assert "--force" in capsys.readouterr().err


def test_a_failed_element_says_why_below_the_table(elements, tmp_path, capsys):
    """One element with its fx_n and fy_n columns exchanged: the table said FAILED and no
    more; now its first problem and where the rest are follow the table (exit 1)."""
    bad = tmp_path / "swapped"
    bad.mkdir()
    for f in Path(elements[1]).iterdir():
        (bad / f.name).write_bytes(f.read_bytes())
    table = pd.read_csv(bad / "calibration.csv", comment="#")
    table[["fx_n", "fy_n"]] = table[["fy_n", "fx_n"]].to_numpy()
    table.to_csv(bad / "calibration.csv", index=False)
    assert main(["calibrate", "sensors", elements[0], str(bad), "--out", str(tmp_path / "z"), "--scheduler", "serial",
                 "--no-progress"]) == 1
    lines = capsys.readouterr().out.splitlines()
    why = [ln for ln in lines if ln.startswith("swapped: ")]
    assert len(why) == 1 and "with axes x and y exchanged" in why[0]
    assert why[0].endswith(f"{tmp_path / 'z' / 'swapped' / 'verdict.json'})")
    assert not any(ln.startswith("elem1: ") for ln in lines)


def test_an_element_with_an_unidentified_design_prints_no_raw_warning(elements, tmp_path, capfd):
    """An element whose stage moved along y only: on the LocalCluster its design warning
    reached stderr from the worker process raw, with the source path and line; the same
    news is the element's verdict, printed below the table."""
    flat = tmp_path / "y-only"
    flat.mkdir()
    for f in Path(elements[1]).iterdir():
        (flat / f.name).write_bytes(f.read_bytes())
    table = pd.read_csv(flat / "calibration.csv", comment="#")
    table[(table.ux_mm == 0) & (table.uz_mm == 0)].to_csv(flat / "calibration.csv", index=False)
    assert main(["calibrate", "sensors", elements[0], str(flat), "--out", str(tmp_path / "o"), "--no-progress"]) == 1
    out, err = capfd.readouterr()
    assert err == "", err
    (why,) = [ln for ln in out.splitlines() if ln.startswith("y-only: ")]
    assert "the data do not pin K along the displacement direction" in why


# A bad dataset among good ones (an outside audit):
# The audit's run reported 'elements: 3/3 done', then the bad calibration.csv's error, and
# left OUT empty: the good posteriors were lost. Now every dataset is read and its prior built
# before the first fit, and an element that still raises during its fit no longer takes the
# finished ones with it.


def _copy(src, dst: Path, *, files=("calibration.csv", "scene.toml")) -> Path:
    dst.mkdir()
    for name in files:
        (dst / name).write_bytes((Path(src) / name).read_bytes())
    return dst


@pytest.fixture
def fits(monkeypatch):
    """Counts the fits started (the serial scheduler runs them in this process)."""
    calls = []
    real = matrix.fit_matrix

    def counted(*a, **kw):
        calls.append(1)
        return real(*a, **kw)

    monkeypatch.setattr(matrix, "fit_matrix", counted)
    return calls


def _errors(err: str) -> list[str]:
    """stderr without the command's first status line ('feeler calibrate sensors: ...', a terminal's)."""
    return [ln for ln in err.splitlines() if not ln.startswith("feeler calibrate sensors: ")]


def _bad_copy(src, dst: Path) -> Path:
    """The audit's sc_bad: fx_n in row 4 set to 'oops'."""
    bad = _copy(src, dst)
    table = pd.read_csv(bad / "calibration.csv", comment="#", dtype=str)
    table.loc[3, "fx_n"] = "oops"
    table.to_csv(bad / "calibration.csv", index=False)
    return bad


@pytest.mark.parametrize("scheduler", [[], ["--scheduler", "serial"]], ids=["local-cluster", "serial"])
def test_a_bad_dataset_among_good_ones_is_refused_before_any_fit(elements, tmp_path, capsys, fits, scheduler):
    """The audit's command: before, 'elements: 3/3 done' (serial: 1/3) and then the error, with
    nothing written; now the error comes before any fit starts (no cluster either)."""
    bad = _bad_copy(elements[1], tmp_path / "sc_bad")
    out = tmp_path / "out"
    assert main(["calibrate", "sensors", elements[0], str(bad), elements[1], "--out", str(out), *scheduler,
                 "--progress"]) == 2
    err = capsys.readouterr().err
    assert _errors(err) == [f"feeler: error: {bad / 'calibration.csv'}: column fx_n, row 4: 'oops' is not a finite number"]
    assert "done" not in err
    assert fits == []
    assert not out.exists() or not any(out.iterdir())


def test_every_bad_dataset_is_found_before_any_fit(elements, tmp_path, capsys, fits):
    """A bad CSV, a missing path and a dataset without scene.toml (this command has no --c0):
    the first in full, the others counted and named, in one line. Before, the first fit ran,
    and a dataset without scene.toml was 'argument --c0: ... give --c0', an option this
    command does not have, naming no dataset."""
    bad = _bad_copy(elements[1], tmp_path / "sc_bad")
    missing = tmp_path / "nope"
    no_scene = _copy(elements[1], tmp_path / "no_scene", files=("calibration.csv",))
    assert main(["calibrate", "sensors", elements[0], str(no_scene), "--out", str(tmp_path / "a"),
                 "--scheduler", "serial", "--no-progress"]) == 2
    (line,) = _errors(capsys.readouterr().err)
    assert line.startswith(f"feeler: error: {no_scene / 'scene.toml'}: no such file: ") and "nominal C0" in line
    assert main(["calibrate", "sensors", elements[0], str(bad), str(missing), str(no_scene), elements[1],
                 "--out", str(tmp_path / "b"), "--scheduler", "serial", "--no-progress"]) == 2
    (line,) = _errors(capsys.readouterr().err)
    assert line.startswith(f"feeler: error: {bad / 'calibration.csv'}: column fx_n, row 4: 'oops'")
    assert line.endswith(f"(and 2 more bad DATASETs: {missing}, {no_scene}; nothing was fitted)")
    assert fits == []


def _second_fit_raises(monkeypatch, exc):
    """Make the second element's fit raise ``exc``; returns the real fit_matrix."""
    calls, real = [], matrix.fit_matrix

    def second_raises(*a, **kw):
        calls.append(1)
        if len(calls) == 2:
            raise exc
        return real(*a, **kw)

    monkeypatch.setattr(matrix, "fit_matrix", second_raises)
    return real


@pytest.mark.parametrize("exc, status, kind", [(RuntimeError("a bug"), 1, "failed: element elem2: RuntimeError: a bug"),
                                               (DataFileError("x.csv", "changed"), 2, "error: element elem2: x.csv: "
                                                                                      "changed")],
                         ids=["bug", "bad-input"])
def test_an_element_that_raises_keeps_the_finished_ones(elements, tmp_path, capsys, monkeypatch, exc, status, kind):
    """Defence in depth: an element whose fit raises (not a failed verdict) after the checks
    passed. Before, the exception left OUT empty (or a traceback); now the other elements are
    written, the failing one is named in one line and the exit status is not 0."""
    real = _second_fit_raises(monkeypatch, exc)
    third = _copy(elements[0], tmp_path / "elem3")
    out = tmp_path / "out"
    assert main(["calibrate", "sensors", elements[0], elements[1], str(third), "--out", str(out),
                 "--scheduler", "serial", "--no-progress"]) == status
    std = capsys.readouterr()
    for name in ("elem1", "elem3"):
        assert {p.name for p in (out / name).iterdir()} >= {"posterior.nc", "summary.csv", "verdict.json"}
    assert not (out / "elem2").exists()
    assert _errors(std.err) == [f"feeler: {kind} (not fitted; nothing written for it)"]
    assert re.search(r"(?m)^elem2 +ERROR ", std.out) and f"wrote 2 posteriors under {out}" in std.out
    # the finished ones are those a run without the failure computes (element i, seed SEED + i)
    monkeypatch.setattr(matrix, "fit_matrix", real)
    assert main(["calibrate", "sensors", elements[0], elements[1], str(third), "--out", str(tmp_path / "ref"),
                 "--scheduler", "serial", "--no-progress"]) == 0
    for name in ("elem1", "elem3"):
        pd.testing.assert_frame_equal(pd.read_csv(out / name / "summary.csv"),
                                      pd.read_csv(tmp_path / "ref" / name / "summary.csv"))


def test_a_ctrl_c_mid_run_keeps_the_elements_already_finished(elements, tmp_path, capsys, monkeypatch):
    """Results were written only after the last element: a Ctrl-C (or a dask worker that
    died, which map_seeds raises the same way) lost every finished posterior. Each is now
    written as it finishes; the interrupted run says which it kept."""
    _second_fit_raises(monkeypatch, KeyboardInterrupt)
    out = tmp_path / "out"
    assert main(["calibrate", "sensors", elements[0], elements[1], "--out", str(out), "--scheduler", "serial",
                 "--no-progress"]) == 130
    err = capsys.readouterr().err
    assert f"kept 1 finished posterior(s) under {out}: elem1" in err and "feeler: interrupted" in err
    assert {p.name for p in (out / "elem1").iterdir()} >= {"posterior.nc", "summary.csv", "verdict.json"}
    assert not (out / "elem2").exists()


def test_resume_after_a_ctrl_c_fits_only_what_is_missing(elements, tmp_path, capsys, monkeypatch):
    """An audit: a Ctrl-C during a save left an element with posterior.nc alone, and the
    only way on was --force, refitting every element. An element without verdict.json (written
    last) is now an interrupted save, and --resume keeps the complete ones, fitting the rest
    to what one uninterrupted run writes."""
    real = _second_fit_raises(monkeypatch, KeyboardInterrupt)
    out = tmp_path / "out"
    assert main(["calibrate", "sensors", *elements, "--out", str(out), "--scheduler", "serial",
                 "--no-progress"]) == 130
    assert "run the same command with --resume to fit the others" in capsys.readouterr().err
    (out / "elem2").mkdir()
    (out / "elem2" / "posterior.nc").write_bytes(b"cut short")               # a save cut after its first file
    monkeypatch.setattr(matrix, "fit_matrix", real)
    assert main(["calibrate", "sensors", *elements, "--out", str(out), "--scheduler", "serial"]) == 2
    err = capsys.readouterr().err
    assert "elem1/verdict.json: already exists; pass --resume to fit only the elements not yet written" in err
    before = (out / "elem1" / "posterior.nc").stat().st_mtime_ns
    assert main(["calibrate", "sensors", *elements, "--out", str(out), "--scheduler", "serial", "--no-progress",
                 "--resume"]) == 0
    std = capsys.readouterr()
    assert "--resume: 1 of 2 element(s) already written" in std.err
    assert f"wrote 1 posterior under {out} (1 kept from the earlier run)" in std.out       # not "wrote 2", nor "1 posteriors"
    assert re.search(r"(?m)^elem1 +ok ", std.out) and re.search(r"(?m)^elem2 +ok ", std.out)
    assert (out / "elem1" / "posterior.nc").stat().st_mtime_ns == before                  # kept, not refitted
    assert main(["calibrate", "sensors", *elements, "--out", str(tmp_path / "ref"), "--scheduler", "serial",
                 "--no-progress"]) == 0
    for name in ("elem1", "elem2"):
        pd.testing.assert_frame_equal(pd.read_csv(out / name / "summary.csv"),
                                      pd.read_csv(tmp_path / "ref" / name / "summary.csv"))
    assert main(["calibrate", "sensors", *elements, "--out", str(out), "--resume", "--force"]) == 2


def test_a_calibration_csv_given_for_its_directory_names_the_element_by_it(elements, tmp_path, capsys):
    """`calibrate sensors DIR/calibration.csv` wrote OUT/calibration.csv/ (a directory named
    like a file); the element is its dataset directory, as when the directory is given."""
    out = tmp_path / "out"
    assert main(["calibrate", "sensors", str(Path(elements[0]) / "calibration.csv"), elements[1], "--out", str(out),
                 "--scheduler", "serial", "--no-progress"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["elem1", "elem2"]
    assert re.search(r"(?m)^elem1 +ok ", capsys.readouterr().out)
