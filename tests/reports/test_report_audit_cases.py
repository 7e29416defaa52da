"""Cases from an outside audit of `feeler report` (audit 2, F1, F3 and F4).

F1: a failed fit whose draws are all NaN crashed the report (raw numpy warnings, then a
traceback from ax.hist), losing the good parts beside it. F4: the thresholds of a failed
M4 fit were tabulated and drawn as results in "Robot and human discrimination". F3: the
outputs of decode and validate sbc, a lone posterior.nc and an empty directory were
passed over in silence (exit 0, "holds: 0 part(s)").
"""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from feeler.cli import main

NO_FINITE = "no finite draws: the fit failed, see its verdict"
FAILED_FIT = "from a failed fit: see its verdict"


def _fail(fit_dir, problem: str) -> None:
    (fit_dir / "verdict.json").write_text(json.dumps({"ok": False, "problems": [problem]}), encoding="utf-8")


def _undefined(fit_dir, names=("a", "h")) -> None:
    """Make ``names`` of a fit all NaN (as a neuron fit of one plate leaves them) and fail it."""
    import pandas as pd
    import xarray as xr

    with xr.open_datatree(fit_dir / "posterior.nc", engine="h5netcdf") as src:
        tree = src.load()
    ds = tree["posterior"].to_dataset()
    for name in names:
        ds[name] = ds[name] * np.nan
    tree["posterior"] = xr.DataTree(ds)
    (fit_dir / "posterior.nc").unlink()
    tree.to_netcdf(fit_dir / "posterior.nc", engine="h5netcdf")
    summary = pd.read_csv(fit_dir / "summary.csv")
    summary.loc[summary["name"].isin(names), summary.columns[1:]] = np.nan
    summary.to_csv(fit_dir / "summary.csv", index=False)
    _fail(fit_dir, f"{', '.join(names)}: no finite posterior draws (not defined by these data)")


def _section(html: str, title: str) -> str:
    start = html.index(f"<h2>{title}")
    end = html.find("<h2>", start + 4)
    return html[start:end if end > 0 else None]


# F1 ---------------------------------------------------------------------------------

@pytest.mark.parametrize("per_chain", [False, True])
def test_draws_of_one_value_are_a_line_not_a_crash(per_chain):
    """Audit 3: a neuron fit of two plates pins both plate means (their draws spread by
    3e-17) and a snap offset of exactly 0. numpy raised 'Too many bins for data range' and
    `feeler demo`'s report ended in a traceback; a zero spread by rounding drew ticks
    1e-17 apart ('0.000000000000000000' twice)."""
    from feeler.reports.fit_plots import _marginals

    rng = np.random.default_rng(3)
    draws = {"a": rng.normal(3.3, 0.04, (2, 400)), "plate_mean_mm[0]": rng.normal(0.0, 1e-17, (2, 400)),
             "plate_mean_mm[1]": 0.1 + rng.normal(0.0, 2e-17, (2, 400)), "plate_snap_mm[0]": np.zeros((2, 400))}
    fig = _marginals(draws, list(draws), {}, per_chain=per_chain, title="Marginal posteriors", src=("posterior.nc",))
    assert fig.problems == ()


def test_split_finite_names_entries_without_a_finite_draw():
    from feeler.reports.fit_plots import split_finite

    nan = np.full((2, 3), np.nan)
    kept, empty = split_finite({"a": nan, "b": np.ones((2, 3)), "c": np.array([[np.nan, 1.0, np.inf]]),
                                "d": np.full((1, 2), np.inf)})
    assert list(kept) == ["b", "c"] and empty == ["a", "d"]


def test_a_failed_fit_without_finite_draws_beside_good_parts_is_reported(part_run, tmp_path, capsys):
    """The audit's fit_1p beside good parts: exit 1 with a traceback and no report. Now the
    undefined parameters are named in words, no numpy warning leaks, the rest is reported."""
    run = part_run("four-plates", "m2")
    shutil.copytree(run / "m2", run / "m2-failed")
    _undefined(run / "m2-failed")
    assert main(["report", str(run), "--no-pdf", "--out", str(tmp_path / "out")]) == 0
    cap = capsys.readouterr()
    assert "warning" not in cap.err and "Traceback" not in cap.err and "All-NaN" not in cap.err
    assert "FAILED calibration shown first: M2: neuron (a, τ, h) and decoder noise (m2-failed/)" in cap.out
    html = (tmp_path / "out" / "report.html").read_text(encoding="utf-8")
    failed = _section(html, "FAILED — M2: neuron (a, τ, h) and decoder noise (m2-failed/)")
    assert f"a (mm per unit strain), h (mm): {NO_FINITE}." in failed
    assert "Marginal posteriors" in failed                        # τ, σ, ... still drawn
    assert "<h2>Robot scans (simulated, four-plates/)" in html
    assert NO_FINITE not in _section(html, "M2: neuron (a, τ, h) and decoder noise (m2/)")


# F4 ---------------------------------------------------------------------------------

def test_thresholds_of_a_failed_m4_fit_are_marked_in_the_comparison(part_run, tmp_path, capsys):
    """The audit's levels-in-mm fit: DT 0.000915 µm [0.000703, 0.00119] tabulated and drawn
    in the comparison section with no failed mark."""
    run = part_run("m4")
    assert main(["report", str(run), "--no-pdf", "--no-progress", "--out", str(tmp_path / "ok")]) == 0
    good = _section((tmp_path / "ok" / "report.html").read_text(encoding="utf-8"), "Robot and human discrimination")
    assert FAILED_FIT not in good and 'class="failed"' not in good
    assert "Robot and human psychometric functions on one axis" in good
    _fail(run / "m4", "heights: the tested levels are below fingertip step heights: were they given in mm?")
    assert main(["report", str(run), "--no-pdf", "--no-progress", "--out", str(tmp_path / "bad")]) == 0
    capsys.readouterr()
    bad = _section((tmp_path / "bad" / "report.html").read_text(encoding="utf-8"), "Robot and human discrimination")
    assert "The human thresholds come from the M4 fit in m4/, which FAILED its verdict" in bad
    rows = bad[bad.index("<tbody>"):bad.index("</tbody>")].split("<tr")[1:]
    assert rows and all(r.startswith(' class="failed"') and FAILED_FIT in r for r in rows)
    assert "Robot and human psychometric functions on one axis" not in bad         # its curves: not drawn


def test_the_robot_threshold_of_a_failed_m2_fit_is_marked_in_the_comparison(part_run, tmp_path, capsys):
    run = part_run("m2", "discriminate")
    _fail(run / "m2", "a: R-hat 1.2 > 1.01")
    assert main(["report", str(run), "--no-pdf", "--no-progress", "--out", str(tmp_path / "out")]) == 0
    capsys.readouterr()
    html = (tmp_path / "out" / "report.html").read_text(encoding="utf-8")
    sec = _section(html, "Robot and human discrimination")
    assert "The robot&#39;s threshold comes from the M2 fit in m2/, which FAILED its verdict" in sec
    assert f'<tr class="failed"><td>robot — {FAILED_FIT}</td>' in sec
    assert f"pairs of plates ({FAILED_FIT})" in sec


def test_the_weber_claim_compares_nothing_from_a_failed_fit(part_run, tmp_path):
    from feeler.reports import discover
    from feeler.reports.claims_human import claim_weber

    run = part_run("m2", "discriminate", "m4", "psychophysics")
    assert claim_weber(discover(run)).mark == "finding"
    _fail(run / "m4", "heights: were they given in mm?")
    claim = claim_weber(discover(run))
    assert claim.mark == "inconclusive" and "not compared: the human's M4 fit FAILED its verdict" in claim.run


# F3 ---------------------------------------------------------------------------------

@pytest.mark.parametrize("files, named", [
    ({"decisions.csv": "scan_id,decided_mm\n0,0.1\n"}, "decisions.csv (decode output)"),
    ({"ranks.csv": "dataset,a\n0,3\n", "sbc.csv": "name,chi2_p,ecdf_p\na,0.5,0.5\n"},
     "ranks.csv (validate sbc output), sbc.csv (validate sbc output)"),
    ({"posterior.nc": None}, "posterior.nc (a fit's file without its verdict.json)"),
    ({}, "it holds no files"),
])
def test_a_directory_with_nothing_to_show_is_a_one_line_error(run_dir, tmp_path, capsys, files, named):
    """Each gave exit 0 and "holds: 0 part(s)" (and a 2-page PDF of "not in this run")."""
    run = tmp_path / "run"
    run.mkdir()
    for name, text in files.items():
        if text is None:
            shutil.copyfile(run_dir / "m2" / name, run / name)
        else:
            (run / name).write_text(text, encoding="utf-8")
    assert main(["report", str(run), "--no-progress"]) == 2
    cap = capsys.readouterr()
    err = cap.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"feeler: error: {run}: nothing the report can show")
    assert named in err[0] and "`feeler report` reads scans.csv" in err[0] and "posterior.nc with summary.csv" in err[0]
    assert cap.out == "" and not any(run.glob("report*"))


def test_files_the_report_does_not_read_are_named(part_run, tmp_path, capsys):
    """A decode's decisions.csv inside a simulated run was never mentioned."""
    run = part_run("four-plates")
    (run / "four-plates" / "decisions.csv").write_text("scan_id,decided_mm\n0,0.1\n", encoding="utf-8")
    (run / "sbc").mkdir()
    (run / "sbc" / "sbc.csv").write_text("name,chi2_p,ecdf_p\na,0.5,0.5\n", encoding="utf-8")
    assert main(["report", str(run), "--no-pdf", "--no-progress", "--out", str(tmp_path / "out")]) == 0
    cap = capsys.readouterr()
    assert cap.err == ("not reported: four-plates/decisions.csv (decode output), "
                       "sbc/sbc.csv (validate sbc output)\n")
    html = (tmp_path / "out" / "report.html").read_text(encoding="utf-8")
    assert ("Not reported (the report does not read them): four-plates/decisions.csv (decode output), "
            "sbc/sbc.csv (validate sbc output).") in html


def test_no_pdf_beside_an_earlier_reports_pdf_says_it_is_not_this_ones(part_run, tmp_path, capsys):
    """report --no-pdf into a directory holding an earlier report.pdf left that PDF beside the
    new HTML without a word (a fixer helper noticed). A note says whose it is."""
    run = part_run("m4")
    out = tmp_path / "out"
    out.mkdir()
    (out / "report.pdf").write_bytes(b"%PDF-1.7 an earlier report")
    assert main(["report", str(run), "--no-pdf", "--no-progress", "--out", str(out)]) == 0
    assert (f"note: {out / 'report.pdf'} is an earlier report's, not this one's (--no-pdf); run without --no-pdf "
            "to replace it, or remove it") in capsys.readouterr().out
    assert main(["report", str(run), "--no-pdf", "--no-progress", "--out", str(tmp_path / "clean")]) == 0
    assert "earlier report" not in capsys.readouterr().out
