"""Trial tables → flat cell arrays, and the numpy log-likelihood every backend shares.

A *condition* is one (standard_um, standard_speed_mm_s, comparison_speed_mm_s) triple; a
*cell* is one row of the aggregated table (subject, condition, comparison height, n
trials, k responses counted: "comparison higher" or, in nAFC, "correct"). The fits use
:meth:`Cells.canonical`: zero-trial rows, and subjects and conditions without any trial,
are dropped, and the rows sorted, so that a fit cannot depend on row order or on
zero-trial rows.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.special import betaln, gammaln

from feeler.calib.psychometric.model.priors import Priors
from feeler.calib.psychometric.model.task import COMPARISON, Task
from feeler.errors import ArgumentError

__all__ = ["Cells", "Priors", "make_cells", "log_lik_cells", "POOLED", "COUNT_COLUMNS"]

POOLED = "all"  # the subject label of pooled estimates in outputs
COUNT_COLUMNS = {"comparison": "n_comparison_higher", "nafc": "n_correct"}


@dataclass(frozen=True)
class Cells:
    """Flat arrays, one entry per row.

    Attributes:
        subjects (tuple[str, ...]): subject labels (index order).
        conditions (tuple[tuple[float, float, float], ...]): (standard_um,
            standard_speed_mm_s, comparison_speed_mm_s) per condition index.
        subject, condition (ndarray[n_cells] int): indices.
        x_um (ndarray[n_cells]): comparison heights, µm.
        n, k (ndarray[n_cells] float): trials and responses counted.
        task (Task): comparison design or nAFC.
    """
    subjects: tuple
    conditions: tuple
    subject: np.ndarray
    condition: np.ndarray
    x_um: np.ndarray
    n: np.ndarray
    k: np.ndarray
    task: Task = field(default=COMPARISON)

    @property
    def standard_um(self) -> np.ndarray:
        """Standard height per condition, µm (ndarray[n_conditions])."""
        return np.array([c[0] for c in self.conditions])

    def condition_label(self, c: int) -> str:
        """``10 um, 20/20 mm/s``: standard and the two speeds of condition ``c``."""
        std, vs, vc = self.conditions[c]
        return f"{std:g} um, {vs:g}/{vc:g} mm/s"

    def attrs(self) -> dict[str, str]:
        """Labels stored with the posterior so outputs can be rebuilt after loading."""
        return {"subjects": json.dumps(list(self.subjects)),
                "conditions": json.dumps([list(c) for c in self.conditions]),
                "n_alternatives": json.dumps(self.task.n_alternatives)}

    def _replace(self, keep: np.ndarray, subjects: tuple, sub: np.ndarray, conditions=None,
                 cond=None) -> "Cells":
        return Cells(subjects, self.conditions if conditions is None else conditions, sub,
                     self.condition[keep] if cond is None else cond, self.x_um[keep], self.n[keep],
                     self.k[keep], self.task)

    def select(self, mask: np.ndarray, subjects: tuple) -> "Cells":
        """The cells of ``mask`` with subjects relabelled to ``subjects`` (index 0..)."""
        codes = {s: i for i, s in enumerate(subjects)}
        sub = np.array([codes[self.subjects[i]] for i in self.subject[mask]], dtype=int)
        return self._replace(mask, subjects, sub)

    def pooled(self) -> "Cells":
        """Every subject's trials as one observer labelled :data:`POOLED`: the rows of
        equal (condition, level) merged (their counts added), sorted."""
        key = np.stack([self.condition.astype(float), self.x_um])
        uniq, inv = np.unique(key, axis=1, return_inverse=True)
        n, k = np.zeros(uniq.shape[1]), np.zeros(uniq.shape[1])
        np.add.at(n, inv.ravel(), self.n)
        np.add.at(k, inv.ravel(), self.k)
        return Cells((POOLED,), self.conditions, np.zeros(uniq.shape[1], dtype=int),
                     uniq[0].astype(int), uniq[1], n, k, self.task)

    def canonical(self) -> "Cells":
        """Rows with trials only, sorted by (subject, condition, x, n, k); subjects and
        conditions without any trial dropped (order of first appearance kept).

        Raises:
            ArgumentError: no row has a trial.
        """
        keep = self.n > 0
        if not keep.any():
            raise ArgumentError("trials", "every row has n_trials = 0", "needs at least one trial")
        subs = [i for i in dict.fromkeys(self.subject[keep].tolist())]
        conds = sorted(set(self.condition[keep].tolist()))
        s_map, c_map = {s: i for i, s in enumerate(subs)}, {c: i for i, c in enumerate(conds)}
        sub = np.array([s_map[s] for s in self.subject[keep]], dtype=int)
        cond = np.array([c_map[c] for c in self.condition[keep]], dtype=int)
        out = self._replace(keep, tuple(self.subjects[i] for i in subs), sub,
                            tuple(self.conditions[c] for c in conds), cond)
        order = np.lexsort((out.k, out.n, out.x_um, out.condition, out.subject))
        return out._replace(order, out.subjects, out.subject[order], out.conditions, out.condition[order])


def make_cells(trials: pd.DataFrame, task: Task | None = None) -> Cells:
    """Encode a validated trial table (see :func:`feeler.psydata.read_trials`), row for row.

    Args:
        trials: aggregated table with ``n_comparison_higher`` (comparison design) or
            ``n_correct`` (nAFC) counts.
        task: the nAFC :class:`Task` for ``n_correct`` data; None or the comparison task
            for ``n_comparison_higher`` data.
    Raises:
        ArgumentError: empty table, the reserved subject label, or a task that does not
            match the counts.
    """
    if len(trials) == 0:
        raise ArgumentError("trials", "empty table", "needs at least one row")
    nafc_data = COUNT_COLUMNS["nafc"] in trials.columns
    if nafc_data and (task is None or not task.is_nafc):
        raise ArgumentError("nafc", None, "nAFC data (column n_correct) need the number of "
                                          "alternatives (--nafc N)")
    if not nafc_data and task is not None and task.is_nafc:
        raise ArgumentError("nafc", task.n_alternatives, "the data count 'comparison judged higher' "
                                                         "(a comparison design); nAFC needs n_correct")
    subjects = tuple(dict.fromkeys(str(s) for s in trials["subject"]))
    if POOLED in subjects:
        raise ArgumentError("subject", POOLED, f"the label {POOLED!r} is reserved for pooled estimates")
    keys = list(zip(trials["standard_um"].astype(float), trials["standard_speed_mm_s"].astype(float),
                    trials["comparison_speed_mm_s"].astype(float)))
    conditions = tuple(sorted(set(keys)))
    cond_index = {c: i for i, c in enumerate(conditions)}
    sub_index = {s: i for i, s in enumerate(subjects)}
    count = COUNT_COLUMNS["nafc" if nafc_data else "comparison"]
    return Cells(subjects, conditions,
                 np.array([sub_index[str(s)] for s in trials["subject"]], dtype=int),
                 np.array([cond_index[c] for c in keys], dtype=int),
                 trials["comparison_um"].to_numpy(dtype=float),
                 trials["n_trials"].to_numpy(dtype=float),
                 trials[count].to_numpy(dtype=float), task or COMPARISON)


def log_lik_cells(cells: Cells, pse, sigma, lapse, phi=None) -> np.ndarray:
    """Log-likelihood of every cell (binomial, or beta-binomial with concentration φ).

    Args:
        pse, sigma (ndarray[..., n_cells]): per-cell location and σ (µm).
        lapse (ndarray[..., n_cells]): per-cell lapse rate in [0, 0.5).
        phi (ndarray[..., n_cells] | None): beta-binomial concentration, > 0.
    Returns:
        ndarray[..., n_cells]; a zero-trial cell contributes exactly 0.
    """
    n, k = cells.n, cells.k
    log_p, log_q = cells.task.log_pq((cells.x_um - pse) / sigma, lapse)
    log_choose = gammaln(n + 1) - gammaln(k + 1) - gammaln(n - k + 1)
    if phi is None:
        return log_choose + _xlog(k, log_p) + _xlog(n - k, log_q)
    tiny = np.finfo(float).tiny                 # p = 0 exactly: the k = 0 limit stays finite
    a, b = np.maximum(phi * np.exp(log_p), tiny), np.maximum(phi * np.exp(log_q), tiny)
    return log_choose + betaln(k + a, n - k + b) - betaln(a, b)


def _xlog(count, log_prob):
    """count·log_prob with 0·(−inf) = 0."""
    return np.where(count > 0, count * log_prob, 0.0)
