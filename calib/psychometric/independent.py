"""How many draws a fit of independent draws needs, and the verdict it gets.

The exact grid, Laplace and the finger route's grid hand out *independent* draws from a
posterior computed without a sampler. R-hat compares chains of a sampler to see whether
they have mixed; independent draws have nothing to mix, and their R-hat is noise alone
(at 4 chains × 100 draws, 11 % of the parameters read above 1.01 by chance). Their
effective sample size is their number. So the verdict of such a fit does not judge the
estimated R-hat and ESS (the table still shows them); the draw counts are checked before
any work instead (:func:`check_draw_counts`, also for NUTS, where R-hat is judged):

- at least :data:`MIN_CHAINS` chains: the rank-normalised split R-hat of one chain is
  undefined (NaN);
- at least :data:`MIN_DRAWS_PER_CHAIN` draws per chain: split R-hat halves each chain;
- chains × draws at least the verdict's bulk ESS (:class:`~feeler.calib.diagnostics.Thresholds`,
  400): fewer independent draws cannot reach it, and their intervals are too rough.
"""
from __future__ import annotations

from typing import Mapping

from feeler.calib.diagnostics import Thresholds, diagnose, summarize
from feeler.calib.fit import FitResult
from feeler.calib.posterior import flat_draws
from feeler.errors import ArgumentError

__all__ = ["MIN_CHAINS", "MIN_DRAWS_PER_CHAIN", "MIN_TOTAL_DRAWS", "check_draw_counts", "independent_result"]

MIN_CHAINS = 2
MIN_DRAWS_PER_CHAIN = 4
MIN_TOTAL_DRAWS = int(Thresholds().ess_bulk_min)


def check_draw_counts(chains: int, draws: int, *, flag: str = "") -> None:
    """Refuse draw counts the summary's R-hat and ESS cannot be computed or met with.

    Args:
        chains, draws (int): chains and draws per chain (already integers >= 1).
        flag (str): "--" for command-line messages ("--chains"), "" for a library call.
    Raises:
        ArgumentError: one line naming the argument, its value and the minimum.
    """
    need = (f"the summary's R-hat needs at least {MIN_CHAINS} chains of at least {MIN_DRAWS_PER_CHAIN} draws "
            f"(one chain: undefined), and the verdict's bulk ESS chains × draws >= {MIN_TOTAL_DRAWS}")
    if chains < MIN_CHAINS:
        raise ArgumentError(f"{flag}chains", chains, f"at least {MIN_CHAINS}: {need}")
    if draws < MIN_DRAWS_PER_CHAIN or chains * draws < MIN_TOTAL_DRAWS:
        least = max(MIN_DRAWS_PER_CHAIN, -(-MIN_TOTAL_DRAWS // chains))
        raise ArgumentError(f"{flag}draws", draws, f"at least {least} with {chains} chains: {need}")


def independent_result(posterior, *, backend: str, priors: Mapping[str, str], seconds: float) -> FitResult:
    """:func:`feeler.calib.fit.make_result` for independent draws: every other check of
    :func:`feeler.calib.diagnostics.diagnose` applies; R-hat is taken as 1 (nothing to
    mix) and the bulk ESS as the number of draws (see the module doc). The summary keeps
    the estimated R-hat and ESS."""
    summary = summarize(posterior)
    n = next(iter(flat_draws(posterior).values())).size
    judged = summary.assign(r_hat=1.0, ess_bulk=float(n))
    verdict = diagnose(posterior, judged, backend=backend)
    return FitResult(posterior=posterior, summary=summary, verdict=verdict, priors=dict(priors), backend=backend,
                     seconds=float(seconds))
