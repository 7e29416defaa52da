"""Report sections against the files of the run: numbers, sources, order, labels."""
from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feeler.calib.neuron.classify import expected_calibration_error
from feeler.reports import build_report, discover
from feeler.reports.discover import FIT_FILES
from feeler.reports.sec_classify import classify_section, plate_columns, reliability
from feeler.reports.sec_psycho import psychometric_section


def _spec(inv, key):
    return next(s for s in inv.present if s.key == key)


def test_discover_lists_present_and_missing(run_dir):
    inv = discover(run_dir)
    keys = [s.key for s in inv.present]
    assert keys == ["robot", "fit:m1", "classify", "psychometric", "fit:m4", "fig6", "finger", "benchmarks"]
    missing = dict(inv.missing)
    assert set(missing) == {"M2: neuron (a, τ, h) and decoder noise", "Finger route: τ and decision noise σ_d"}
    assert missing["M2: neuron (a, τ, h) and decoder noise"] == tuple(f"m2/{f}" for f in FIT_FILES)


def test_classification_numbers_from_the_csv(run_dir):
    inv = discover(run_dir)
    section = classify_section(inv, _spec(inv, "classify"))
    table = next(b for b in section.blocks if b.kind == "table")
    rows = {r[0]: r for r in table.rows}
    # hand-made file: step 0 → 2 of 3 right, step 0.1 → 3 of 3; scans 2 and 5 outside their interval
    assert rows["all"][1:] == ("6", "0.833", str(round(np.mean([.9, .8, .6, .95, .7, .98]), 3)), "0.667")
    assert rows["0"][2] == "0.667" and rows["0.1"][2] == "1"
    assert rows["0"][4] == "0.667" and rows["0.1"][4] == "0.667"
    prob = np.array([[.9, .1], [.8, .2], [.4, .6], [.05, .95], [.3, .7], [.02, .98]])
    ece = expected_calibration_error(prob, [0, 0, 0, 1, 1, 1])
    assert table.caption.endswith(f"{ece:.3g}.")
    assert all(b.sources == ("classify/classification.csv",) for b in section.blocks)


def test_plate_columns_parse_only_probabilities():
    assert plate_columns(["scan_id", "p_0mm", "p_0.05mm", "p_xmm", "plate_mm", "p_0.2"]) == {"p_0mm": 0.0, "p_0.05mm": 0.05}


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.floats(0.0, 1.0), st.booleans()), min_size=1, max_size=60))
def test_reliability_bins_reproduce_the_ece(cases):
    conf = np.array([c for c, _ in cases])
    hit = np.array([h for _, h in cases])
    rel = reliability(conf, hit)
    assert rel[:, 2].sum() == len(cases)
    # a two-class problem with top probability max(conf, 1 - conf) has the same bins only when
    # conf >= 0.5; build the probabilities so that class 0 is the top class with probability conf
    top = np.maximum(conf, 0.5)
    prob = np.stack([top, 1 - top], axis=1)
    rel_top = reliability(top, hit)
    ece = np.sum(rel_top[:, 2] / len(cases) * np.abs(rel_top[:, 1] - rel_top[:, 0]))
    assert ece == pytest.approx(expected_calibration_error(prob, np.where(hit, 0, 1)), abs=1e-12)


def test_robot_and_human_numbers(run_dir):
    inv = discover(run_dir)
    section = psychometric_section(inv, _spec(inv, "psychometric"))
    robot, human = (b for b in section.blocks if b.kind == "table")
    disc = json.loads((run_dir / "discriminate/discrimination.json").read_text())
    assert robot.rows[0][1] == "0.005 [0.0032, 0.0074]" and robot.rows[1][1] == "0.05 [0.032, 0.074]"
    assert robot.sources == ("discriminate/discrimination.json",)
    assert len(robot.rows) == 3 + len(disc["pairs"])
    thr = pd.read_csv(run_dir / "m4/thresholds.csv", comment="#")
    pooled = thr[thr["subject"] == "all"].reset_index(drop=True)
    assert [r[0] for r in human.rows] == ["all"] * len(pooled)
    for row, (_, r) in zip(human.rows, pooled.iterrows()):
        std = 10.0                                                      # the scene's standard, µm
        assert row[5] == f"{r['dt_um'] / std:.3g} [{r['dt_lb_um'] / std:.3g}, {r['dt_ub_um'] / std:.3g}]"
    notes = [b for b in section.blocks if b.kind == "note"]
    assert notes and notes[0].level == "synthetic" and "SYNTHETIC" in notes[0].text


def test_every_source_is_a_file_of_the_run(report, run_dir):
    html = report.html.read_text(encoding="utf-8")
    sources = set()
    for block in re.findall(r"Source: ([^<]+)</span>", html):
        sources |= {s.strip() for s in block.split(",")}
    assert {"four-plates/scans.csv", "m1/posterior.nc", "m4/thresholds.csv", "classify/classification.csv",
            "finger/strain.csv", "benchmarks/speed.csv", "finger-route/tau_report.json",
            "robot_table.json"} <= sources
    for s in sources:
        assert (run_dir / s).exists(), s


def test_robot_table_from_the_demo_file(report):
    html = report.html.read_text(encoding="utf-8")
    robot = html[html.index('<section id="robot">'):]
    robot = robot[:robot.index("</section>")]
    assert "Per plate: peak z, raw U̇_y and the ΔU_y jump" in robot
    assert "<td>0.21</td>" in robot and "<td>0.93</td>" in robot   # peak_z_mean of 0.2 mm; pc by peak z


def test_human_points_labelled_synthetic(report):
    html = report.html.read_text(encoding="utf-8")
    assert "Synthetic data." in html and "psychophysics/trials.csv" in html
    fig6 = html[html.index('<section id="fig6">'):]
    assert "Human points: SYNTHETIC" in fig6[:fig6.index("</section>")]


def test_failed_calibration_comes_first(copy_run, tmp_path):
    bad = {"ok": False, "problems": ["C[0,0]: R-hat 1.2 > 1.01"]}
    (copy_run / "m4/verdict.json").write_text(json.dumps(bad), encoding="utf-8")
    for part in ("four-plates", "classify", "finger", "benchmarks", "finger-route"):
        import shutil
        shutil.rmtree(copy_run / part)
    report = build_report(copy_run, tmp_path / "out", pdf=False)
    assert report.failed == ("M4: human psychometric functions (m4/)",)
    html = report.html.read_text(encoding="utf-8")
    banner = html.index("FAILED CALIBRATION: M4")
    assert banner < html.index("<section")
    assert html.index('<section id="fit-m4">') == html.index("<section")
    assert "C[0,0]: R-hat 1.2 &gt; 1.01" in html
