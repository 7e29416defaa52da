"""The latency/accuracy table (demo and benchmark): the rule on a recorded pass is the
decoder's own decision, and the table's rows are consistent."""

import numpy as np
import pandas as pd

from feeler.calib.neuron.live import LiveDecoder
from feeler.calib.neuron.live.trade import decision_index, demo_table, record_pass, trade_rows
from feeler.calib.neuron.synth import FOUR_PLATES
from feeler.cli import main


def test_recorded_pass_reproduces_the_decoders_decisions(small_fit):
    data, res = small_fit
    x = np.asarray(data.t_s) * 0.5
    for th in (0.6, 0.99):
        dec = LiveDecoder(res, n_draws=40, threshold=th)
        for k in (0, 40, 90):
            r = record_pass(dec, data.t_s, data.strain[k] * dec.length_mm, x)
            d = dec.finish().decision
            assert (None if d is None else d.index) == decision_index(r, th)


def test_demo_table_on_a_simulated_run(fit_dir, tmp_path):
    run = tmp_path / "held-out"
    assert main(["simulate", str(FOUR_PLATES), "--out", str(run)]) == 0
    scans = pd.read_csv(run / "scans.csv")
    scans[scans.scan_id % 12 == 0].to_csv(run / "scans.csv", index=False)        # 8 scans, 2 per plate
    caption = demo_table(fit_dir, run, tmp_path / "decoder.csv", thresholds=(0.5, 0.9), n_draws=30)
    t = pd.read_csv(tmp_path / "decoder.csv")
    assert list(t.option) == ["threshold 0.5", "threshold 0.9", "end of scan (classify)"] and "held-out" in caption
    assert {"latency_s", "accuracy"} <= set(t.columns)
    assert (t.accuracy <= t.decided + 1e-12).all() and t.decided.iloc[0] >= t.decided.iloc[1]
    assert (t.latency_s.iloc[:2] <= t.latency_s.iloc[2]).all()      # no decision after the scan's end
    assert t.accuracy.iloc[2] == 1.0 and t.accuracy.iloc[0] >= 0.75


def test_trade_rows_by_hand():
    # two scans: peaked from sample 2; the first reaches p 0.95 on the right plate, the second 0.7 on a wrong one
    # (plates 0, 0.1, 0.2): the first reaches p 0.95 on the right plate, the second 0.7 on a wrong one
    t = np.arange(5.0)
    r1 = np.column_stack([[0, 0, 1, 1, 1], [0.5, 0.6, 0.95, 0.95, 0.95], [0.1] * 5, t, t, [1] * 5, [0] * 5, [0] * 5])
    r2 = np.column_stack([[0, 0, 1, 1, 1], [0.5, 0.6, 0.7, 0.7, 0.7], [0.2] * 5, t, t, [2] * 5, [0] * 5, [0] * 5])
    rows = trade_rows([r1, r2], np.array([0.1, 0.1]), 1.0, (0.6, 0.9))
    assert rows[0]["decided"] == 1.0 and rows[0]["accuracy"] == 0.5 and rows[0]["latency_s"] == 1.0
    assert rows[1]["decided"] == 0.5 and rows[1]["accuracy"] == 0.5 and rows[1]["accuracy_decided"] == 1.0
    # the lowest plate (index 0) is decided only at the scan's end
    low = np.column_stack([[0, 0, 1, 1, 1], [0.5, 0.6, 0.95, 0.95, 0.95], [0.0] * 5, t, t, [0] * 5, [0] * 5, [0] * 5])
    assert decision_index(low, 0.9) == 4 and decision_index(low, 0.99) is None
    assert decision_index(r1, 0.9) == 2
    flagged = r1.copy()
    flagged[:3, 6] = 1                                  # flagged until sample 3; at the end too
    assert decision_index(flagged, 0.9) == 3
    flagged[:, 6:] = 1
    assert decision_index(flagged, 0.5) is None
