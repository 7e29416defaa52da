"""The outside audit's M4 cases (s43, F2 and F3): too few levels for a curve, and NaN
thresholds or DTs printed with a verdict of ok."""
import math
import re
from types import SimpleNamespace

import numpy as np
import pytest

from feeler.calib.psychometric.model.task import Task
from feeler.calib.psychometric.outputs import checks
from feeler.calib.psychometric.outputs.display import (DASH, UNBOUNDED, shown_columns, threshold_cells,
                                                       threshold_note)
from feeler.cli import main
from feeler.errors import ArgumentError

HEAD = "subject,standard_um,standard_speed_mm_s,comparison_um,comparison_speed_mm_s,n_trials,"
# the audit's inputs (/work/exp/s43/audit/in/)
TWO_LEVELS = HEAD + "n_comparison_higher\nS1,10,20,7.6,20,20,2\nS1,10,20,12.4,20,20,20\n"
NAFC_OK = HEAD + "n_correct\nS1,0,20,0.8,20,20,12\nS1,0,20,1.6,20,20,15\nS1,0,20,2.4,20,20,19\n"
S1 = HEAD + "n_comparison_higher\n" + "".join(
    f"S1,10,20,{x},20,20,{k}\n" for x, k in ((7.6, 2), (8.4, 3), (9.2, 4), (10.0, 10), (10.8, 15), (11.6, 18),
                                            (12.4, 19)))


def _write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def _fit(capsys, path, *extra):
    code = main(["fit", "psychophysics", path, "--no-plots", *extra])
    out, err = capsys.readouterr()
    return code, out, err


# F2: a curve needs three levels, two of them between none and all ------------------------

def test_two_levels_are_too_few_for_location_spread_and_lapse():
    (msg,) = checks.level_problems("S1 [c]", 2, np.array([7.6, 12.4, 7.6]))
    assert "2 tested levels (7.6, 12.4 µm)" in msg and f"at least {checks.MIN_LEVELS}" in msg
    assert "a single tested level (10.8 µm)" in checks.level_problems("S1 [c]", 1, np.array([10.8]))[0]
    assert checks.level_problems("S1 [c]", 3, np.array([7.6, 10.0, 12.4])) == []


def test_one_level_between_none_and_all_does_not_pin_the_spread():
    x, n = np.array([7.6, 8.4, 9.2, 10.8, 11.6]), np.full(5, 20)
    (msg,) = checks.interior_problems("S1 [c]", Task(), x, n, np.array([0, 0, 10, 20, 20]))
    assert "at 1 of the 5 tested levels (only at 9.2 µm)" in msg and "spread is not pinned down" in msg
    assert checks.interior_problems("S1 [c]", Task(), x, n, np.array([0, 3, 10, 20, 20])) == []
    # cells at one level are pooled: 0/10 and 10/10 at 8.4 µm make one level in between
    x2, n2 = np.array([7.6, 8.4, 8.4, 9.2, 12.4]), np.array([20, 10, 10, 20, 20])
    assert checks.interior_problems("S1 [c]", Task(), x2, n2, np.array([0, 0, 10, 10, 20])) == []


def test_cli_two_levels_fail_the_verdict_naming_the_levels(tmp_path, capsys):
    code, out, _ = _fit(capsys, _write(tmp_path, "p_twolevels.csv", TWO_LEVELS))
    assert code == 1 and "verdict: FAILED" in out and "verdict: ok" not in out
    assert "S1 [10 um, 20/20 mm/s]: 2 tested levels (7.6, 12.4 µm), and the curve needs at least 3" in out


# F3: no NaN with exit 0 -----------------------------------------------------------------

@pytest.mark.parametrize("nafc, pc, ok", [(2, 0.5, False), (2, 0.51, True), (4, 0.25, False), (4, 0.3, True),
                                          (None, 0.01, True), (None, 0.0, False), (None, 1.0, False),
                                          (2, math.nan, False), (2, True, False)])
def test_pc_must_lie_between_the_guess_rate_and_one(nafc, pc, ok):
    if ok:
        assert Task(nafc).check_pc(pc, "--pc") == pc
        return
    with pytest.raises(ArgumentError, match=r"--pc="):
        Task(nafc).check_pc(pc, "--pc")


def test_cli_pc_at_the_guess_rate_is_refused_before_reading(tmp_path, capsys):
    code, out, err = _fit(capsys, _write(tmp_path, "p_nafc_ok.csv", NAFC_OK), "--nafc", "2", "--pc", "0.5")
    lines = [ln for ln in err.splitlines() if ln.startswith("feeler:")]
    assert code == 2 and out == "" and "reading" not in err and len(lines) == 1
    assert "--pc=0.5" in lines[0] and "(0.5, 1)" in lines[0] and "1/2" in lines[0]


def _stats(mean, lb, ub, median, unreached, lapse_ub=0.136):
    return {"threshold": {"mean": mean, "lb": lb, "ub": ub, "median": median, "unreached": unreached},
            "lapse": {"mean": 0.05, "lb": 0.007, "ub": lapse_ub, "median": 0.05}}


def test_a_threshold_without_a_finite_bound_fails_the_verdict():
    (msg,) = checks.threshold_problems("S1 [c]", Task(), 0.999, _stats(np.nan, np.inf, np.inf, np.inf, 0.998))
    assert "99.8 % of the posterior never reaches P = 0.999" in msg and "1 − λ/2" in msg
    assert "--pc <= 0.932" in msg                                   # 1 − 0.136/2, rounded down
    assert checks.threshold_problems("S1 [c]", Task(2), 0.99, _stats(np.nan, 2.6, np.inf, np.inf, 0.856)) == []
    assert checks.threshold_problems("S1 [c]", Task(), 0.75, _stats(10.7, 10.3, 11.2, 10.7, 0.0)) == []
    (low,) = checks.threshold_problems("S1 [c]", Task(), 0.01, _stats(np.nan, 9.0, np.inf, 12.0, 0.86))
    assert "P stays above 0.01" in low and "--pc >= 0.068" in low   # the floor λ/2 at the lapse's ub


def _row(mean, lb, ub, median, unreached, design="2AFC", pc=0.99, slope=np.nan):
    return SimpleNamespace(threshold_um=mean, threshold_lb_um=lb, threshold_ub_um=ub, threshold_median_um=median,
                           threshold_unreached=unreached, slope_per_um=slope, design=design, pc=pc, subject="S1",
                           standard_speed_mm_s=20.0, comparison_speed_mm_s=20.0)


def test_threshold_cells_show_estimates_bounds_or_a_dash_never_nan():
    est = threshold_cells(_row(1.569, 0.968, 2.145, 1.56, 0.0, slope=0.431))
    assert est == {"threshold_um": "1.569", "threshold_lb_um": "0.968", "threshold_ub_um": "2.145",
                   "slope_per_um": "0.431"}
    bound = threshold_cells(_row(np.nan, 2.625, np.inf, np.inf, 0.856))
    assert bound["threshold_um"] == "> 2.625" and bound["slope_per_um"] == DASH
    assert bound["threshold_ub_um"] == UNBOUNDED == "unbounded"               # printed 'inf' (review s49)
    assert "is a bound, > 2.625 µm: 85.6 % of the posterior never reaches P = 0.99" in \
        threshold_note(_row(np.nan, 2.625, np.inf, np.inf, 0.856))
    assert threshold_cells(_row(np.nan, 2.1, 3.0, 2.4, 0.01))["threshold_um"] == "2.400"      # the median
    assert set(threshold_cells(_row(np.nan, np.inf, np.inf, np.inf, 0.998)).values()) == {DASH}
    assert set(threshold_cells(_row(np.nan, 9.0, np.inf, 12.0, 0.86, "comparison", 0.01)).values()) == {DASH}
    assert threshold_note(_row(1.569, 0.968, 2.145, 1.56, 0.0)) == ""


def test_nafc_tables_leave_out_the_dt_columns():
    import pandas as pd
    cols = ["subject", "pse_um", "dt_um", "dt_lb_um", "dt_ub_um", "threshold_um"]
    assert shown_columns(pd.DataFrame({"design": ["2AFC", "2AFC"]}), cols) == ["subject", "pse_um", "threshold_um"]
    assert shown_columns(pd.DataFrame({"design": ["comparison"]}), cols) == cols


def _table_rows(out):
    return [ln.split() for ln in out.splitlines() if re.match(r"\s+(S1|all)\s+\d", ln)]


def test_cli_nafc_prints_no_dt_and_no_nan(tmp_path, capsys):
    code, out, _ = _fit(capsys, _write(tmp_path, "p_nafc_ok.csv", NAFC_OK), "--nafc", "2")
    assert code == 0 and "verdict: ok" in out and "NaN" not in out and "nan" not in out
    assert "dt_um" not in out and "no DT in nAFC" in out and len(_table_rows(out)) == 2


def test_cli_pc_beyond_the_lapse_ceiling_fails_without_nan(tmp_path, capsys):
    code, out, _ = _fit(capsys, _write(tmp_path, "p_s1.csv", S1), "--pc", "0.999")
    assert code == 1 and "verdict: FAILED" in out and "NaN" not in out and "nan" not in out
    assert "S1 [10 um, 20/20 mm/s]: the threshold at P = 0.999 is not pinned down" in out and "--pc <=" in out


def test_cli_pc_most_draws_never_reach_is_a_bound(tmp_path, capsys):
    """The bound's upper end is printed 'unbounded', not 'inf'; thresholds.csv keeps inf,
    the number a program reads back (review s49)."""
    import pandas as pd

    code, out, _ = _fit(capsys, _write(tmp_path, "p_nafc_ok.csv", NAFC_OK), "--nafc", "2", "--pc", "0.99",
                        "--out", str(tmp_path / "fit"))
    assert code == 0 and "NaN" not in out and "nan" not in out and not re.search(r"\binf\b", out)
    rows = _table_rows(out)
    assert len(rows) == 2 and all(r[7] == ">" and r[9] == r[8] and r[10] == UNBOUNDED and r[11] == DASH
                                  for r in rows)
    csv = pd.read_csv(tmp_path / "fit" / "thresholds.csv")
    assert np.all(csv["threshold_ub_um"] == np.inf) and np.all(np.isfinite(csv["threshold_lb_um"]))
    assert re.search(r"note: S1 at 20/20 mm/s: the threshold at P = 0\.99 is a bound, > \d+\.\d{3} µm: "
                     r"\d+\.\d % of the posterior never reaches P = 0\.99", out)


def test_cli_pc_below_the_lapse_floor_fails_without_nan(tmp_path, capsys):
    code, out, _ = _fit(capsys, _write(tmp_path, "p_s1.csv", S1), "--pc", "0.01")
    assert code == 1 and "NaN" not in out and "nan" not in out and "P stays above 0.01" in out


def test_cli_one_level_in_the_transition_fails_the_verdict(tmp_path, capsys):
    steep = HEAD + "n_comparison_higher\n" + "".join(
        f"S1,10,20,{x},20,20,{k}\n" for x, k in ((7.6, 0), (8.4, 0), (9.2, 10), (10.8, 20), (11.6, 20)))
    code, out, _ = _fit(capsys, _write(tmp_path, "steep.csv", steep))
    assert code == 1 and "at 1 of the 5 tested levels (only at 9.2 µm)" in out


def test_fit_refuses_pc_at_the_guess_rate_before_fitting(tmp_path):
    from feeler.calib.psychometric.fit import fit_psychometric
    from feeler.psydata import read_trials

    trials = read_trials(_write(tmp_path, "p_nafc_ok.csv", NAFC_OK))
    with pytest.raises(ArgumentError, match=r"pc=0\.25: proportion correct must be in \(1/4, 1\)"):
        fit_psychometric(trials, rng=np.random.default_rng(0), nafc=4, pc=0.25)


def test_curve_text_shows_the_bound_not_nan(tmp_path, capsys, monkeypatch):
    import matplotlib.figure

    # the numbers stand in a block under the axes (Figure.text), where they hide no data
    texts, text = [], matplotlib.figure.Figure.text
    monkeypatch.setattr(matplotlib.figure.Figure, "text", lambda self, x, y, s, *a, **k: (texts.append(s),
                                                                                          text(self, x, y, s, *a, **k))[1])
    path = _write(tmp_path, "p_nafc_ok.csv", NAFC_OK)
    assert main(["fit", "psychophysics", path, "--nafc", "2", "--pc", "0.99", "--out", str(tmp_path / "o")]) == 0
    capsys.readouterr()
    assert len(texts) == 2 and all("threshold@0.99 > " in t and "slope —/µm" in t for t in texts)
    assert not any("nan" in t.lower() for t in texts)
