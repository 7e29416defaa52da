"""M1: fit the force→displacement matrix C of a sensor element, U = C F.

Which way to regress. The stage imposes U (commanded, accurate to ~1 µm) and the sensor
measures F (noisy). Regressing U on F ("forward": U = C F + ε) puts the noise in the
regressor, and least squares / any model that treats F as exact is attenuated: for an
uncorrelated design column j shrinks by λ_j = var(F_j)/(var(F_j) + σ_Fj²) towards 0.
The principled default ("inverse") writes the model the way the data are generated:
F = K U + η with K = C⁻¹ (stiffness, N/mm), η ~ N(0, diag σ_F²): the noise is in the
response and the regressor is exact, so there is no attenuation and the Gaussian case
is conjugate (exact backend, :mod:`.exact`). C = K⁻¹ is computed per draw, so its
posterior (and the condition number's) is exact too. This is the errors-in-variables
model "U = C F_true, F = F_true + η" in the limit of an exact stage; ``model="eiv"``
keeps a stage error ε ~ N(0, stage_sd²) on U as latent variables (NUTS only).
``model="forward"`` is the naive regression, kept to show the bias.

Backends: ``exact`` (Gaussian noise, models inverse/forward), ``nuts`` (PyMC, all
variants), ``emcee`` (no latent variables: models inverse/forward; runs until its chains
pass their diagnostics unless ``draws`` is given).

The verdict adds the model's own checks (:mod:`.checks`, :mod:`.degenerate`): unidentified
design directions, copied rows, noise-free outputs (NUTS and emcee are then not started:
:class:`NotSampled`), units off by ~10³, prior–data conflict and posterior predictive checks.
"""
from __future__ import annotations

import time

import numpy as np

from feeler.calib.diagnostics import Verdict
from feeler.calib.fit import FitResult, make_result, posterior_from_draws
from feeler.calib.matrix.backends import sample_emcee, sample_nuts
from feeler.calib.matrix.checks import (conflict_problems, design_problems, noise_unit_problems, ppc_problems,
                                        repeat_problems, sign_problems, span_unit_problems, unit_problems)
from feeler.calib.matrix.data import CalibrationData, weak_directions
from feeler.calib.matrix.degenerate import copy_problems, noise_free_problems, output_problems
from feeler.calib.matrix.exact import exact_posterior
from feeler.calib.matrix.prior import MatrixPrior
from feeler.errors import ArgumentError, FeelerError

__all__ = ["fit_matrix", "NotSampled", "MODELS", "NOISES", "BACKENDS"]

MODELS = ("inverse", "eiv", "forward")
NOISES = ("gaussian", "student")
BACKENDS = ("exact", "nuts", "emcee")
DIMS = {"C": ["disp_axis", "force_axis"], "K": ["force_axis", "disp_axis"],
        "sigma_n": ["force_axis"], "sigma_mm": ["disp_axis"]}


class NotSampled(FeelerError):
    """A sampler was not started: the data pin nothing it could sample (noise-free outputs).

    Attributes:
        backend (str): the sampler that was not run ("nuts" or "emcee").
        verdict (Verdict): the failed verdict, one line per problem found before sampling.
    """

    def __init__(self, backend: str, problems: list[str]):
        self.backend, self.verdict = backend, Verdict(ok=False, problems=tuple(problems))
        super().__init__(f"{backend} not run: {problems[0]}")


def fit_matrix(data: CalibrationData, prior: MatrixPrior, *, model: str = "inverse",
               noise: str = "gaussian", backend: str = "exact", rng: np.random.Generator,
               noise_sd: tuple[float, float, float] | None = None, stage_sd_mm: float = 0.001,
               student_nu: float = 4.0, chains: int = 4, draws: int | None = 1000, tune: int = 1000,
               walkers: int = 32, progress: bool | None = None) -> FitResult:
    """Posterior of C (and K, noise sds, cond(C)) for one calibration campaign.

    Args:
        data: commanded ``u_mm (n, 3)`` and measured ``f_n (n, 3)``.
        prior: nominal C₀ and scales (see :mod:`.prior`).
        model: "inverse" (default, F = K U + η), "eiv" (plus latent stage error),
            "forward" (naive U = C F + ε).
        noise: "gaussian" or "student" (Student-t, ``student_nu`` dof).
        backend: "exact", "nuts" or "emcee".
        rng: source of every random number (seeds of the samplers are drawn from it).
        noise_sd: known noise sd per output axis (N for inverse/eiv, mm for forward);
            None infers it.
        stage_sd_mm: sd of the stage error on U for ``model="eiv"``, mm, > 0.
        chains, draws, tune: chains (exact/NUTS), kept draws per chain, NUTS/emcee warm-up;
            emcee with ``draws=None`` runs until its chains are 50 autocorrelation times
            long, with R-hat ≤ 1.01 and bulk ESS ≥ 400 (first quarter discarded, at most
            200 000 steps; the verdict fails at the cap). None means 1000 for exact/NUTS.
        walkers: emcee walkers (stored as chains).

    Raises:
        ArgumentError: an argument outside what is allowed.
        NotSampled: ``backend`` "nuts" or "emcee" on noise-free outputs (its verdict
            names them); the exact backend returns a failed verdict instead.
    """
    if draws is None and backend != "emcee":
        draws = 1000
    _check(model, noise, backend, noise_sd, stage_sd_mm, student_nu, chains, draws if draws is not None else 4,
           tune, walkers)
    rp = prior.for_direction("forward" if model == "forward" else "inverse")
    what, unit = ("force", "N") if model == "forward" else ("displacement", "mm")
    x, y = (data.f_n, data.u_mm) if model == "forward" else (data.u_mm, data.f_n)
    if np.any(x):
        weak_directions(x, what=what, unit=unit)
    design = design_problems(x, matrix=rp.matrix, what=what, unit=unit)
    # known noise sds give the intervals their width: noise-free outputs then pin nothing less
    noise_free = noise_free_problems(x, y, forward=model == "forward") if noise_sd is None else []
    copied = repeat_problems(data.point_id, data.u_mm, data.f_n, matrix=rp.matrix)
    if not copied and not noise_free:     # noise-free replicated points repeat their rows by nature
        copied = copy_problems(data.u_mm, data.f_n, matrix=rp.matrix)
    problems = design + copied + (output_problems(data.f_n) if not design and model != "forward" else [])
    design_ok = not problems
    problems += noise_free
    if design_ok:
        b_unit = "mm/N" if model == "forward" else "N/mm"
        problems += unit_problems(x, y, prior.c0, forward=model == "forward")
        if not problems:                  # a compliance ~10³ off is named above; with it right, the noise's scale
            problems += noise_unit_problems(x, y, rp.sigma_scale, forward=model == "forward")
        problems += conflict_problems(x, y, rp.b0, rp.sd, matrix=rp.matrix, unit=b_unit)
    elif design and np.any(x):            # the scale along what the design pins: um hid behind the design's line
        problems += span_unit_problems(x, y, prior.c0, forward=model == "forward")
    if noise_free and backend != "exact":
        # NUTS and emcee cannot sample the sigma -> 0 funnel: refuse before any sampling starts
        raise NotSampled(backend, problems)
    known = None if noise_sd is None else np.asarray(noise_sd, dtype=float)
    seed = int(rng.integers(2**31 - 1))
    t0 = time.perf_counter()
    stats = None
    if backend == "exact":
        B, S = exact_posterior(rng, x, y, rp.b0, rp.sd, rp.sigma_scale, n_draws=chains * draws,
                               noise_sd=known)
        B, S = B.reshape(chains, draws, 3, 3), S.reshape(chains, draws, 3)
    elif backend == "nuts":
        out, stats = sample_nuts(x, y, rp, noise=noise, nu=student_nu, eiv=model == "eiv",
                                 stage_sd=stage_sd_mm, noise_sd=known, chains=chains, draws=draws,
                                 tune=tune, seed=seed, progress=progress)
        B, S = out["B"], out["sigma"]
    else:
        out, stats, notes = sample_emcee(x, y, rp, noise=noise, nu=student_nu, noise_sd=known,
                                         walkers=walkers, draws=draws, tune=tune, seed=seed, progress=progress)
        B, S = out["B"], out["sigma"]
        problems += notes
    seconds = time.perf_counter() - t0
    problems += ppc_problems(x, y, B.reshape(-1, 3, 3), S.reshape(-1, 3), rng, matrix=rp.matrix, noise=noise,
                             nu=student_nu, lack_of_fit=not copied)
    attrs = dict(model=model, noise=noise, student_nu=student_nu,
                 noise_sd_known=[] if known is None else [float(v) for v in known])
    posterior = _named_posterior(B, None if known is not None else S, model, data, stats, attrs)
    if design_ok:                      # a design that spans every direction: is C's sign pinned?
        problems += sign_problems(posterior["posterior"]["C"].values, prior.c0)
    priors = rp.stated()
    if known is not None:
        priors["sigma"] = f"known: {list(map(float, known))} {rp.noise_unit}"
    if model == "eiv":
        priors["eps"] = f"stage error per point and axis ~ Normal(0, {stage_sd_mm:g} mm) (latent)"
    if noise == "student":
        priors["noise"] = f"Student-t, {student_nu:g} degrees of freedom (fixed)"
    return make_result(posterior, backend=backend, priors=priors, seconds=seconds, checks=problems)


def _named_posterior(B, S, model, data, stats, attrs):
    """C, K (inverse/eiv), noise sds (when inferred) and cond(C) as a DataTree."""
    with np.errstate(all="ignore"):
        if model == "forward":
            C = B
            draws = {"C": C, "sigma_mm": S}
        else:
            C = _safe_inv(B)
            draws = {"C": C, "K": B, "sigma_n": S}
        draws["cond_C"] = np.linalg.cond(C.reshape(-1, 3, 3)).reshape(C.shape[:2])
    draws = {k: v for k, v in draws.items() if v is not None}   # known noise: not a parameter
    return posterior_from_draws(draws, dims=DIMS, sample_stats=stats,
                                observed={"u_mm": data.u_mm, "f_n": data.f_n}, attrs=attrs)


def _safe_inv(K: np.ndarray) -> np.ndarray:
    """Batched inverse; a singular draw (measure zero, but floating point) gives inf."""
    flat = K.reshape(-1, 3, 3)
    out = np.full_like(flat, np.inf)
    ok = np.abs(np.linalg.det(flat)) > 0
    out[ok] = np.linalg.inv(flat[ok])
    return out.reshape(K.shape)


def _check(model, noise, backend, noise_sd, stage_sd_mm, nu, chains, draws, tune, walkers):
    for name, value, allowed in (("model", model, MODELS), ("noise", noise, NOISES),
                                 ("backend", backend, BACKENDS)):
        if value not in allowed:
            raise ArgumentError(name, value, f"must be one of {', '.join(allowed)}")
    if backend == "exact" and (noise != "gaussian" or model == "eiv"):
        raise ArgumentError("backend", backend, "exact needs noise=gaussian and model inverse or "
                                                "forward; use nuts for student/eiv")
    if backend == "emcee" and model == "eiv":
        raise ArgumentError("backend", backend, "emcee cannot sample the eiv model's latent "
                                                "variables; use nuts")
    if noise_sd is not None:
        sd = np.asarray(noise_sd, dtype=float)
        if sd.shape != (3,) or not np.all(np.isfinite(sd)) or np.any(sd <= 0):
            raise ArgumentError("noise_sd", noise_sd, "must be 3 finite numbers > 0 (or None)")
    if not (np.isfinite(stage_sd_mm) and stage_sd_mm > 0):
        raise ArgumentError("stage_sd_mm", stage_sd_mm, "must be a finite number > 0 (mm)")
    if not (np.isfinite(nu) and nu > 0):
        raise ArgumentError("student_nu", nu, "must be a finite number > 0")
    for name, value, lo in (("chains", chains, 1), ("draws", draws, 4), ("tune", tune, 0),
                            ("walkers", walkers, 8)):
        if not isinstance(value, (int, np.integer)) or value < lo:
            raise ArgumentError(name, value, f"must be an integer >= {lo}")
