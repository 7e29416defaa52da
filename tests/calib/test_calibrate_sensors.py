"""`feeler calibrate sensors`: many elements at once, identical on dask and serially."""
import re
from pathlib import Path

import pandas as pd
import pytest

from feeler.cli import main

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
