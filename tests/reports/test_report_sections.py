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
from feeler.reports.sec_classify import classify_section, plate_columns, reliability
from feeler.reports.sec_compare import Z75, compare_section, folded_points, human_curve


def _spec(inv, key):
    return next(s for s in inv.present if s.key == key)


def _section_html(html: str, sid: str) -> str:
    part = html[html.index(f'<section id="{sid}">'):]
    return part[:part.index("</section>")]


def test_the_demo_run_is_found_part_by_part(run_dir):
    inv = discover(run_dir)
    keys = [s.key for s in inv.present]
    assert keys == ["robot:four-plates", "fit:m1", "fit:m2", "fit:m4", "fit:finger-route", "classify:classify",
                    "compare", "finger", "speed"]
    robot = _spec(inv, "robot:four-plates")
    assert [p.rel for p in robot.parts] == ["four-plates", "held-out"]           # same design, another seed
    assert {p.model for p in inv.of("fit")} == {"m1", "m2", "m4", "finger-route"}
    assert [m.title for m in inv.missing] == []                    # the demo measures the decoder trade too


def test_classification_numbers_from_the_csv(copy_run):
    (copy_run / "classify" / "classification.csv").write_text(
        "scan_id,step_mm,plate_mm,p_0mm,p_0.1mm,height_mm,lo90_mm,hi90_mm,extra_column\n"
        "0,0.0,0.0,0.9,0.1,0.01,-0.02,0.04,a\n1,0.0,0.0,0.8,0.2,0.02,-0.01,0.05,b\n"
        "2,0.0,0.1,0.4,0.6,0.06,0.03,0.09,c\n3,0.1,0.1,0.05,0.95,0.1,0.07,0.13,d\n"
        "4,0.1,0.1,0.3,0.7,0.09,0.06,0.12,e\n5,0.1,0.1,0.02,0.98,0.11,0.12,0.14,f\n", encoding="utf-8")
    inv = discover(copy_run)
    section = classify_section(inv, _spec(inv, "classify:classify"))
    table = next(b for b in section.blocks if b.kind == "table")
    rows = {r[0]: r for r in table.rows}
    # hand-made file: step 0 → 2 of 3 right, step 0.1 → 3 of 3; scans 2 and 5 outside their interval
    assert rows["all"][1:] == ("6", "0.833", str(round(np.mean([.9, .8, .6, .95, .7, .98]), 3)), "0.667")
    assert rows["0"][2] == "0.667" and rows["0.1"][2] == "1"
    prob = np.array([[.9, .1], [.8, .2], [.4, .6], [.05, .95], [.3, .7], [.02, .98]])
    ece = expected_calibration_error(prob, [0, 0, 0, 1, 1, 1])
    assert table.caption.endswith(f"{ece:.3g}.")
    titles = [b.title for b in section.blocks if b.kind == "figure"]
    assert "Calibration curve of the classifier" in titles                     # 4 bins occupied
    assert all(b.sources == ("classify/classification.csv",) for b in section.blocks)


def test_flagged_scans_are_left_out_of_the_numbers_as_classify_does(copy_run):
    """classify's own summary leaves out scans outside the fit's envelope; so does the
    report, and says how many; all flagged leaves a note, not numbers."""
    path = copy_run / "classify" / "classification.csv"
    head = "scan_id,step_mm,plate_mm,p_0mm,p_0.1mm,height_mm,lo90_mm,hi90_mm,flagged,flag\n"
    rows = ["0,0.0,0.0,0.9,0.1,0.01,-0.02,0.04,False,", "1,0.0,0.1,0.2,0.8,0.1,0.05,0.15,True,scan of 0.5 s",
            "2,0.1,0.1,0.05,0.95,0.1,0.07,0.13,False,"]
    path.write_text(head + "\n".join(rows) + "\n", encoding="utf-8")
    inv = discover(copy_run)
    section = classify_section(inv, _spec(inv, "classify:classify"))
    table = next(b for b in section.blocks if b.kind == "table")
    assert {r[0]: r for r in table.rows}["all"][1:3] == ("2", "1")
    assert table.caption.endswith(" 1 of 3 scans, flagged as unlike the fit's training scans, are left out.")
    path.write_text(head + rows[1] + "\n", encoding="utf-8")
    inv = discover(copy_run)                     # an inventory reads each file once (one report)
    (block,) = classify_section(inv, _spec(inv, "classify:classify")).blocks
    assert block.kind == "note" and block.text.startswith("All 1 classified scans are flagged")


def test_labels_that_contradict_the_fit_are_a_warning_first(copy_run):
    """The section warns as `feeler classify` does when the labels contradict the fit:
    30 scans, probability columns written with a trailing zero, the intervals holding 15
    labels where a 90 % interval holds 27, the top probabilities 0.99 where 15 are right."""
    path = copy_run / "classify" / "classification.csv"
    head = "scan_id,step_mm,plate_mm,p_0.00mm,p_0.10mm,height_mm,lo90_mm,hi90_mm,flagged\n"
    right = [f"{k},0.1,0.1,0.01,0.99,0.1,0.09,0.11,False" for k in range(15)]
    wrong = [f"{k},0.0,0.1,0.01,0.99,0.1,0.09,0.11,False" for k in range(15, 30)]
    path.write_text(head + "\n".join(right + wrong) + "\n", encoding="utf-8")
    inv = discover(copy_run)
    first = classify_section(inv, _spec(inv, "classify:classify")).blocks[0]
    assert first.kind == "note" and first.text.startswith("Warning: The fit's intervals do not hold")
    assert "15 of 30 labels inside" in first.text and "15 of 30 classified as their labelled plate" in first.text
    path.write_text(head + "\n".join(right + [w.replace(",0.0,0.1,", ",0.1,0.1,") for w in wrong]) + "\n",
                    encoding="utf-8")
    inv = discover(copy_run)                     # an inventory reads each file once (one report)
    assert not any(b.kind == "note" and "Warning" in b.text
                   for b in classify_section(inv, _spec(inv, "classify:classify")).blocks)


def test_intervals_far_wider_than_claimed_are_a_note_first(copy_run):
    """100 of 100 labels inside their 90 % intervals: the section says the intervals are
    conservative, as `feeler classify` notes, and does not call it a warning."""
    path = copy_run / "classify" / "classification.csv"
    head = "scan_id,step_mm,plate_mm,p_0mm,p_0.1mm,height_mm,lo90_mm,hi90_mm,flagged\n"
    rows = [f"{k},0.1,0.1,0.1,0.9,0.1,0.05,0.15,False" for k in range(90)]
    rows += [f"{k},0.1,0.0,0.9,0.1,0.1,0.05,0.15,False" for k in range(90, 100)]
    path.write_text(head + "\n".join(rows) + "\n", encoding="utf-8")
    inv = discover(copy_run)
    first = classify_section(inv, _spec(inv, "classify:classify")).blocks[0]
    assert first.kind == "note" and first.text.startswith("Note: The fit's 90 % intervals are wider than they claim")
    assert "100 of 100 labels inside" in first.text and "Warning" not in first.text


def test_a_one_point_calibration_curve_is_replaced_by_words(run_dir):
    inv = discover(run_dir)
    section = classify_section(inv, _spec(inv, "classify:classify"))
    titles = [getattr(b, "title", "") for b in section.blocks]
    assert "Calibration curve of the classifier" not in titles
    assert any(b.kind == "note" and "No calibration curve" in b.text for b in section.blocks)


def test_plate_columns_parse_only_probabilities():
    assert plate_columns(["scan_id", "p_0mm", "p_0.05mm", "p_xmm", "plate_mm", "p_0.2"]) == {"p_0mm": 0.0, "p_0.05mm": 0.05}


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.floats(0.0, 1.0), st.booleans()), min_size=1, max_size=60))
def test_reliability_bins_reproduce_the_ece(cases):
    conf = np.array([c for c, _ in cases])
    hit = np.array([h for _, h in cases])
    rel = reliability(conf, hit)
    assert rel[:, 2].sum() == len(cases)
    top = np.maximum(conf, 0.5)
    prob = np.stack([top, 1 - top], axis=1)
    rel_top = reliability(top, hit)
    ece = np.sum(rel_top[:, 2] / len(cases) * np.abs(rel_top[:, 1] - rel_top[:, 0]))
    assert ece == pytest.approx(expected_calibration_error(prob, np.where(hit, 0, 1)), abs=1e-12)


def test_human_curve_passes_75_percent_at_the_threshold():
    assert human_curve(0.0, 1.3) == pytest.approx(0.5)
    assert human_curve(1.3, 1.3) == pytest.approx(0.75, abs=1e-12)
    assert human_curve(-1.3, 1.3) == pytest.approx(0.25, abs=1e-12)
    assert Z75 == pytest.approx(0.6744897501960817)


def test_folded_points_count_correct_answers_on_both_sides():
    trials = pd.DataFrame({"subject": ["A"] * 4 + ["B"] * 2, "standard_um": 10.0, "standard_speed_mm_s": 20.0,
                           "comparison_speed_mm_s": 20.0, "comparison_um": [9.0, 11.0, 10.0, 8.0, 9.0, 12.0],
                           "n_trials": [10, 10, 10, 10, 20, 20], "n_comparison_higher": [3, 8, 5, 1, 4, 19]})
    d, k, n = folded_points(trials, 20.0, 20.0)
    assert d.tolist() == [1.0, 2.0]                                 # the Δ = 0 comparison is left out
    assert k.tolist() == [7 + 8 + 16, 9 + 19] and n.tolist() == [40, 30]


def test_robot_and_human_numbers(run_dir):
    inv = discover(run_dir)
    section = compare_section(inv, _spec(inv, "compare"))
    table = next(b for b in section.blocks if b.kind == "table")
    disc = json.loads((run_dir / "discriminate/discrimination.json").read_text())
    th, w = disc["threshold_mm"], disc["weber"]
    robot = table.rows[0]
    assert robot[0] == "robot" and robot[2].startswith(f"{th['mean'] * 1e3:.3g} [{th['lo95'] * 1e3:.3g}, ")
    assert robot[3].startswith(f"{w['mean']:.3g} [")
    thr = pd.read_csv(run_dir / "m4/thresholds.csv", comment="#")
    pooled = thr[thr["subject"] == "all"].reset_index(drop=True)
    human = table.rows[1:]
    assert len(human) == len(pooled)
    for row, (_, r) in zip(human, pooled.iterrows()):
        std = 10.0                                                     # the scene's standard, µm
        assert row[3] == f"{r['dt_um'] / std:.3g} [{r['dt_lb_um'] / std:.3g}, {r['dt_ub_um'] / std:.3g}]"
        assert "SYNTHETIC" in row[0]
    notes = [b for b in section.blocks if b.kind == "note"]
    assert notes[0].level == "synthetic" and notes[0].text.startswith("SYNTHETIC human data, not human measurements")
    assert "SYNTHETIC — SYNTHETIC" not in notes[0].text and "seed 20040616" in notes[0].text


def test_robot_curve_is_the_one_the_threshold_is_read_from(run_dir):
    """discriminate records the curve it reads its threshold from. An outside review found the
    demo's curve drawn from 400 touches a height beside a threshold from 1000: it crossed 75 %
    at 4.24 um under a threshold marked at 4.49 um, its band (posterior only) lay below it and
    excluded 0.5 at no difference."""
    disc = json.loads((run_dir / "discriminate/discrimination.json").read_text())
    curve = pd.DataFrame(disc["curve"])
    assert not (run_dir / "discriminate/threshold_curve.csv").exists()
    assert curve["lo95"].iloc[0] <= 0.5 <= curve["hi95"].iloc[0] and curve["pc"].is_monotonic_increasing
    th = disc["threshold_mm"]
    assert np.interp(0.75, curve["pc"], curve["delta_mm"]) == pytest.approx(th["mean"], rel=0.01)
    # its band crosses 75 % at the ends of the threshold's interval (both: posterior and simulation error)
    assert np.interp(0.75, curve["hi95"], curve["delta_mm"]) == pytest.approx(th["lo95"], rel=0.05)
    assert np.interp(0.75, curve["lo95"], curve["delta_mm"]) == pytest.approx(th["hi95"], rel=0.05)
    assert np.all(curve["lo95"] <= curve["pc"] + 1e-12) and np.all(curve["pc"] <= curve["hi95"] + 1e-12)


def test_an_older_output_gets_the_same_curve_from_the_demo_stage(run_dir, tmp_path):
    """A discrimination.json written before the command recorded its curve: the demo stage
    computes it as the command does, from the touches and draws the file records."""
    from feeler.demo.curve import write_threshold_curve

    disc = json.loads((run_dir / "discriminate/discrimination.json").read_text())
    old = {k: v for k, v in disc.items() if k != "curve"}
    (tmp_path / "discrimination.json").write_text(json.dumps(old))
    path = write_threshold_curve(run_dir / "m2", tmp_path)
    curve = pd.read_csv(path, comment="#")
    assert f"{disc['n_scans']} touches per height" in path.read_text().splitlines()[0]
    for column, values in disc["curve"].items():
        assert np.allclose(curve[column], values, rtol=1e-5, atol=1e-9), column
    assert write_threshold_curve(run_dir / "m2", run_dir / "discriminate") is None      # it has its curve


def test_every_source_is_a_file_of_the_run(report, run_dir):
    html = (report / "report.html").read_text(encoding="utf-8")
    sources = set()
    for block in re.findall(r"Source: ([^<]+)</span>", html):
        sources |= {s.strip() for s in block.split(",")}
    assert {"four-plates/scans.csv", "m1/posterior.nc", "m4/thresholds.csv", "classify/classification.csv",
            "finger/strain.csv", "skin-ladder/trade.csv", "speed/backends.csv", "finger-route/tau_report.json",
            "discriminate/discrimination.json"} <= sources
    for s in sources:
        assert (run_dir / s).exists(), s


def test_every_parameter_is_named(report):
    html = (report / "report.html").read_text(encoding="utf-8")
    m1 = _section_html(html, "sec-fit-m1")
    assert all(f"C[{i},{j}]" in m1 for i in range(3) for j in range(3)) and "σ_z (N)" in m1 and "cond(C)" in m1
    m4 = _section_html(html, "sec-fit-m4")
    assert "pse · all · 10 µm at 40 vs 20 mm/s" in m4 and "dt · S6 · 10 µm at 20 vs 20 mm/s" in m4
    assert "pse[0,0]" not in m4
    route = _section_html(html, "sec-fit-finger-route")
    assert "no traces are drawn" in route and "κ is a function of τ" in route
    assert route.count("300 ms | data)") == 1                 # the τ note gives P(τ ≤ 300 ms | data) once


def test_tables_are_readable(report):
    html = (report / "report.html").read_text(encoding="utf-8")
    assert "overflow-wrap: anywhere; }" not in html.split("th, td")[1][:200]          # keys are not cut mid-word
    assert "tau_mea" not in html and "tau_report.json</h3>" not in html              # no raw key/value dump


def test_human_points_labelled_synthetic(report, run_dir):
    from feeler.reports.sec_finger import human_points

    html = (report / "report.html").read_text(encoding="utf-8")
    assert "Synthetic data." in html and "psychophysics/trials.csv" in html
    manifest = json.loads((report / "report-manifest.json").read_text(encoding="utf-8"))
    fig6 = next(f for f in manifest["figures"] if f["title"].startswith("Fig. 6"))
    assert {"m4/thresholds.csv", "psychophysics/trials.csv"} <= set(fig6["sources"])
    points, _ = human_points(discover(run_dir))
    assert len(points) == 2 and all("SYNTHETIC" in p[-1] for p in points)
    assert [p[0] for p in points] == [10.0, 10.0]                    # presented: the standard


def test_speed_section_says_where_its_numbers_come_from(report):
    import html as html_lib

    html = (report / "report.html").read_text(encoding="utf-8")
    speed = _section_html(html, "sec-speed")
    assert "Measured during `feeler demo` at" in speed and "a small version" in speed
    # the live decoder's latency is scan time, not wall time (an outside reader); one parenthesis
    assert "but the live decoder's latency, which is scan time since the step" in html_lib.unescape(speed)
    assert ") (" not in html_lib.unescape(speed)
    assert "Calibration backends" in speed and "Sensor fidelity" in speed
    assert "live decoder" in speed.lower() and "decoder.csv" in speed
    finger = _section_html(html, "sec-finger")
    assert "The skin fidelity ladder: seconds per slide against error" in finger and "Trade table" in finger


def test_m2_per_plate_entries_name_their_plate_and_a_its_unit(report, run_dir):
    """The posterior panels and the summary table said plate_mean_mm[0..3] and never which
    plate (height) each index is (an outside walk-through)."""
    import html as html_lib

    from feeler.calib.fit import load

    steps = load(run_dir / "m2").posterior["observed_data"]["plate_steps_mm"].values
    m2 = html_lib.unescape(_section_html((report / "report.html").read_text(encoding="utf-8"), "sec-fit-m2"))
    for i, step in enumerate(steps):
        assert f"<td>plate_mean_mm[{i}] · plate {step:g} mm</td>" in m2
        assert f"<td>plate_sd_mm[{i}] · plate {step:g} mm</td>" in m2
    assert "<td>a (mm per unit strain)</td>" in m2 and "a in mm per unit strain" in m2

    import feeler.reports.fit_plots as fit_plots
    from feeler.reports.readers import load_fit

    panels, real = [], fit_plots._marginals

    def keep(draws, names, labels, **kw):                     # the panels' titles
        panels.extend(labels[n] for n in names)
        return real(draws, names, labels, **kw)

    inv = discover(run_dir)
    part = next(p for p in inv.parts if p.kind == "fit" and p.model == "m2")
    result = load_fit(run_dir / part.rel)
    mp = pytest.MonkeyPatch()
    try:
        mp.setattr(fit_plots, "_marginals", keep)
        fit_plots.plots_of(inv, part, result, dict(result.posterior["posterior"].attrs), sampler=False)
    finally:
        mp.undo()
    assert "a (mm per unit strain)" in panels
    assert [p for p in panels if p.startswith("plate_mean_mm")] == [
        f"plate_mean_mm[{i}] · plate {step:g} mm" for i, step in enumerate(steps)]


def test_speed_captions_say_their_own_times_and_mark_a_failed_fit(part_run, tmp_path, monkeypatch):
    """The captions of Calibration backends and Sensor fidelity carried "... but the live
    decoder's latency, which is scan time since the step", which is Figure R40's; and the
    backends figure drew emcee's point of a fit whose verdict failed (ok False) like the
    exact fit's (an outside walk-through; README: a failed fit's numbers are marked
    wherever they appear)."""
    import feeler.reports.sec_speed as speed

    run = part_run("speed")
    backends = pd.read_csv(run / "speed" / "backends.csv")
    backends["ok"] = [True] + [False] * (len(backends) - 1)          # as the emcee row of the walk-through's demo
    backends.to_csv(run / "speed" / "backends.csv", index=False)
    legends, captions, real = {}, {}, speed.make_figure

    def keep_legend(title, fig, sources, caption=""):
        legends[title] = [(t.get_text(), h.get_markerfacecolor()) for leg in fig.legends
                          for t, h in zip(leg.get_texts(), leg.legend_handles)]
        captions[title] = caption
        return real(title, fig, sources, caption)

    monkeypatch.setattr(speed, "make_figure", keep_legend)
    report = build_report(run, tmp_path / "out", pdf=False)
    for title in ("Calibration backends", "Sensor fidelity (M1 on each level)"):
        assert "decoder" not in captions[title] and "times in wall seconds on this machine" in captions[title]
    decoder = captions["Live decoder: decision latency against accuracy"]
    assert "latency in scan time since the stage passed the step (not wall time)" in decoder
    assert "wall seconds" not in decoder
    entries = legends["Calibration backends"]
    assert entries[0][0] == backends.option[0] and entries[0][1] != "none"          # a passing fit: filled
    assert all(t.endswith("(failed its verdict)") and face == "none" for t, face in entries[1:])
    assert "Hollow markers: fits that failed their verdict" in captions["Calibration backends"]
    assert "Hollow markers" not in captions["Sensor fidelity (M1 on each level)"]
    html = report.html.read_text(encoding="utf-8")
    table = html[html.index("<h3>Calibration backends"):]
    table = table[:table.index("</table>")]
    assert table.count('<tr class="failed">') == len(backends) - 1 and "Rows marked (ok False)" in html


@pytest.mark.parametrize("options", [3, 20, 40])
def test_a_trade_plot_of_many_options_names_every_one_at_its_median(options):
    """The open-world benchmark's 20 scenes in one legend column lost the last four below
    the figure's edge; and the plot took the best round where the table leads with medians."""
    from feeler.reports.sec_speed import _trade_figure

    rng = np.random.default_rng(3)
    frame = pd.DataFrame({"benchmark": [f"test_random_scene[random-{i:02d}]" for i in range(options)],
                          "min_s": rng.uniform(10, 20, options), "median_s": rng.uniform(30, 50, options),
                          "rounds": 3, "accuracy": rng.uniform(0.6, 1.0, options)})
    fig = _trade_figure("open_world", frame, "median_s", "accuracy", "benchmarks/open_world.csv", "measured")
    assert fig.problems == ()
    from feeler.reports.sec_speed import trade_columns
    assert trade_columns(frame) == ("median_s", "accuracy")


def test_options_at_one_point_share_a_marker_named_by_all(monkeypatch):
    """Four live-decoder thresholds at (3.36 s, 1.00) were drawn on top of each other, so
    one or two of the five legend entries showed (an outside reader of the report)."""
    import feeler.reports.sec_speed as speed

    legends = []
    real = speed.make_figure

    def keep_legend(title, fig, sources, caption=""):
        legends.extend(t.get_text() for leg in fig.legends for t in leg.get_texts())
        return real(title, fig, sources, caption)

    monkeypatch.setattr(speed, "make_figure", keep_legend)
    frame = pd.DataFrame({"option": ["0.5", "0.7", "0.9", "0.99", "end"], "latency_s": [3.36, 3.36, 3.36, 3.36, 9.5],
                          "accuracy": [1.0, 1.0, 1.0, 1.0, 1.0]})
    fig = speed._trade_figure("decoder", frame, "latency_s", "accuracy", "benchmarks/decoder.csv", "measured")
    assert fig.problems == () and "share a marker, named by all of them" in fig.caption
    assert legends == ["0.5, 0.7,\n0.9, 0.99", "end"]
    from feeler.reports.sec_speed import _shared_label
    assert _shared_label(["threshold 0.5", "threshold 0.7", "threshold 0.9"]) == "threshold 0.5, 0.7,\n0.9"
def test_failed_calibration_comes_first(part_run, tmp_path):
    run = part_run("m1", "m4", "psychophysics")
    bad = {"ok": False, "problems": ["pse[0,0]: R-hat 1.2 > 1.01"]}
    (run / "m4/verdict.json").write_text(json.dumps(bad), encoding="utf-8")
    report = build_report(run, tmp_path / "out", pdf=False)
    assert report.failed == ("M4: human psychometric functions (m4/)",)
    html = report.html.read_text(encoding="utf-8")
    assert html.index("FAILED CALIBRATION: M4") < html.index("<section")
    sections = re.findall(r'<section id="([^"]+)"', html)
    assert sections[:2] == ["sec-front", "sec-fit-m4"]
    front = _section_html(html, "sec-front")
    verdicts = front[front.index("Verdict of every fit"):]
    assert verdicts.index("M4: human psychometric functions") < verdicts.index("M1: sensor")
    assert "FAILED: pse[0,0]: R-hat 1.2 &gt; 1.01" in verdicts


def test_a_window_at_an_end_of_its_range_is_noted_in_the_fit_section():
    """The M2 fit's window-edge notes (recorded in its checks) reach the report as notes
    beside the predictive check, one each, with the posterior as their source."""
    from feeler.reports.sec_fits import _ppc_note

    line = "tau_s: leans on its lower prior bound 0.5 (8 % of draws below 0.515): the shortest window"
    attrs = {"ppc_coverage90": 0.93, "ppc_p_value": 0.2, "checks": json.dumps({"window_edge": [line]})}
    notes = _ppc_note(attrs, "neuron/posterior.nc")
    assert [n.text for n in notes[:1]] == [f"Window: {line}."] and len(notes) == 2
    assert all(n.sources == ("neuron/posterior.nc",) for n in notes)
    assert len(_ppc_note({"ppc_coverage90": 0.93}, "p.nc")) == 1


def test_the_neuron_fit_section_says_how_its_training_scans_read(report, run_dir):
    """The demo's M2 section carries the fit's leave-one-out reading, in the words the fit's
    CLI prints, from the figures its posterior records (and with each mode's accuracy when
    the fit decodes by mode)."""
    import html

    import xarray as xr

    from feeler.calib.neuron.fit import reading_text
    attrs = xr.open_datatree(run_dir / "m2" / "posterior.nc")["posterior"].attrs
    reading = json.loads(attrs["loo_reading"])
    assert reading["scans"] == 24 and 0.25 <= reading["base_accuracy"] <= reading["accuracy"] <= 1.0
    page = html.unescape((report / "report.html").read_text(encoding="utf-8"))
    assert f"Leave-one-out reading: {reading_text(reading)}" in page
    by_mode = json.loads(attrs.get("mode_decoders", "{}"))
    for k, v in by_mode.items():
        assert f"{k}s {100 * v['loo']['accuracy']:.0f} % (the most common plate alone" in page


def test_m4_thresholds_never_show_nan():
    """A threshold the lapse keeps most draws from reaching (fit psychophysics --nafc 2 --pc
    0.99: mean NaN, upper end inf) showed "nan" in the report's table; now a bound, and a
    slope or p it cannot give shows a dash."""
    import pandas as pd

    from feeler.reports.m4_extras import _cell

    r = pd.Series({"threshold_um": float("nan"), "threshold_lb_um": 2.625, "threshold_ub_um": float("inf"),
                   "slope_per_um": float("nan"), "gof_p": 0.41, "backend": "nuts"})
    assert _cell(r, "threshold_um") == "> 2.625"
    assert _cell(r, "slope_per_um") == "—" and _cell(r, "backend") == "nuts" and _cell(r, "gof_p") == "0.41"
    assert _cell(pd.Series({**r.to_dict(), "threshold_lb_um": float("nan")}), "threshold_um") == "—"


def test_a_benchmark_table_of_one_round_shows_its_median_alone():
    """The open-world table (one round a scene) ran past the PDF page's right edge: with one
    round, min, mean, q1 and q3 are the median again. With more rounds all are shown."""
    import pandas as pd

    from feeler.reports.sec_speed import table_columns
    one = pd.DataFrame({"benchmark": ["a", "b"], "min_s": [1.0, 2.0], "mean_s": [1.0, 2.0], "rounds": [1, 1],
                        "median_s": [1.0, 2.0], "q1_s": [1.0, 2.0], "q3_s": [1.0, 2.0], "ece": [0.01, 0.02],
                        "measured_at": ["t", "t"]})
    assert table_columns(one) == ["benchmark", "median_s", "ece"]
    many = one.assign(rounds=[1, 5])
    assert table_columns(many) == ["benchmark", "min_s", "mean_s", "rounds", "median_s", "q1_s", "q3_s", "ece"]


def test_m2_says_its_parameters_are_the_decoders_and_m4_why_its_two_tables_differ(report):
    """An outside reader took M2's a, h and τ for the paper's neuron parameters (the scene's
    τ = 3 s lay outside M2's interval), and found M4's summary (from draws) and thresholds
    table (integrated on the grid) disagreeing in the tails with nothing said."""
    import html as html_lib

    html = html_lib.unescape((report / "report.html").read_text(encoding="utf-8"))
    m2 = _section_html(html, "sec-fit-m2")
    assert "not an estimate of the neuron's time constant (the scene's neuron: τ = 3 s)" in m2
    assert "z = a·P − h (mm; a in mm per unit strain), not the paper's gain" in m2
    m4 = _section_html(html, "sec-fit-m4")
    assert "the thresholds table below integrates the posterior itself" in m4 and "Monte Carlo error" in m4
    assert "integrates the posterior itself" not in _section_html(html, "sec-fit-m1")


def test_the_m4_curves_print_at_the_size_they_are_drawn(run_dir):
    """Four a row, the per-subject curves' annotations printed at 3-4 pt (an outside reader):
    the gallery shows them two a row, at the width the fit draws them."""
    from PIL import Image

    from feeler.reports.discover import discover
    from feeler.reports.m4_extras import CURVE_WIDTH_IN, curves_gallery

    inv = discover(run_dir)
    part = next(p for p in inv.parts if p.kind == "fit" and p.model == "m4")
    gallery = curves_gallery(inv, part)
    assert gallery.width_in == CURVE_WIDTH_IN and 2 * CURVE_WIDTH_IN < 7.24      # two a row on A4, 13 mm margins
    png = Image.open(run_dir / gallery.items[0][2])
    assert abs(png.size[0] / png.info.get("dpi", (170, 170))[0] - CURVE_WIDTH_IN) < 0.05
