"""Corrupt files of a run: a one-line DataFileError naming the file, before any output."""
from __future__ import annotations

import pytest

from feeler.cli import main
from feeler.errors import DataFileError
from feeler.reports import build_report

FP, PSY = ("four-plates",), ("finger-route", "m4", "psychophysics")


@pytest.mark.parametrize("parts, rel, content, problem", [
    (("m1",), "m1/posterior.nc", b"\x89HDF\r\n garbage", "not a readable NetCDF posterior"),
    (("m1",), "m1/summary.csv", b"name,mean\nC,1\n", "missing column(s)"),
    (("m1",), "m1/verdict.json", b'{"ok": "maybe"', "not a verdict"),
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
    (FP, "four-plates/scans.csv", b"scan_id,t_s\n0,0\n", "missing column(s)"),
    (PSY, "finger-route/tau_report.json", b'{"tau_median_s": -1}', "must be > 0"),
    (("finger",), "finger/strain.csv", b"step_um,speed_mm_s,t_s,x_mm,eps_y\n5,20,0,0,0\n", "every step height"),
    (("skin-ladder",), "skin-ladder/trade.csv", b"level,mesh\nl2,x\n", "missing column(s)"),
    (("speed",), "speed/backends.csv", b"\x00\xff\xfe", "not a readable CSV"),
    (("speed",), "speed/speed.json", b'{"tables": {}}', "missing key(s) measured"),
])
def test_corrupt_file_is_named_in_one_line(part_run, tmp_path, parts, rel, content, problem):
    run = part_run(*parts)
    (run / rel).write_bytes(content)
    _refused_before_any_figure(run, tmp_path, rel.split("/")[-1], problem)


def _refused_before_any_figure(run, tmp_path, name: str, problem: str, *, error=DataFileError) -> None:
    """build_report of ``run`` stops with one line naming ``name`` and ``problem``, before
    any figure is drawn and without writing a report."""
    stages = []
    with pytest.raises(error) as info:
        build_report(run, tmp_path / "out", pdf=False, progress=stages.append)
    message = str(info.value)
    assert "\n" not in message and name in message and problem in message, message
    assert not [s for s in stages if "figure" in s], stages
    assert not (tmp_path / "out" / "report.html").exists()

# each beside the four-plates scans, whose section comes first and draws figures: the corrupt
# file's own section came later, and its error only after those figures (an outside audit)
@pytest.mark.parametrize("parts, rel, content, problem", [
    (FP + ("held-out",), "held-out/scans.csv", b"scan_id,t_s\n0,0\n", "missing column(s)"),
    (FP + ("held-out",), "held-out/scene.toml", b"[scene\nkind = 1", "not valid TOML"),
    (FP + ("m1", "sensor-calibration"), "sensor-calibration/truth.json", b"{not json", "not a readable JSON file"),
    (FP + ("m4",), "m4/thresholds.csv", b"subject,pse_um\nall,1\n", "missing column(s)"),
    (FP + ("m4",), "m4/curves/index.csv", b"subject\nS1\n", "missing column(s)"),
    (FP + ("m4",), "m4/curves/S1_10um_20mm_s_20mm_s.png", b"not a png", "not a readable PNG"),
    (FP + ("classify",), "classify/classification.csv", b"step_mm,plate_mm,lo90_mm,hi90_mm\n0,0,0,0\n",
     "no probability columns"),
    (FP + ("discriminate",), "discriminate/discrimination.json", b"{not json", "not a readable JSON file"),
    (FP + ("psychophysics",), "psychophysics/trials.csv", b"subject,standard_um\nS1,oops\n", "missing column(s)"),
    (FP + ("psychophysics",), "psychophysics/scene.toml", b"\xff\xfe garbage", "not a readable text file"),
    (FP + ("finger",), "finger/strain.csv", b"step_um,speed_mm_s,t_s,x_mm,eps_y\n5,20,0,0,0\n", "every step height"),
    (FP + ("skin-ladder",), "skin-ladder/ladder.json", b"{not json", "not a readable JSON file"),
    (FP + ("skin-ladder",), "skin-ladder/convergence.csv", b"\x00\xff\xfe", "not a readable CSV"),
    (FP + ("speed",), "speed/decoder.csv", b"\x00\xff\xfe", "not a readable CSV"),
    (FP + ("speed",), "speed/speed.json", b'{"tables": {}}', "missing key(s) measured"),
    (FP + PSY, "finger-route/tau_report.json", b'{"tau_median_s": -1}', "must be > 0"),
])
def test_every_input_is_read_before_the_first_figure(part_run, tmp_path, parts, rel, content, problem):
    """A corrupt file of any section stops the report with its one-line error before any
    figure is drawn (only the fits were read first; the others when their section came)."""
    from feeler.errors import InputError

    run = part_run(*parts)
    (run / rel).write_bytes(content)
    _refused_before_any_figure(run, tmp_path, rel, problem, error=InputError)


def test_skin_figure_tables_are_read_before_the_first_figure(part_run, tmp_path):
    """`feeler skin figures` tables (no strain histories): read with the rest, before any figure."""
    run = part_run(*FP)
    (run / "skin-figures").mkdir()
    (run / "skin-figures" / "fig5_peaks.csv").write_text("step_um,speed_mm_s,peak_z_norm\n1,20,0.5\n2,20,1\n",
                                                         encoding="utf-8")
    (run / "skin-figures" / "fig6_accepted.csv").write_text("tau_s,step_um\n0.1,1\n", encoding="utf-8")
    stages = []
    with pytest.raises(DataFileError, match=r"fig6_accepted\.csv: missing column\(s\) speed_mm_s, accepted_um"):
        build_report(run, tmp_path / "out", pdf=False, progress=stages.append)
    assert not [s for s in stages if "figure" in s], stages


@pytest.mark.parametrize("where", ["discrimination.json", "threshold_curve.csv"])
def test_a_threshold_curve_without_its_columns_is_named(part_run, tmp_path, where):
    """The curve the threshold was read from, as discriminate records it in its JSON, or in
    threshold_curve.csv beside an older JSON without it: either without its columns is named."""
    import json

    run = part_run("discriminate")
    path = run / "discriminate" / "discrimination.json"
    obj = json.loads(path.read_text(encoding="utf-8"))
    bad = {"delta_mm": [0.0], "pc": [0.5]}
    if where == "discrimination.json":
        obj["curve"] = bad
    else:
        del obj["curve"]
        (run / "discriminate" / where).write_text("delta_mm,pc\n0,0.5\n", encoding="utf-8")
    path.write_text(json.dumps(obj), encoding="utf-8")
    with pytest.raises(DataFileError) as info:
        build_report(run, tmp_path / "out", pdf=False)
    message = str(info.value)
    assert "\n" not in message and where in message and "a threshold curve needs" in message


def test_cli_corrupt_netcdf_exit_2(part_run, capsys):
    run = part_run("m4")
    (run / "m4" / "posterior.nc").write_bytes(b"not a netcdf file")
    assert main(["report", str(run), "--no-pdf", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "m4/posterior.nc" in err[0] and err[0].startswith("feeler: error:")


def test_run_dir_must_be_a_directory(tmp_path, capsys):
    assert main(["report", str(tmp_path / "nowhere"), "--no-pdf"]) == 2
    assert "not a directory" in capsys.readouterr().err


def test_finger_histories_need_their_scene(part_run, tmp_path):
    run = part_run("finger")
    (run / "finger" / "scene.toml").unlink()
    with pytest.raises(DataFileError, match=r"finger/scene\.toml: missing; the finger's strain histories need"):
        build_report(run, tmp_path / "out", pdf=False)


def test_a_fit_cut_short_is_named_before_any_figure_is_drawn(tmp_path):
    """A truncated m1/summary.csv gave a KeyError traceback, a truncated m2 one a two-row
    table; and a corrupt fit was found only when its section came, after seconds of the
    other sections' figures. Every fit is now read first."""
    from pathlib import Path

    import numpy as np

    from feeler.calib.fit import make_result, posterior_from_draws

    scene = tmp_path / "small.toml"
    shipped = Path(__file__).resolve().parents[2] / "datasets-synthetic" / "four-plates.toml"
    scene.write_text(shipped.read_text(encoding="utf-8").replace("scans_per_plate = 24", "scans_per_plate = 3"),
                     encoding="utf-8")
    run = tmp_path / "run"
    assert main(["simulate", str(scene), "--out", str(run / "four-plates"), "--no-progress"]) == 0
    rng = np.random.default_rng(3)
    fit = make_result(posterior_from_draws({"C": rng.normal(0.2, 0.01, size=(4, 500, 3, 3))},
                                           dims={"C": ["disp_axis", "force_axis"]}),
                      backend="exact", priors={}, seconds=0.1)
    fit.save(run / "m1")
    summary = run / "m1" / "summary.csv"
    summary.write_bytes(summary.read_bytes()[:300])
    stages = []
    with pytest.raises(DataFileError) as info:
        build_report(run, tmp_path / "out", pdf=False, progress=stages.append)
    message = str(info.value)
    assert "\n" not in message and "m1/summary.csv: no row for C[0,1]" in message
    assert not [s for s in stages if "figure" in s], stages
    assert not (tmp_path / "out" / "report.html").exists()


# a field of a JSON file the report reads, hand-edited to another shape: each gave a traceback
# (AttributeError, TypeError, ValueError, matplotlib's "'xerr' must not contain negative values")
@pytest.mark.parametrize("parts, rel, path, value, problem", [
    (("discriminate",), "discriminate/discrimination.json", ("pairs",), 3, "pairs holds 3; expected a list"),
    (("discriminate",), "discriminate/discrimination.json", ("pairs", 0, "pc"), "abc", "pairs[0].pc holds 'abc'"),
    (("discriminate",), "discriminate/discrimination.json", ("threshold_mm",), [1], "threshold_mm holds [1]"),
    (("discriminate",), "discriminate/discrimination.json", ("threshold_mm", "mean"), "abc",
     "threshold_mm.mean holds 'abc'; expected a number or a bound"),
    (("discriminate",), "discriminate/discrimination.json", ("threshold_mm", "found"), "abc",
     "threshold_mm.found holds 'abc'; expected the fraction of draws"),
    (("discriminate",), "discriminate/discrimination.json", ("notes",), 3, "notes holds 3; expected a list of strings"),
    (("discriminate",), "discriminate/discrimination.json", ("curve",), 3, "curve holds 3"),
    (("discriminate",), "discriminate/discrimination.json", ("curve",), {"delta_mm": [0, 1], "pc": [0.5]},
     "curve: not a table"),
    (("m1", "sensor-calibration"), "sensor-calibration/truth.json", ("scene",), 3, "scene holds int 3; expected an object"),
    (("m1", "sensor-calibration"), "sensor-calibration/truth.json", ("scene", "sensor", "c_mm_per_n"), [1, 2],
     "scene.sensor.c_mm_per_n holds [1, 2]; expected the 3x3 compliance matrix"),
    (("speed",), "speed/speed.json", ("tables",), 3, "tables holds 3; expected an object"),
    (("speed",), "speed/speed.json", ("tables",), ["backends"], "tables holds ['backends']; expected an object"),
    (("speed",), "speed/speed.json", ("measured",), 3, "measured holds 3; expected text"),
    (PSY, "finger-route/tau_report.json", ("tau_median_s",), "abc", "tau_median_s = 'abc' must be > 0"),
    (PSY, "finger-route/tau_report.json", ("p_tau_le_300ms",), 2, "p_tau_le_300ms = 2 must be a probability"),
    (PSY, "finger-route/tau_report.json", ("tau_eti95_s",), "abc", "tau_eti95_s = 'abc' must be two numbers"),
])
def test_a_json_field_of_another_shape_is_named_in_one_line(part_run, tmp_path, parts, rel, path, value, problem):
    import json

    run = part_run(*parts)
    obj = json.loads((run / rel).read_text(encoding="utf-8"))
    node = obj
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    (run / rel).write_text(json.dumps(obj), encoding="utf-8")
    _refused_before_any_figure(run, tmp_path, rel.split("/")[-1], problem)


def test_a_threshold_given_as_a_bare_number_is_shown(part_run, tmp_path):
    """threshold_mm may be a bare number (the reader takes one); its Weber fraction's object
    then has no "found" to borrow (an AttributeError traceback)."""
    import json

    run = part_run("discriminate")
    path = run / "discriminate" / "discrimination.json"
    obj = json.loads(path.read_text(encoding="utf-8"))
    obj["threshold_mm"] = 0.0045
    path.write_text(json.dumps(obj), encoding="utf-8")
    build_report(run, tmp_path / "out", pdf=False)
    assert "4.5" in (tmp_path / "out" / "report.html").read_text(encoding="utf-8")


def test_an_estimate_outside_its_interval_is_drawn(part_run, tmp_path):
    """A mean may lie outside its equal-tailed or bootstrap interval; the error bar then ends
    at the mean on that side (matplotlib raised "'xerr' must not contain negative values")."""
    import json

    from feeler.reports.model import error_span

    assert error_span([2.0, 1.0], [1.0, 1.5], [3.0, 2.0]).tolist() == [[1.0, 0.0], [1.0, 1.0]]
    run = part_run("discriminate")
    path = run / "discriminate" / "discrimination.json"
    obj = json.loads(path.read_text(encoding="utf-8"))
    obj["threshold_mm"]["lo95"] = obj["threshold_mm"]["mean"] * 1.1
    path.write_text(json.dumps(obj), encoding="utf-8")
    build_report(run, tmp_path / "out", pdf=False)
    assert (tmp_path / "out" / "report.html").is_file()
