"""Sections an outside review (s49) read page by page: the discrimination file's notes
(item 2), one reading of the PSE column (item 10), the two P(correct) estimands (item 4)."""
from __future__ import annotations

import json

from feeler.reports import discover
from feeler.reports.sec_compare import compare_section
from feeler.reports.sec_robot import robot_section

NOTE = ("note: reference 0.1 mm lies outside the plates the fit was trained on (0.05-0.0725 mm): its threshold "
        "and PSE extrapolate the calibration")


def _spec(inv, key):
    return next(s for s in inv.present if s.key == key)


def _compare(run):
    inv = discover(run)
    return compare_section(inv, _spec(inv, "compare"))


def test_every_note_of_the_discrimination_file_is_shown(copy_run):
    path = copy_run / "discriminate" / "discrimination.json"
    obj = json.loads(path.read_text())
    assert "notes" not in obj or not obj["notes"]                # an old file: nothing to show, no failure
    before = [b.text for b in _compare(copy_run).blocks if b.kind == "note"]
    path.write_text(json.dumps({**obj, "notes": [NOTE, "note: a second one"], "extrapolated": True}))
    section = _compare(copy_run)
    notes = [b for b in section.blocks if b.kind == "note"]
    assert [n.text for n in notes if n.text not in before] == [NOTE, "note: a second one"]
    assert all(n.level == "failed" for n in notes if n.text.startswith("note:"))
    table = next(b for b in section.blocks if b.kind == "table")
    assert table.rows[0][0] == "robot — EXTRAPOLATED (outside the trained plates)"


def test_the_pse_column_reads_the_same_way_for_robot_and_human(run_dir):
    table = next(b for b in _compare(run_dir).blocks if b.kind == "table")
    assert table.columns[-2:] == ("PSE", "PSE is the")
    disc = json.loads((run_dir / "discriminate/discrimination.json").read_text())["pse"]
    robot = table.rows[0]
    assert robot[-1] == (f"height at {disc['speed_test_mm_s']:g} mm/s felt equal to 100 µm at "
                         f"{disc['speed_ref_mm_s']:g} mm/s")
    assert " at " not in robot[-2]                     # the speed moved to its own column
    cross = [r for r in table.rows[1:] if "standard at 40 mm/s vs comparison at 20 mm/s" in r[1]]
    assert cross and all(r[-1] == "height at 20 mm/s felt equal to 10 µm at 40 mm/s" for r in cross)
    assert "Faster feels higher when" in table.caption


def test_the_two_pc_estimands_are_named_and_told_apart(run_dir):
    inv = discover(run_dir)
    robot = robot_section(inv, _spec(inv, "robot:four-plates"))
    pairs = next(b for b in robot.blocks if b.kind == "table" and "adjacent plates" in b.title)
    assert pairs.title.startswith("Empirical 2AFC") and "model-based" in pairs.caption
    m3 = next(b for b in _compare(run_dir).blocks if b.kind == "note" and "pairs of plates" in b.text)
    assert m3.text.startswith("Robot, model-based 2AFC P(correct)") and "'empirical' table" in m3.text


def _ladder(run, converged):
    from feeler.reports.sec_finger import ladder_blocks

    path = run / "skin-ladder" / "ladder.json"
    info = json.loads(path.read_text())
    path.write_text(json.dumps({**info, "met": {**info.get("met", {}), "convergence": converged}}))
    inv = discover(run)
    return ladder_blocks(inv, inv.first("ladder"))


def test_the_ladder_calls_its_finest_mesh_converged_only_when_the_verdict_says_so(copy_run):
    from feeler.reports.finger_plots import ladder_trade

    rows = [("l2", "converged", 0.3, 0.0), ("l1", "converged", 0.002, 0.018), ("l0", "closed form", 2e-4, 0.34)]
    labels = [t.get_text() for t in ladder_trade(rows, converged=False).legends[0].get_texts()]
    assert labels[:2] == ["L2 (finest, reference)", "L1 (finest)"] and not any("converged" in t for t in labels)
    labels = [t.get_text() for t in ladder_trade(rows, converged=True).legends[0].get_texts()]
    assert labels[0] == "L2 (converged) = reference"
    blocks = _ladder(copy_run, False)
    table = next(b for b in blocks if b.kind == "table" and b.title == "Trade table")
    assert not any("converged" in cell for row in table.rows for cell in row)
    assert ("L2", "finest") == table.rows[0][:2] and "NOT met" in table.caption
    table = next(b for b in _ladder(copy_run, True) if b.kind == "table" and b.title == "Trade table")
    assert ("L2", "converged") == table.rows[0][:2]


def test_human_fits_carry_the_synthetic_label_in_text_and_figures(run_dir):
    from feeler.reports.sec_fits import fit_section

    inv = discover(run_dir)
    for key in ("fit:m4", "fit:finger-route"):
        section = fit_section(inv, _spec(inv, key))
        notes = [b for b in section.blocks if b.kind == "note" and b.level == "synthetic"]
        assert notes and notes[0].text.startswith("Fitted to SYNTHETIC human data"), key
        figures = [b for b in section.blocks if b.kind == "figure"]
        assert figures and all("SYNTHETIC" in f.title and f.caption.startswith("SYNTHETIC") for f in figures), \
            [(f.title, f.caption[:40]) for f in figures]


def test_an_estimate_and_its_interval_keep_the_same_significant_figures():
    import numpy as np

    from feeler.reports.model import interval
    from feeler.reports.sec_speed import times

    assert interval(10.8, 10.5, 11.0) == "10.8 [10.5, 11.0]"
    assert interval(9.9, 9.53, 10.3) == "9.90 [9.53, 10.3]"
    assert interval(1.76, 1.49, 2.0) == "1.76 [1.49, 2.00]"
    assert interval(np.float64(0.9963), 0.99, 1.0, 4) == "0.9963 [0.9900, 1.000]"
    assert interval(4.5e-5, 4e-5, 5.1e-5) == "4.50e-05 [4.00e-05, 5.10e-05]"
    assert interval(4000, 3900, float("nan")) == "4000 [3900, –]"
    assert times(1549.3) == "1,549" and times(155.6) == "156" and times(1.957) == "1.96"


def test_the_speed_section_names_the_ladder_mesh_by_its_verdict(copy_run):
    from feeler.reports.sec_speed import speed_section

    _ladder(copy_run, False)
    inv = discover(copy_run)
    note = next(b.text for b in speed_section(inv, _spec(inv, "speed")).blocks
                if b.kind == "note" and b.text.startswith("Skin ladder"))
    assert "(converged)" not in note and "L1 (finest)" in note and "e+" not in note


def test_the_last_pdf_page_is_not_a_lone_caption(report):
    """The demo PDF's last page held one line, the versions table's caption (item 21)."""
    import pypdfium2

    pdf = pypdfium2.PdfDocument(str(report / "report.pdf"))
    last = pdf[len(pdf) - 1].get_textpage().get_text_range()
    lines = [ln for ln in last.splitlines() if ln.strip()]
    assert len(lines) > 3 and "python" in last and "Installed when this report was made" not in last, lines


def test_short_tables_are_kept_on_one_page_and_the_tau_summary_before_its_figure(report):
    import re

    html = (report / "report.html").read_text(encoding="utf-8")
    versions = html[html.index("Package versions, installed"):]
    assert re.match(r"[^<]*(<span[^>]*>[^<]*</span>)?</h3>\s*<table style=\"break-inside: avoid\">", versions)
    route = html[html.index('<section id="sec-fit-finger-route">'):]
    route = route[:route.index("</section>")]
    assert route.index("τ posterior median") < route.index("Accepted against presented step height at the fitted τ")


def test_the_comparisons_last_page_holds_a_whole_figure_not_a_paragraphs_end(report):
    """The demo's last page of this section held only the end of the robot's P(correct)
    paragraph (review s49, item 21): the section ends with the human data figure, which
    is never split, so text before it cannot leave a page to itself."""
    import pypdfium2

    from feeler.reports.build import MANIFEST

    starts = json.loads((report / MANIFEST).read_text(encoding="utf-8"))["page_sections"]
    first = next(i for i, s in enumerate(starts) if "sec-compare" in s)
    last = next((i - 1 for i in range(first + 1, len(starts)) if starts[i]), len(starts) - 1)
    text = pypdfium2.PdfDocument(str(report / "report.pdf"))[last].get_textpage().get_text_range()
    assert "Human 2AFC data and the pooled psychometric functions." in text, text[:300]
