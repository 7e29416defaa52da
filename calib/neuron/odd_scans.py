"""M2's per-scan check: training scans far outside the other touches of their plate (part of
the verdict's decoder-fit checks, :func:`.checks.posterior_problems`), and how a check names
a scan and a plate."""
from __future__ import annotations

import numpy as np

from feeler.calib.neuron.model import PeakTable, Plates

__all__ = ["odd_scan_problems", "scan_name", "mm_text", "ODD_ALPHA", "MAX_ODD"]

# family-wise level of the per-scan check over all scans: clean training sets of the nine hard
# scenes and four-plates (200 each) are flagged at most 1 % of the time at 0.001 (tilted 2 of 200:
# a touch on a lifted corner, which real plates make too), up to 4 % at 0.01
ODD_ALPHA = 0.001


def mm_text(v) -> str:
    """A step height as the checks print it."""
    return f"{v + 0.0:g} mm"                   # + 0.0: a step of -0 reads 0


def scan_name(k: int, scan_names=None) -> str:
    """How a check names scan ``k`` (0-based place in the data): by the data's own name for
    it (:attr:`~feeler.calib.neuron.data.NeuronData.scan_names`: its scan_id as written,
    or its file), else by its place in file order."""
    if scan_names is not None and 0 <= k < len(scan_names):
        return str(scan_names[k])
    return f"scan {k + 1} in file order"


MAX_ODD = 5           # far-out scans looked for one after another (each hides the next: see odd_scan_problems)


def odd_scan_problems(table: PeakTable, plates: Plates, pit: np.ndarray, log_w: np.ndarray, scan_names=None, *,
                      refit=None) -> list[str]:
    """Training scans far outside the other touches of their plate: a two-sided
    leave-one-out tail 2·min(PIT, 1 − PIT) below ``ODD_ALPHA`` over the scans (Bonferroni).
    One mislabelled or corrupted scan widens its plate and bends the noise model, but moves
    no per-plate check (1 scan in 24 outside the band is chance). It also hides the next:
    three mislabels in one file showed one at a time. So with ``refit(keep) -> PIT of the
    kept scans``, the worst scan is set aside and the rest tested again, up to
    :data:`MAX_ODD` times. The line names the worst scan (:func:`scan_name`), the plate its
    reading matches at the heaviest window if there is one (within 3 of that plate's sds,
    the set-aside scans left out: a wrong label), then the others."""
    n = pit.size
    keep = np.ones(n, bool)
    found, tails, extra = [], {}, []
    current = pit
    for _ in range(MAX_ODD):
        tail = np.full(n, np.nan)
        tail[keep] = np.clip(2 * np.minimum(current, 1 - current), 0.0, 1.0)
        known = np.isfinite(tail)
        odd = np.flatnonzero(known & (tail < ODD_ALPHA / max(int(known.sum()), 1)))
        if odd.size == 0:
            break
        k = int(odd[np.nanargmin(tail[odd])])
        found.append(k)
        tails[k] = float(tail[k])
        keep[k] = False
        left = np.bincount(plates.group[keep], minlength=plates.steps_mm.size)
        if refit is None or left.min() < 3:
            extra = [int(j) for j in odd[np.argsort(tail[odd])] if j != k]     # not tested again: named as seen
            break
        current = refit(keep)
    if not found:
        return []
    k = found[0]
    own = int(plates.group[k])
    p = table.peak[:, int(np.argmax(log_w))]
    clean = np.ones(n, bool)
    clean[found] = False
    dist = np.full(plates.steps_mm.size, np.inf)
    for c in range(dist.size):
        v = p[clean & (plates.group == c)]
        if v.size >= 2 and np.std(v, ddof=1) > 0:
            dist[c] = abs(p[k] - v.mean()) / np.std(v, ddof=1)
    near = int(np.argmin(dist))
    if near != own and dist[near] < 3:
        like = (f"its reading matches plate {mm_text(plates.steps_mm[near])} ({dist[near]:.1f} sds from that plate's "
                f"mean), so it is probably mislabelled: fix its label or remove it")
    else:
        like = ("its reading matches no plate: a corrupted scan (its scale or offset) or a touch unlike the rest "
                "(a tilted or slipping contact), which the decoder's plates do not describe; check it, and remove it "
                "if it is not a touch of this plate")
    rest = found[1:] + extra
    more = ""
    if rest:
        names = ", ".join(scan_name(j, scan_names) for j in rest[:3]) + (", ..." if len(rest) > 3 else "")
        lie = "scan lies outside its plate" if len(rest) == 1 else "scans lie outside their plates"
        more = f"; {len(rest)} more {lie} too ({names})"
    shown = f"= {tails[k]:.1g}" if tails[k] >= 1e-15 else "< 1e-15"      # 1 − PIT resolves no finer
    return [f"step_mm: {scan_name(k, scan_names)} (labelled {mm_text(plates.steps_mm[own])}) lies far outside the "
            f"other touches of its plate (leave-one-out p {shown}, below {ODD_ALPHA:g} over "
            f"{n} scans); {like}{more}"]
