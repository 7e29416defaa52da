"""Ctrl-C while a report is written: the earlier report.html, report.pdf and manifest stay
a set. Before, a Ctrl-C in the PDF step left a new report.html beside the previous PDF
and manifest, with exit 130 and no word about it."""
from __future__ import annotations

from pathlib import Path

import pytest

from feeler.cli import main

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def sim_run(tmp_path) -> Path:
    """A small simulated robot run holding an earlier report (three files of known text)."""
    scene = tmp_path / "small.toml"
    text = (ROOT / "datasets-synthetic" / "four-plates.toml").read_text(encoding="utf-8")
    scene.write_text(text.replace("scans_per_plate = 24", "scans_per_plate = 3"), encoding="utf-8")
    run = tmp_path / "run"
    assert main(["simulate", str(scene), "--out", str(run), "--no-progress"]) == 0
    for name in ("report.html", "report.pdf", "report-manifest.json"):
        (run / name).write_text(f"earlier {name}", encoding="utf-8")
    return run


def test_ctrl_c_in_the_pdf_leaves_the_earlier_report_as_it_was(sim_run, monkeypatch, capsys):
    import feeler.reports.build as build

    def pdf_interrupted(html, path, progress=lambda stage: None):
        Path(path).write_bytes(b"%PDF-1.7 half a file")
        raise KeyboardInterrupt

    before = sorted(p.name for p in sim_run.iterdir())
    monkeypatch.setattr(build, "write_pdf", pdf_interrupted)
    assert main(["report", str(sim_run), "--no-progress"]) == 130
    for name in ("report.html", "report.pdf", "report-manifest.json"):
        assert (sim_run / name).read_text(encoding="utf-8") == f"earlier {name}"
    assert sorted(p.name for p in sim_run.iterdir()) == before            # no temporary file left
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"feeler: interrupted: no report written to {sim_run} ")
    assert "the earlier report.html, report.pdf, report-manifest.json there are unchanged" in err[0]


def test_a_complete_report_replaces_all_three_and_leaves_no_temporary_file(sim_run, monkeypatch):
    import feeler.reports.build as build

    def pdf(html, path, progress=lambda stage: None):
        Path(path).write_bytes(b"%PDF-1.7 new")
        return (("sec-a",),)

    monkeypatch.setattr(build, "write_pdf", pdf)
    report = build.build_report(sim_run)
    assert report.pdf == sim_run / "report.pdf" and (sim_run / "report.pdf").read_bytes() == b"%PDF-1.7 new"
    assert "<html" in report.html.read_text(encoding="utf-8") and report.n_pages == 1
    assert '"pages": 1' in report.manifest.read_text(encoding="utf-8")
    assert not [p for p in sim_run.iterdir() if p.name.endswith(".partial")]


def test_an_interrupt_during_the_renames_is_held_until_all_are_in_place(tmp_path, monkeypatch):
    import os
    import signal

    from feeler.reports.staged import staged

    before = signal.signal(signal.SIGINT, signal.default_int_handler)     # Ctrl-C raises KeyboardInterrupt
    try:
        with staged(tmp_path) as files:
            files.path("a").write_text("new a")
            files.path("b").write_text("new b")
            real_replace = os.replace

            def replace_then_sigint(src, dst):
                real_replace(src, dst)
                signal.raise_signal(signal.SIGINT)      # as if Ctrl-C came between the two renames

            monkeypatch.setattr(os, "replace", replace_then_sigint)
            try:
                files.install()
            except KeyboardInterrupt:
                pytest.fail("the interrupt split the set: it must be held until every file is in place")
            monkeypatch.undo()
    finally:
        signal.signal(signal.SIGINT, before)
    assert (tmp_path / "a").read_text() == "new a" and (tmp_path / "b").read_text() == "new b"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "b"]
