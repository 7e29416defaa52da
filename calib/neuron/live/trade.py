"""Decision latency against accuracy of the live decoder, over decision thresholds.

Each scan is streamed once through a :class:`~feeler.calib.neuron.live.LiveDecoder`; per
sample its rule inputs are kept (response past its peak; top plate and its probability).
The decision at threshold θ is the decoder's own rule applied to the recorded pass
(:func:`decision_index`): the first unflagged sample where the peak has passed and the
top plate, not the lowest one, has probability ≥ θ; else the scan's last sample if the
scan is not flagged and its top plate then has probability ≥ θ; else none. Per θ: accuracy = correct
decisions / all scans (undecided counts as wrong), the fraction decided, the accuracy of
the decisions made, and the median latency since the stage passed the step, in s and mm.
"""
from __future__ import annotations

import numpy as np

__all__ = ["record_pass", "decision_index", "trade_rows", "end_row", "demo_table"]


def record_pass(dec, t_s, uy_mm, x_mm) -> np.ndarray:
    """One scan through ``dec``: ndarray[n, 8] of (peaked, top p, top plate mm, t s, x mm,
    top plate's index, flagged so far, flagged at the end)."""
    dec.reset()
    out = np.empty((len(t_s), 8))
    for k, (t, uy, x) in enumerate(zip(t_s, uy_mm, x_mm)):
        s = dec.push(t, uy, x_mm=x)
        j = int(np.argmax(s.prob))
        out[k, :7] = (s.peaked, s.prob[j], dec.plates_mm[j], t, x, j, bool(s.flags))
    out[:, 7] = bool(dec.finish().flags)
    return out


def decision_index(r: np.ndarray, threshold: float) -> int | None:
    """The sample a recorded pass (:func:`record_pass`) is decided at, or None."""
    ok = np.flatnonzero((r[:, 0] > 0) & (r[:, 1] >= threshold) & (r[:, 5] > 0) & (r[:, 6] == 0))
    if ok.size:
        return int(ok[0])
    return r.shape[0] - 1 if r[-1, 1] >= threshold and r[-1, 7] == 0 else None


def _t_step(step_x_mm, t, x):
    return float(np.interp(step_x_mm, x, t)) if x[-1] >= x[0] else float(np.interp(-step_x_mm, -x, t))


def trade_rows(passes, step_mm, step_x_mm: float, thresholds, *, label: str = "") -> list[dict]:
    """Rows (option, threshold, latency_s, latency_mm, accuracy, decided, accuracy_decided)
    of recorded ``passes`` (list of :func:`record_pass`) of scans labelled ``step_mm``
    (ndarray[n_scans], mm) whose step lies at stage position ``step_x_mm`` (mm)."""
    rows = []
    for th in thresholds:
        hit, lat_s, lat_mm = [], [], []
        for r, step in zip(passes, step_mm):
            i = decision_index(r, th)
            if i is None:
                hit.append(False)
                continue
            hit.append(bool(np.isclose(r[i, 2], step)))
            lat_s.append(r[i, 3] - _t_step(step_x_mm, r[:, 3], r[:, 4]))
            lat_mm.append(abs(r[i, 4] - step_x_mm))
        rows.append({"option": f"{label}threshold {th:g}", "threshold": float(th),
                     "latency_s": float(np.median(lat_s)) if lat_s else np.nan,
                     "latency_mm": float(np.median(lat_mm)) if lat_mm else np.nan,
                     "accuracy": float(np.mean(hit)), "decided": len(lat_s) / len(passes),
                     "accuracy_decided": float(np.sum(hit) / len(lat_s)) if lat_s else np.nan})
    return rows


def end_row(passes, step_mm, step_x_mm: float) -> dict:
    """The row of deciding at the end of each scan (what ``classify`` answers)."""
    hit = [bool(np.isclose(r[-1, 2], s)) for r, s in zip(passes, step_mm)]
    lat_s = [r[-1, 3] - _t_step(step_x_mm, r[:, 3], r[:, 4]) for r in passes]
    return {"option": "end of scan (classify)", "threshold": np.nan, "latency_s": float(np.median(lat_s)),
            "latency_mm": float(np.median([abs(r[-1, 4] - step_x_mm) for r in passes])),
            "accuracy": float(np.mean(hit)), "decided": 1.0, "accuracy_decided": float(np.mean(hit))}


def demo_table(fit_dir, run_dir, path, *, thresholds=(0.5, 0.7, 0.9, 0.99), n_draws: int = 100) -> str:
    """The trade on a run's scans (``run_dir`` with ``scene.toml`` and labelled scans),
    decoded with the fit in ``fit_dir``; written to ``path`` (CSV). Returns its caption."""
    import pandas as pd

    from feeler.calib.fit import load
    from feeler.calib.neuron.live import LiveDecoder
    from feeler.calib.neuron.live.scan_csv import read_scan_records
    from feeler.scene import load_scene

    step_x = float(load_scene(f"{run_dir}/scene.toml").surface.position_mm)
    records = read_scan_records(run_dir)
    dec = LiveDecoder(load(fit_dir), seed=0, n_draws=n_draws)
    passes = [record_pass(dec, r.t_s, r.uy_mm, r.x_mm) for r in records]
    steps = np.array([r.step_mm for r in records], float)
    rows = trade_rows(passes, steps, step_x, thresholds) + [end_row(passes, steps, step_x)]
    pd.DataFrame(rows).to_csv(path, index=False)
    return (f"Live decoder on the {len(records)} held-out scans ({n_draws} draws): a scan is decided once its "
            "response has passed its peak and the top plate's probability reaches the threshold; latency = median "
            "time since the stage passed the step; accuracy counts undecided scans as wrong.")
