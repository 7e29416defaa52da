"""Missing files give a report of what is there; corrupt files a one-line DataFileError."""
from __future__ import annotations

import json
import shutil

import pypdfium2 as pdfium
import pytest

from feeler.cli import main
from feeler.errors import DataFileError
from feeler.reports import build_report
from feeler.reports.discover import SPECS


def test_empty_run_lists_everything_missing(tmp_path, capsys):
    (tmp_path / "run").mkdir()
    assert main(["report", str(tmp_path / "run"), "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert f"report: {tmp_path / 'run' / 'report.html'}" in out
    assert f"sections: 0 shown, {len(SPECS)} with missing files" in out
    html = (tmp_path / "run" / "report.html").read_text(encoding="utf-8")
    for spec in SPECS:
        assert f"{spec.title}: missing {', '.join(spec.required)}".replace("&", "&amp;") in html
    assert len(pdfium.PdfDocument(tmp_path / "run" / "report.pdf")) == 2     # title page + appendix


def test_partial_run_shows_what_is_there(part_run, tmp_path):
    run = part_run("four-plates", "m4", "discriminate", "finger-route")
    (run / "four-plates" / "scans.csv").unlink()
    report = build_report(run, tmp_path / "out", pdf=False)
    keys = [s.key for s in report.inventory.present]
    assert "robot" not in keys and "fig6" not in keys and "psychometric" in keys
    missing = dict(report.inventory.missing)
    assert missing["Robot scans over the four plates (paper Figs 7–9)"] == ("four-plates/scans.csv",)
    assert "psychophysics/trials.csv" in missing["Robot and human discrimination side by side"]


FP, PSY = ("four-plates",), ("finger-route", "m4", "psychophysics")


@pytest.mark.parametrize("parts, rel, content, problem", [
    (("m1",), "m1/posterior.nc", b"\x89HDF\r\n garbage", "not a readable NetCDF posterior"),
    (("m1",), "m1/summary.csv", b"name,mean\nC,1\n", "missing columns"),
    (("classify",), "classify/classification.csv", b"\xff\xfe\x00garbage\x00", "not a readable CSV"),
    (("classify",), "classify/classification.csv", b"scan_id,step_mm,plate_mm\n0,0,0\n",
     "missing column(s) lo90_mm"),
    (("classify",), "classify/classification.csv", b"step_mm,plate_mm,lo90_mm,hi90_mm,p_0mm\nx,0,0,0,1\n",
     "column step_mm: missing or non-numeric value at data row 1"),
    (("classify",), "classify/classification.csv", b"step_mm,plate_mm,lo90_mm,hi90_mm\n0,0,0,0\n",
     "no probability columns"),
    (("m4",), "m4/thresholds.csv", b"subject,pse_um\nall,1\n", "missing column(s)"),
    (("psychophysics",), "psychophysics/trials.csv", b"subject,standard_um\nS1,oops\n", "missing column(s)"),
    (("discriminate",), "discriminate/discrimination.json", b"{not json", "not a readable JSON file"),
    (("discriminate",), "discriminate/discrimination.json", b"[1, 2]", "expected a JSON object"),
    (("discriminate",), "discriminate/discrimination.json", b'{"pairs": []}', "missing key(s) threshold_mm"),
    (FP, "robot_table.json", b'{"plates": [{"step_mm": 0}]}', "unexpected layout of the per-plate table"),
    (FP, "four-plates/scans.csv", b"scan_id,t_s\n0,0\n", "missing column(s)"),
    (PSY, "finger-route/tau_report.json", b'{"tau_median_s": -1}', "must be > 0"),
    (("benchmarks",), "benchmarks/speed.csv", b"\x00\xff\xfe", "not a readable CSV"),
])
def test_corrupt_file_is_named_in_one_line(part_run, tmp_path, parts, rel, content, problem):
    run = part_run(*parts)
    (run / rel).write_bytes(content)
    with pytest.raises(DataFileError) as info:
        build_report(run, tmp_path / "out", pdf=False)
    message = str(info.value)
    assert "\n" not in message and rel.split("/")[-1] in message and problem in message


def test_cli_corrupt_netcdf_exit_2(part_run, capsys):
    run = part_run("m4")
    (run / "m4" / "posterior.nc").write_bytes(b"not a netcdf file")
    assert main(["report", str(run), "--no-pdf", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "m4/posterior.nc" in err and err.startswith("feeler: error:")


def test_run_dir_must_be_a_directory(tmp_path, capsys):
    assert main(["report", str(tmp_path / "nowhere"), "--no-pdf"]) == 2
    assert "not a directory" in capsys.readouterr().err


def test_extra_fit_directory_is_reported(part_run, tmp_path):
    run = part_run("m1")
    shutil.copytree(run / "m1", run / "m1-student")
    (run / "m1-student" / "verdict.json").write_text(json.dumps({"ok": True, "problems": []}))
    report = build_report(run, tmp_path / "out", pdf=False)
    assert "fit:m1-student" in [s.key for s in report.inventory.present]
    assert "Fit: m1-student (m1-student/)" in report.html.read_text(encoding="utf-8")
