"""What the (small, shared) demo campaign wrote: every stage's files and logs, the curve
behind the robot's threshold, the trades it measured, and what it printed."""
from __future__ import annotations

import csv
import json

from feeler.cli import main


def test_the_campaign_ran_every_stage(run_dir):
    printed = (run_dir.parent / "printed.txt").read_text(encoding="utf-8")
    for heading in ("M1 —", "M2 —", "held-out", "M3 —", "M4 —", "SYNTHETIC",
                    "measuring small versions now", "skin ladder (two coarse meshes)", "report:"):
        assert heading in printed, heading
    assert {"delta_mm", "pc", "lo95", "hi95"} <= set(json.loads((run_dir / "discriminate/discrimination.json")
                                                             .read_text())["curve"])     # the threshold's own curve
    for fit in ("m1", "m2", "m4", "finger-route"):
        assert json.loads((run_dir / fit / "verdict.json").read_text())["ok"], fit
        assert (run_dir / fit / "posterior.nc").stat().st_size > 0
    for rel in ("classify/classification.csv", "discriminate/discrimination.json", "m4/thresholds.csv",
                "finger/strain.csv", "skin-ladder/trade.csv", "speed/speed.json", "report.pdf"):
        assert (run_dir / rel).is_file(), rel
    assert (run_dir / "logs" / "calibrate-neuron.txt").read_text().startswith("$ feeler calibrate neuron")
    assert "--n-scans 80" in (run_dir / "logs" / "discriminate.txt").read_text()


def test_the_demo_refuses_to_overwrite_before_any_work(run_dir, capsys):
    before = {p: p.stat().st_mtime_ns for p in run_dir.rglob("*") if p.is_file()}
    assert main(["demo", "--out", str(run_dir)]) == 2
    assert "--force" in capsys.readouterr().err
    assert before == {p: p.stat().st_mtime_ns for p in run_dir.rglob("*") if p.is_file()}


def _rows(path):
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def test_trades_measured_during_the_demo_are_labelled(run_dir):
    index = json.loads((run_dir / "speed" / "speed.json").read_text())
    assert index["measured"].startswith("during `feeler demo` at ") and set(index["tables"]) == {"backends", "fidelity", "decoder"}
    backends = _rows(run_dir / "speed" / "backends.csv")
    assert [r["option"] for r in backends] == ["exact, 4 x 1000 draws", "emcee, 400 draws after 200"]
    exact = backends[0]
    assert exact["ok"] == "True" and float(exact["error_ref_sd"]) < 0.2 and float(exact["seconds"]) > 0
    assert [r["option"] for r in _rows(run_dir / "speed" / "fidelity.csv")] == ["displacement", "areas", "images"]
    ladder = json.loads((run_dir / "skin-ladder" / "ladder.json").read_text())
    assert ladder["size"] == "tiny" and ladder["measured"] == index["measured"].split(" (")[0]
    trade = _rows(run_dir / "skin-ladder" / "trade.csv")
    l2 = next(r for r in trade if r["level"] == "l2" and r["mesh"] == "converged")
    assert float(l2["rate_error"]) == 0.0
    assert all(float(r["seconds_per_slide"]) > 0 for r in trade)
