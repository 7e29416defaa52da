"""`feeler report DIR` on any run directory: one fit, one simulation, an acquisition, a
skin study, human data alone, a mix under other names, nothing; what the command says
and its progress."""
from __future__ import annotations

import base64
import json
import os
import shutil
import sys

import pytest

from feeler.cli import main
from feeler.reports import build_report, discover
from tests.cli._run import in_a_pty


def _sections(report) -> list[str]:
    return [s.key for s in report.inventory.present]


def test_a_single_fit_directory(run_dir, tmp_path):
    fit = shutil.copytree(run_dir / "m1", tmp_path / "m1")
    report = build_report(fit, tmp_path / "out", pdf=False)
    assert _sections(report) == ["fit:"] and report.inventory.parts[0].model == "m1"
    html = report.html.read_text(encoding="utf-8")
    assert "M1: sensor force→displacement matrix (./)" in html and "Source: posterior.nc" in html
    needs = {m.title: m.needs for m in report.inventory.missing}
    assert (f"`feeler calibrate neuron {tmp_path}/four-plates --out {tmp_path}/m2`"        # beside the fit
            in needs["M2: neuron (a, τ, h) and decoder noise"])
    assert all(f["layout_problems"] == [] for f in report.figures) and len(report.figures) == 3


def _commands(needs: str) -> list[list[str]]:
    """The `feeler ...` commands of a hint, split as a shell would."""
    import re
    import shlex

    return [shlex.split(c) for c in re.findall(r"`(feeler [^`]*)`", needs)]


def _outs(inv) -> dict[str, str]:
    """{title: the --out of its first command} of the missing sections."""
    found = {}
    for m in inv.missing:
        for argv in _commands(m.needs):
            if "--out" in argv:
                found.setdefault(m.title, argv[argv.index("--out") + 1])
    return found


def test_hints_on_a_fit_directory_name_the_fit_and_write_beside_it(run_dir, tmp_path, capsys):
    """`feeler report out/m2` said `feeler classify out/m2/m2 SCANS_DIR --out out/m2/classify`:
    the fit is out/m2 itself (the command as printed failed: out/m2/m2/posterior.nc
    missing), and every hint wrote into the fit's directory."""
    fit = shutil.copytree(run_dir / "m2", tmp_path / "runs" / "m2")
    (tmp_path / "runs" / "discriminate").mkdir()                     # taken: the hint picks a free name
    inv = discover(fit)
    needs = {m.title: m.needs for m in inv.missing}
    assert _commands(needs["Classification of held-out scans"])[0][:3] == ["feeler", "classify", str(fit)]
    assert _commands(needs["The robot's difference threshold"])[0] == [
        "feeler", "discriminate", str(fit), "--out", str(tmp_path / "runs" / "discriminate-2")]
    outs = _outs(inv)
    assert len(outs) == 9 and all(os.path.dirname(o) == str(tmp_path / "runs") for o in outs.values()), outs
    assert not any(os.path.exists(o) for o in outs.values())
    assert inv.missing_note == (f"these commands write beside {fit} (it holds one command's output), in "
                                f"{tmp_path / 'runs'}; `feeler report {tmp_path / 'runs'}` shows them with it")
    # as printed: the robot's threshold from the fit (small, to be quick)
    argv = _commands(needs["The robot's difference threshold"])[0][1:]
    assert main([*argv, "--n-scans", "20", "--no-progress"]) == 0
    assert (tmp_path / "runs" / "discriminate-2" / "discrimination.json").is_file()
    capsys.readouterr()
    assert main(["report", str(fit), "--no-pdf", "--no-progress"]) == 0          # the command and the first page
    out = capsys.readouterr().out
    assert f"needs `feeler classify {fit} SCANS_DIR --out {tmp_path / 'runs' / 'classify'}`" in out
    assert f"note: {inv.missing_note}" in out
    html = (fit / "report.html").read_text(encoding="utf-8")
    assert f"feeler classify {fit} SCANS_DIR" in html and "These commands write beside" in html
    assert f"{fit}/" not in html.split("Not in this run")[1].split("</table>")[0]


def test_hints_on_a_simulation_chain_through_the_fit_they_suggest(run_dir, tmp_path):
    sim = shutil.copytree(run_dir / "four-plates", tmp_path / "runs" / "sim")
    needs = {m.title: m.needs for m in discover(sim).missing}
    m2 = str(tmp_path / "runs" / "m2")
    assert _commands(needs["M2: neuron (a, τ, h) and decoder noise"]) == [
        ["feeler", "calibrate", "neuron", str(sim), "--out", m2]]
    assert _commands(needs["The robot's difference threshold"])[0][2] == m2
    assert _commands(needs["Classification of held-out scans"])[0][2] == m2
    trials = str(tmp_path / "runs" / "psychophysics" / "trials.csv")
    assert _commands(needs["Human 2AFC trials"])[0][-1] == str(tmp_path / "runs" / "psychophysics")
    assert _commands(needs["M4: human psychometric functions"])[0][3] == trials
    m1 = _commands(needs["M1: sensor force→displacement matrix"])
    assert m1[0][-1] == m1[1][3] == str(tmp_path / "runs" / "sensor-calibration")   # simulate, then fit it


def test_hints_on_a_run_of_several_parts_write_inside_it(part_run, run_dir):
    run = part_run("m2", "four-plates", "psychophysics")
    inv = discover(run)
    needs = {m.title: m.needs for m in inv.missing}
    assert _commands(needs["The robot's difference threshold"])[0] == [
        "feeler", "discriminate", str(run / "m2"), "--out", str(run / "discriminate")]
    assert _commands(needs["M4: human psychometric functions"])[0][3] == str(run / "psychophysics" / "trials.csv")
    assert inv.missing_note == "" and all(os.path.dirname(o) == str(run) for o in _outs(inv).values())
    assert discover(run_dir).missing == ()                                   # the whole demo: nothing


def test_a_single_simulation_directory(run_dir, tmp_path, capsys):
    sim = shutil.copytree(run_dir / "four-plates", tmp_path / "sim")
    assert main(["report", str(sim), "--no-pdf", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "holds: 1 part(s) in 1 section(s)\n  Robot scans (simulated, ./)" in out
    assert "not in this run: M1: sensor force→displacement matrix — needs `feeler simulate " in out
    assert f"`feeler calibrate sensor {tmp_path / 'sensor-calibration'} --out {tmp_path / 'm1'}`" in out
    manifest = json.loads((sim / "report-manifest.json").read_text(encoding="utf-8"))
    assert [f["sources"] for f in manifest["figures"]] == [["scans.csv", "scene.toml"]] * 2


def test_an_acquisition(acquired, tmp_path):
    report = build_report(acquired, tmp_path / "out", pdf=False)
    assert _sections(report) == ["robot:"] and report.inventory.parts[0].kind == "acquisition"
    html = report.html.read_text(encoding="utf-8")
    assert "Robot scans (acquired, ./)" in html and "Acquisition counts" in html
    needs = {m.title: m.needs for m in report.inventory.missing}              # new outputs beside the run
    assert (f"`feeler calibrate neuron {acquired} --out {acquired.parent / 'm2'}`"
            in needs["M2: neuron (a, τ, h) and decoder noise"])
    assert "the plan (scene.toml) sets the length; a, τ, h are the paper&#39;s (§5.2)" in html
    assert "Sample timing of the acquisition" in [f["title"] for f in report.figures]
    assert all(f["layout_problems"] == [] for f in report.figures)
    # plates 0 and 0.2 mm only: the claims needing two non-zero plates say so
    assert "needs scans of two non-zero plates" in html


def test_a_mix_under_other_names(run_dir, tmp_path):
    mix = tmp_path / "mix"
    shutil.copytree(run_dir / "m2", mix / "calibrations" / "neuron-2026")
    shutil.copytree(run_dir / "four-plates", mix / "scans" / "monday")
    shutil.copytree(run_dir / "discriminate", mix / "robot-threshold")
    shutil.copytree(run_dir / "skin-ladder", mix / "skin" / "ladder-2026")
    inv = discover(mix)
    assert [s.key for s in inv.present] == ["robot:scans/monday", "fit:calibrations/neuron-2026", "compare", "finger",
                                            "speed"]
    assert inv.first("fit", "m2").label == "calibrations/neuron-2026/"
    report = build_report(mix, tmp_path / "out", pdf=False)
    assert all(f["layout_problems"] == [] for f in report.figures)
    assert all((mix / s).exists() for f in report.figures for s in f["sources"])


def test_skin_figure_tables_without_histories(tmp_path):
    scene = tmp_path / "tiny.toml"
    scene.write_text('[scene]\nkind = "finger-steps"\n[loading]\nspeeds_mm_s = [20.0, 40.0]\ntravel_step_mm = 0.05\n'
                     '[steps]\nheights_um = [5.0, 15.0]\n[model]\nlevel = "l0"\n', encoding="utf-8")
    assert main(["skin", "figures", str(scene), "--out", str(tmp_path / "figs")]) == 0
    report = build_report(tmp_path / "figs", tmp_path / "out", pdf=False)
    assert _sections(report) == ["finger"]
    assert [f["title"] for f in report.figures] == ["Fig. 5: peak pulse density against step height",
                                                    "Fig. 6: accepted against presented step height"]
    assert "Figs 3–4 need strain.csv" in report.html.read_text(encoding="utf-8")


def test_human_trials_alone(run_dir, tmp_path):
    trials = shutil.copytree(run_dir / "psychophysics", tmp_path / "trials")
    report = build_report(trials, tmp_path / "out", pdf=False)
    assert _sections(report) == ["compare"]
    assert [f["title"] for f in report.figures] == ["Human 2AFC data and the pooled psychometric functions"]


def _png(tmp_path) -> bytes:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(2, 1.5))
    ax.plot([0, 1], [0, 1])
    fig.savefig(tmp_path / "x.png")
    plt.close(fig)
    return (tmp_path / "x.png").read_bytes()


def test_m4_curve_images_and_new_threshold_columns_are_shown(run_dir, tmp_path):
    m4 = shutil.copytree(run_dir / "m4", tmp_path / "run" / "m4")
    thr = (m4 / "thresholds.csv").read_text(encoding="utf-8").splitlines()
    head = next(i for i, line in enumerate(thr) if line.startswith("subject"))
    cols = thr[head].split(",")
    assert {"backend", "pc", "slope_per_um"} <= set(cols)              # the fit writes them
    b = cols.index("backend")
    thr[head + 1:] = [",".join(f[:b] + ["laplace"] + f[b + 1:]) for f in (ln.split(",") for ln in thr[head + 1:])]
    (m4 / "thresholds.csv").write_text("\n".join(thr) + "\n", encoding="utf-8")
    (m4 / "curves").mkdir(exist_ok=True)
    png = _png(tmp_path)
    rows = ["subject,standard_um,standard_speed_mm_s,comparison_speed_mm_s,file"]
    for s in ("S1", "S2", "all"):
        (m4 / "curves" / f"{s}-20.png").write_bytes(png)
        rows.append(f"{s},10,20,20,curves/{s}-20.png")
    (m4 / "curves" / "index.csv").write_text("\n".join(rows) + "\n", encoding="utf-8")
    report = build_report(tmp_path / "run", tmp_path / "out", pdf=False)
    html = report.html.read_text(encoding="utf-8")
    assert html.count(base64.b64encode(png).decode("ascii")) == 3
    assert "S2 · 10 µm at 20 vs 20 mm/s" in html and "<th>slope at P (1/µm)</th>" in html and "laplace" in html
    listed = [f for f in report.figures if f["drawn_by"] != "feeler"]
    assert [f["sources"] for f in listed] == [[f"m4/curves/{s}-20.png"] for s in ("S1", "S2", "all")]


def test_a_listed_curve_that_is_not_a_png_is_named(run_dir, tmp_path):
    from feeler.errors import DataFileError

    m4 = shutil.copytree(run_dir / "m4", tmp_path / "run" / "m4")
    (m4 / "curves").mkdir(exist_ok=True)
    (m4 / "curves" / "index.csv").write_text("subject,standard_um,standard_speed_mm_s,comparison_speed_mm_s,file\n"
                                             "S1,10,20,20,curves/gone.png\n", encoding="utf-8")
    with pytest.raises(DataFileError, match=r"gone\.png: listed in m4/curves/index\.csv but not a readable PNG"):
        build_report(tmp_path / "run", tmp_path / "out", pdf=False)


def test_a_run_lists_what_each_missing_section_needs(run_dir, tmp_path, capsys):
    """An empty directory is an error now (tests/reports/test_report_audit_cases.py); one
    part lists the other 11 expected sections with what each would need."""
    run = shutil.copytree(run_dir / "psychophysics", tmp_path / "run" / "psychophysics")
    assert main(["report", str(run.parent), "--no-progress", "--no-pdf"]) == 0
    out = capsys.readouterr().out
    assert "holds: 1 part(s) in 1 section(s)" in out and out.count("not in this run: ") == 11
    html = (tmp_path / "run" / "report.html").read_text(encoding="utf-8")
    assert "Not in this run, and what each would need" in html
    odd = shutil.copytree(run, tmp_path / "Mëßung Ω 1" / "psychophysics")      # commands to paste, quoted
    needs = [m.needs for m in discover(odd.parent).missing if "--out" in m.needs]   # what stdout prints
    assert needs and all(f"'{odd.parent}" in n for n in needs), needs


def test_progress_is_a_line_per_stage_and_figure_off_a_terminal(run_dir, tmp_path, capsys):
    fit = shutil.copytree(run_dir / "m2", tmp_path / "m2")
    assert main(["report", str(fit), "--no-pdf"]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err[0] == f"feeler report: reading {fit} ..."
    figures = [f["title"] for f in json.loads((fit / "report-manifest.json").read_text(encoding="utf-8"))["figures"]]
    assert len(figures) >= 2                                              # the lines below are a real check
    assert err[1:] == ["report: reading the run ...", "report: reading 1 fit ...",
                       "report: section 1/1: M2: neuron (a, τ, h) and decoder noise (./) ...",
                       *[f"report: section 1/1, figure {k}: {t} ..." for k, t in enumerate(figures, 1)],
                       "report: first page ...", "report: html ..."]
    assert main(["report", str(fit), "--no-pdf", "--no-progress"]) == 0
    assert capsys.readouterr().err == ""                       # as every command: no first line either


def test_figures_are_counted_over_the_report(run_dir, tmp_path, capsys):
    mix = tmp_path / "mix"
    shutil.copytree(run_dir / "m1", mix / "m1")
    shutil.copytree(run_dir / "m2", mix / "m2")
    assert main(["report", str(mix), "--no-pdf"]) == 0
    err = capsys.readouterr().err.splitlines()
    drawn = [ln for ln in err if ", figure " in ln]
    n = len(json.loads((mix / "report-manifest.json").read_text(encoding="utf-8"))["figures"])
    assert [int(ln.split(", figure ")[1].split(":")[0]) for ln in drawn] == list(range(1, n + 1))
    assert {ln.split(",")[0] for ln in drawn} == {"report: section 1/2", "report: section 2/2"}


def test_the_pdf_stage_says_each_step_and_page(run_dir, tmp_path, capsys):
    run = shutil.copytree(run_dir / "psychophysics", tmp_path / "run" / "psychophysics").parent
    assert main(["report", str(run)]) == 0
    err = capsys.readouterr().err.splitlines()
    pdf = err[err.index("report: html ...") + 1:]
    pages = json.loads((run / "report-manifest.json").read_text(encoding="utf-8"))["pages"]
    assert pages >= 2 and pdf == ["report: pdf: loading WeasyPrint ...", "report: pdf: parsing the html ...",
                                  "report: pdf: applying the styles ...", "report: pdf: building the boxes ...",
                                  *[f"report: pdf: laying out page {p} ..." for p in range(1, pages + 1)],
                                  "report: pdf: writing the file ..."]
    import logging
    steps = logging.getLogger("weasyprint.progress")
    assert steps.handlers == [] and steps.propagate and steps.level == logging.NOTSET     # left as found


def test_progress_bar_on_a_terminal(run_dir, tmp_path):
    fit = shutil.copytree(run_dir / "m2", tmp_path / "m2")
    env = dict(os.environ, MPLBACKEND="Agg", COLUMNS="100")
    text = in_a_pty([sys.executable, "-m", "feeler", "report", str(fit), "--no-pdf"], env=env, stdout=False)
    assert "report: section 1/1: M2: neuron" in text and "\r" in text                       # a bar redrawn in place
    assert "report: section 1/1: M2: neuron (a, τ, h) and decoder noise (./) ...\n" not in text.replace("\r\n", "\n")


@pytest.mark.parametrize("make", ["file", "readonly"])
def test_an_unwritable_out_is_refused_before_any_work(run_dir, tmp_path, capsys, make):
    out = tmp_path / "out"
    if make == "file":
        out.write_text("x")
    else:
        out.mkdir()
        out.chmod(0o500)
        if os.access(out, os.W_OK):                   # root writes anywhere
            pytest.skip("running as root: a read-only directory is still writable")
    assert main(["report", str(run_dir / "m1"), "--out", str(out / "r" if make != "file" else out)]) == 2
    err = capsys.readouterr().err
    assert len([ln for ln in err.splitlines() if ln.startswith("feeler:")]) == 1 and "--out" in err \
        and "report: reading the run" not in err
    assert not (out / "r").exists() if make != "file" else out.read_text() == "x"


@pytest.mark.parametrize("n_plates", [3, 9, 18])
def test_a_classification_of_many_plates_is_drawn_readably(tmp_path, n_plates):
    """18 plates drew their confusion matrix at 3.6 in with two-line cell labels and upright
    tick labels: 29 overlapping texts (and a bin count over a tick label in the calibration
    curve). The figure grows, its ticks turn, its cells say less; no layout problem remains."""
    import numpy as np
    import pandas as pd

    rng = np.random.default_rng(n_plates)
    plates = np.round(np.geomspace(0.01, 1.5, n_plates) - 0.01, 3)
    step = np.repeat(plates, 6)
    prob = rng.dirichlet(np.full(n_plates, 0.3), step.size)
    prob[np.arange(step.size), np.searchsorted(plates, step)] += 2.0          # mostly right, some not
    prob /= prob.sum(axis=1, keepdims=True)
    decided = plates[prob.argmax(axis=1)]
    frame = pd.DataFrame({"scan_id": np.arange(step.size), "step_mm": step, "plate_mm": decided,
                          **{f"p_{v:g}mm": prob[:, k] for k, v in enumerate(plates)},
                          "height_mm": decided, "lo90_mm": decided - 0.01, "hi90_mm": decided + 0.01})
    (tmp_path / "classify").mkdir()
    frame.to_csv(tmp_path / "classify" / "classification.csv", index=False)
    report = build_report(tmp_path, tmp_path / "out", pdf=False)
    titles = [f["title"] for f in report.figures]
    assert any(t.startswith("Confusion matrix") for t in titles) and len(titles) >= 2
    assert [(f["title"], f["layout_problems"]) for f in report.figures if f["layout_problems"]] == []


def test_a_simulation_of_many_plates_draws_eight_curves_and_says_so(tmp_path):
    """18 plates' legends in Figs 7-9 were cut at the panels' edges (and colours repeat after
    10): eight plates, evenly spaced, are drawn and the caption says which share (here of 10)."""
    from pathlib import Path

    scene = (Path(__file__).parents[2] / "datasets-synthetic" / "four-plates.toml").read_text()
    many = "heights_mm = [" + ", ".join(f"{0.02 * k:g}" for k in range(10)) + "]"
    text = scene.replace("heights_mm = [0.0, 0.05, 0.1, 0.2]", many).replace("scans_per_plate = 24",
                                                                            "scans_per_plate = 2")
    assert many in text and "scans_per_plate = 2\n" in text
    (tmp_path / "many.toml").write_text(text)
    assert main(["simulate", str(tmp_path / "many.toml"), "--out", str(tmp_path / "run" / "sim")]) == 0
    report = build_report(tmp_path / "run", tmp_path / "out", pdf=False)
    assert [(f["title"], f["layout_problems"]) for f in report.figures if f["layout_problems"]] == []
    html = report.html.read_text(encoding="utf-8")
    assert html.count("(8 of the 10 plates, evenly spaced)") == 2


def test_an_acquisition_killed_mid_run_says_so_in_words(acquired, tmp_path):
    """A SIGKILLed run's summary.json has no "stopped" (nothing ran to write it): the report
    said "()" after its counts; an interrupted one said "(KeyboardInterrupt: )"."""

    run = shutil.copytree(acquired, tmp_path / "killed", ignore=shutil.ignore_patterns("report*"))
    summary = json.loads((run / "summary.json").read_text())
    summary.update(complete=False, scans_done=1)
    (run / "summary.json").write_text(json.dumps(summary))
    html = build_report(run, tmp_path / "out", pdf=False).html.read_text(encoding="utf-8")
    assert "scans (stopped without a word: killed, or the machine went down); resume with" in html
    summary["stopped"] = "interrupted (Ctrl-C)"
    (run / "summary.json").write_text(json.dumps(summary))
    html = build_report(run, tmp_path / "out2", pdf=False).html.read_text(encoding="utf-8")
    assert "scans (interrupted (Ctrl-C)); resume with" in html and "()" not in html.split("Incomplete")[1][:200]


def test_a_calibration_campaign_alone_says_how_to_fit_it_beside_it(run_dir, tmp_path):
    """Its section said `--out DIR/m1`, inside the simulation's directory."""
    data = shutil.copytree(run_dir / "sensor-calibration", tmp_path / "runs" / "cal")
    report = build_report(data, tmp_path / "out", pdf=False)
    html = report.html.read_text(encoding="utf-8")
    assert f"fit them with `feeler calibrate sensor {data} --out {tmp_path / 'runs' / 'm1'}`" in html
