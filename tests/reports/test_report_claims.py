"""The first page's claims: each mark's branch on inputs made to land in it, bounds shown
as bounds, and the claims of the demo run traced to its files."""
from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from feeler.reports import discover
from feeler.reports.claims import claim_jump_ratio, claim_rate_vs_z, paper_claims
from feeler.reports.claims_human import claim_faster_felt_higher, claim_tau, claim_threshold
from feeler.reports.discdata import estimate

SEED = 20040616


def _robot_inv(tmp_path, steps, jump, rate, z):
    """An inventory whose robot part holds the given per-scan features."""
    (tmp_path / "scans").mkdir(parents=True)
    (tmp_path / "scans" / "scans.csv").write_text("scan_id\n0\n", encoding="utf-8")
    inv = discover(tmp_path)
    part = inv.first("robot")
    step = np.asarray(steps, float)
    inv.cache[("robot", part.rel)] = SimpleNamespace(part=part, scans=SimpleNamespace(step_mm=step),
                                                     steps=sorted(set(step.tolist())), jump_uy_mm=np.asarray(jump),
                                                     peak_rate_uy_mm_s=np.asarray(rate), peak_z=np.asarray(z))
    return inv


def _plates(n=24, plates=(0.0, 0.05, 0.1, 0.2)):
    return np.repeat(plates, n)


@pytest.mark.parametrize("scale, noise, mark", [((1, 2, 4), 0.002, "reproduced"), ((1, 2, 5), 0.002, "reproduced"),
                                                ((1, 2, 7), 0.002, "not reproduced"),
                                                ((1, 3, 2), 0.002, "not reproduced"),
                                                ((1, 2, 4), 0.04, "inconclusive")])
def test_jump_ratio_marks(tmp_path, scale, noise, mark):
    steps = _plates()
    means = {0.0: 0.0, 0.05: 0.05 * scale[0], 0.1: 0.05 * scale[1], 0.2: 0.05 * scale[2]}
    jump = np.array([means[s] for s in steps]) + np.random.default_rng(SEED).normal(0, noise, steps.size)
    claim = claim_jump_ratio(_robot_inv(tmp_path, steps, jump, jump, jump))
    assert claim.mark == mark, claim.run
    assert claim.sources == ("scans/scans.csv",)


@pytest.mark.parametrize("rate_gap, z_gap, mark", [(0.1, 5.0, "reproduced"), (3.0, 5.0, "not reproduced"),
                                                   (0.1, 0.05, "not reproduced"), (0.5, 0.9, "inconclusive")])
def test_rate_against_z_marks(tmp_path, rate_gap, z_gap, mark):
    steps = _plates(n=40)
    noise = np.random.default_rng(SEED).normal(0, 1, (2, steps.size))
    level = np.select([steps == 0.05, steps == 0.1], [0.0, 1.0], 2.0)
    rate, z = level * rate_gap + noise[0], level * z_gap + noise[1]
    claim = claim_rate_vs_z(_robot_inv(tmp_path, steps, steps, rate, z))
    assert claim.mark == mark, claim.run
    assert claim.run.startswith("0.05 vs 0.1 mm: U̇_y peak ")


@pytest.mark.parametrize("n", [1, 4])
def test_a_few_scans_a_plate_are_inconclusive_not_a_verdict(tmp_path, n):
    """An emulated run of one scan a plate showed 'U̇_y peak 1 [1, 1], peak z 1 [1, 1]
    (1 + 1 scans)' marked NOT REPRODUCED (an outside audit): a bootstrap over one pair
    is no interval. The same data with 5 scans a plate, every pair told apart, bound
    P(correct) below only at 0.025^(1/5) = 0.48: still inconclusive; with 15 (0.78), a mark."""
    steps = _plates(n=n)
    level = np.select([steps == 0.05, steps == 0.1], [0.0, 1.0], 2.0)
    for claim in (claim_jump_ratio(_robot_inv(tmp_path / "j", steps, steps, steps, steps)),
                  claim_rate_vs_z(_robot_inv(tmp_path / "r", steps, steps, level * 3.0, level * 5.0))):
        assert claim.mark == "inconclusive", claim.run
        assert claim.run.startswith(f"too few scans for an interval ({n} + {n}") and "at least 5 a plate" in claim.run
    for n, mark in ((5, "inconclusive"), (15, "not reproduced")):
        steps = _plates(n=n)
        level = np.select([steps == 0.05, steps == 0.1], [0.0, 1.0], 2.0)
        claim = claim_rate_vs_z(_robot_inv(tmp_path / f"r{n}", steps, steps, level * 3.0, level * 5.0))
        assert claim.mark == mark, (n, claim.run)


def test_claims_without_data_say_what_they_need(tmp_path):
    claims = paper_claims(discover(tmp_path))
    assert [c.mark for c in claims] == ["not in this run"] * len(claims)
    assert all(c.run.startswith("needs ") for c in claims)


def _tau_inv(tmp_path, p, ok=None):
    d = tmp_path / "route"
    d.mkdir(exist_ok=True)
    (d / "tau_report.json").write_text(json.dumps({"tau_median_s": 0.135, "tau_eti95_s": [0.119, 0.16],
                                                   "p_tau_le_300ms": p, "skin_level": "l0"}), encoding="utf-8")
    if ok is not None:
        (d / "verdict.json").write_text(json.dumps({"ok": ok, "problems": [] if ok else ["tau_s: R-hat 1.3"]}))
    return discover(tmp_path)


@pytest.mark.parametrize("p, ok, mark", [(0.999, True, "reproduced"), (0.01, True, "not reproduced"),
                                         (0.5, True, "inconclusive"), (0.999, False, "inconclusive"),
                                         (0.999, None, "reproduced")])
def test_tau_marks(tmp_path, p, ok, mark):
    claim = claim_tau(_tau_inv(tmp_path, p, ok))
    assert claim.mark == mark and claim.run.startswith("τ 135 [119, 160] ms")
    assert ("FAILED" in claim.run) == (ok is False)


def _disc_inv(tmp_path, threshold, weber=None):
    d = tmp_path / "disc"
    d.mkdir(exist_ok=True)
    obj = {"pairs": [], "reference_mm": 0.1, "threshold_mm": threshold,
           "weber": weber or {"mean": 0.05, "lo95": 0.04, "hi95": 0.06}}
    (d / "discrimination.json").write_text(json.dumps(obj), encoding="utf-8")
    return discover(tmp_path)


@pytest.mark.parametrize("threshold, mark, text", [
    ({"mean": 0.0044, "lo95": 0.0042, "hi95": 0.0046, "found": 1.0}, "reproduced", "4.4 [4.2, 4.6] µm"),
    ({"mean": 0.06, "lo95": 0.055, "hi95": 0.07, "found": 1.0}, "not reproduced", "60 [55, 70] µm"),
    ({"mean": 0.04, "lo95": 0.03, "hi95": 0.06, "found": 1.0}, "inconclusive", "40 [30, 60] µm"),
    ({"mean": 0.02, "lo95": 0.018, "hi95": 0.024, "found": 0.4}, "inconclusive",
     "> 18 µm (60 % of draws never reach 75 %)"),
    ({"mean": "> 0.025", "lo95": None, "hi95": None, "found": 0.3}, "inconclusive", "> 25 µm"),
    ({"mean": "> 0.06", "found": 0.1}, "not reproduced", "> 60 µm (90 % of draws never reach 75 %)"),
])
def test_robot_threshold_marks_and_bounds(tmp_path, threshold, mark, text):
    claim = claim_threshold(_disc_inv(tmp_path, threshold))
    assert claim.mark == mark and claim.run.startswith(text), claim.run


def test_estimate_reads_bounds_and_fractions():
    assert estimate({"mean": "≥ 2.5", "found": 0.2}).bound == ">"
    e = estimate({"mean": 0.01, "lo95": 0.008, "hi95": float("nan"), "found": 0.9, "max_delta_mm": 0.025})
    assert (e.bound, e.value) == (">", 0.025) and e.scaled(1e3).text(3, "µm").startswith("> 25 µm (10 %")
    assert estimate({"mean": 0.01, "lo95": 0.008, "hi95": 0.012, "found": 0.99}).bound == ""


def _thresholds_inv(tmp_path, pse, lo, hi, extra=""):
    d = tmp_path / "m4"
    d.mkdir(exist_ok=True)
    (d / "thresholds.csv").write_text(
        f"subject,standard_um,standard_speed_mm_s,comparison_speed_mm_s,pse_um,pse_lb_um,pse_ub_um,dt_um,dt_lb_um,"
        f"dt_ub_um,backend,pc,slope{extra and ',' + extra}\n"
        f"all,10,20,20,10,9.8,10.2,1.0,0.9,1.2,laplace,0.75,0.4{extra and ',1'}\n"
        f"all,10,40,20,{pse},{lo},{hi},1.7,1.4,2.0,laplace,0.75,0.3{extra and ',1'}\n", encoding="utf-8")
    return discover(tmp_path)


@pytest.mark.parametrize("pse, lo, hi, mark", [(10.7, 10.5, 11.0, "reproduced"), (9.5, 9.2, 9.8, "not reproduced"),
                                               (10.1, 9.8, 10.4, "inconclusive")])
def test_faster_felt_higher_marks(tmp_path, pse, lo, hi, mark):
    claim = claim_faster_felt_higher(_thresholds_inv(tmp_path, pse, lo, hi, extra="new_column"))
    assert claim.mark == mark and claim.run.startswith(f"PSE of 10 µm at 40 mm/s against 20 mm/s: {pse:#.3g} [")


def test_the_demo_claims_come_from_its_files(run_dir):
    inv = discover(run_dir)
    claims = {c.key: c for c in paper_claims(inv)}
    assert set(claims) == {"jump", "rate-vs-z", "fig5-linear", "fig5-speed", "felt-higher", "tau",
                           "robot-threshold", "weber"}
    assert all(c.mark != "not in this run" for c in claims.values())
    rep = json.loads((run_dir / "finger-route/tau_report.json").read_text())
    assert claims["tau"].run.startswith(f"τ {rep['tau_median_s'] * 1e3:.3g} [")
    # the finger's speed effect at τ = 300 ms is a fraction of a per cent: not the paper's Fig. 5
    speed = claims["fig5-speed"]
    assert speed.mark == "not reproduced" and "at 10 ms" in speed.run
    assert claims["weber"].mark == "finding" and "SYNTHETIC" in claims["weber"].run
    for c in claims.values():
        assert all((run_dir / s).is_file() for s in c.sources), c
