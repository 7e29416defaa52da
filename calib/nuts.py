"""The shared NUTS runner: a PyMC model sampled by nutpie (NUTS in Rust), compiled once.

``sample_model(model, draws=…, tune=…, chains=…, seed=…)`` is a drop-in for
``pm.sample(...)``: it returns the same ``DataTree`` layout (groups ``posterior`` and
``sample_stats`` with dims ``(chain, draw, <var>_dim_k)``; ``diverging``, ``lp``,
``tree_depth``, ``step_size``, ``energy``, ``acceptance_rate``, ``n_steps``) and the
same diagnostics follow from it. Why nutpie: PyMC's own sampler runs its leapfrog steps
in Python (40–117 s per fit here), nutpie runs them in Rust against a numba-compiled
log density and its gradient, with the chains in threads of this process.

Compiling that density is most of a fit's wall time when done afresh (numba: ~5–20 s
for M4). PyTensor caches its compiled graphs on disk under a key that covers the graph
and its constants; nutpie's C entry points around them, though, are closures numba
cannot cache. Here they are generated from source under a key derived from PyTensor's
(:func:`_entry_points`), so a second fit of the same model structure and data loads
them from PyTensor's cache directory (``pytensor.config.base_compiledir``/numba) instead
of compiling. A model PyTensor cannot key (an op without a cache key, shared data)
takes nutpie's own, uncached, compile.

Reproducibility: a seed gives the same draws in every process that loads the compiled
model from the cache. The one process that compiles it (the first fit of a new model
or data set) runs the freshly JIT-compiled graph, which rounds differently in the last
bits from the cached object code, and NUTS can amplify that into different (equally
valid) chains. Loading PyTensor's build of the graph before the entry points makes
the choice of copy not depend on load order (:func:`_entry_points`).

The timings go in ``tree["sample_stats"].attrs``: ``compile_seconds`` (graph to machine
code, or its cache load), ``sampling_seconds``, ``compile_cache`` ("hit", "miss" or
"off"), ``sampler`` — and :func:`stats_of` carries them to a backend's sample-stats
dict. Without nutpie installed, PyMC's own sampler runs (``sampler`` "pymc"; PyMC 6's
``pm.sample`` picks nutpie by itself when it is installed, compiling it afresh each time).
"""
from __future__ import annotations

import contextlib
import logging
import os
import signal
import time

import numpy as np

from feeler.calib.progress import bar_width, show_progress, stage

__all__ = ["sample_model", "stats_of", "SampleStats", "available_cores"]

log = logging.getLogger(__name__)

# nutpie's names → PyMC's, so that downstream code reads one layout
_STAT_NAMES = {"logp": "lp", "depth": "tree_depth", "mean_tree_accept": "acceptance_rate",
               "step_size": "step_size", "energy": "energy", "diverging": "diverging",
               "n_steps": "n_steps"}
# bump when the generated entry points change (part of their cache key)
_ENTRY_VERSION = "feeler-nutpie-entry-1"


class SampleStats(dict):
    """``dict[name] -> ndarray (chain, draw)`` plus ``attrs`` (timings, sampler)."""

    def __init__(self, *args, attrs: dict | None = None, **kwargs):
        super().__init__(*args, **kwargs)
        self.attrs = dict(attrs or {})


def available_cores() -> int:
    """CPUs this process may run on (its affinity mask), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def sample_model(model, *, draws: int, tune: int, chains: int, seed: int, target_accept: float = 0.8,
                 progress: bool | None = None, var_names=None, cores: int | None = None,
                 adaptation: str = "diag"):
    """NUTS draws of ``model`` (a ``pm.Model``), as ``pm.sample`` would return them.

    Args:
        draws, tune, chains (int): kept draws and warm-up steps per chain, chains.
        seed (int): the run's seed; the same seed gives the same draws.
        target_accept (float): step-size target in (0, 1).
        progress (bool | None): progress bar on stderr (None: on a terminal; off one a
            line as the model is built and one as sampling starts; False: silent).
        var_names (list[str] | None): variables to keep (None: every free and
            deterministic variable).
        cores (int | None): chains run at once in threads (None: the CPUs available).
        adaptation (str): nutpie's mass-matrix adaptation: "diag" (from draws and
            gradients, nutpie's default) or "draw_diag" (from draws only, as PyMC and
            Stan: longer trajectories per draw, so more effective draws per draw on
            funnels such as hierarchical scales).
    Returns:
        xarray.DataTree: groups ``posterior`` and ``sample_stats`` (timings in its attrs).
    """
    try:
        import nutpie
    except ImportError:  # the sampler of last resort: same layout, slower
        return _sample_pymc(model, draws=draws, tune=tune, chains=chains, seed=seed,
                            target_accept=target_accept, progress=progress, var_names=var_names)
    lines = progress is None and not show_progress(None)     # off a terminal: a line per stage
    if lines:
        stage("NUTS: building the model (numba compiles it on a first run, then it is cached)")
    t0 = time.perf_counter()
    compiled, cache = compile_model(model, var_names)
    compile_s = time.perf_counter() - t0
    cores = min(chains, cores or available_cores())
    if lines:
        stage(f"NUTS: sampling {chains} chain(s) of {tune} warm-up and {draws} kept draws")
    t0 = time.perf_counter()
    bar = _Progress(chains * (draws + tune)) if show_progress(progress) else None
    try:
        with _sigint_seen() as seen:
            tree = nutpie.sample(compiled, draws=draws, tune=tune, chains=chains, cores=cores,
                                 seed=int(seed), target_accept=float(target_accept), save_warmup=False,
                                 progress_bar=False, progress_callback=bar, adaptation=adaptation)
    finally:
        if bar is not None:
            bar.close()
    sampling_s = time.perf_counter() - t0
    if seen or _kept_draws(tree) < draws:      # nutpie swallows Ctrl-C and returns what it has: not a fit
        raise KeyboardInterrupt("NUTS sampling interrupted")
    out = _pymc_layout(tree, var_names)
    out["sample_stats"].attrs.update({"compile_seconds": compile_s, "sampling_seconds": sampling_s,
                                      "compile_cache": cache, "sampler": f"nutpie {nutpie.__version__}"})
    log.info("NUTS (nutpie): compile %.2f s (cache %s), sampling %.2f s", compile_s, cache, sampling_s)
    return out


@contextlib.contextmanager
def _sigint_seen():
    """A list that gets an entry when SIGINT arrives inside the block; the signal still goes
    to the handler in place (Python's raises KeyboardInterrupt). nutpie catches that
    KeyboardInterrupt, aborts and returns the draws so far: the longest chain's length,
    the other chains' unfinished draws NaN (none during warm-up). The fits then failed on
    that trace with a traceback ('cannot reshape array', 'p < 0, p > 1 or p contains NaNs'),
    exit 1, instead of feeler's interrupt line and exit 130; an early abort can even raise
    ('Sampler has no results to take'), re-raised as the interrupt. Outside the main thread, or
    with SIGINT ignored, nothing is installed (:func:`_kept_draws` still sees a short trace)."""
    from feeler.children import sigint_handler

    seen: list[int] = []
    previous = signal.getsignal(signal.SIGINT)

    def note(signum, frame):
        seen.append(signum)
        previous(signum, frame)

    with sigint_handler(note if callable(previous) else previous):
        try:
            yield seen
        except Exception:
            if seen:                # nutpie's abort can fail itself ('Sampler has no results to take')
                raise KeyboardInterrupt("NUTS sampling interrupted") from None
            raise


def _kept_draws(tree) -> int:
    """Kept draws per chain in nutpie's result (0 when it has no posterior yet); fewer than
    asked for: the run was cut short (:func:`_sigint_seen`)."""
    try:
        return int(tree["posterior"].sizes.get("draw", 0))
    except (KeyError, AttributeError, TypeError):
        return 0


def stats_of(tree, names=("diverging", "lp")) -> SampleStats:
    """The sample stats ``names`` of ``tree`` as ``(chain, draw)`` arrays, with the
    runner's timings in ``.attrs`` (for a backend's sample-stats dict)."""
    stats = tree["sample_stats"]
    return SampleStats({k: np.asarray(stats[k].transpose("chain", "draw").values) for k in names},
                       attrs={k: v for k, v in stats.attrs.items()
                              if k in ("compile_seconds", "sampling_seconds", "compile_cache", "sampler")})


def compile_model(model, var_names=None):
    """nutpie's compiled form of ``model`` and how its entry points were obtained
    ("hit": loaded from the cache, "miss": compiled and cached, "off": not cacheable)."""
    import nutpie
    from nutpie import compile_pymc as cp
    from pymc.initial_point import make_initial_point_fn

    init = make_initial_point_fn(model=model, default_strategy="support_point",
                                 jitter_rvs=set(model.free_RVs), return_transformed=True)
    init = cp._wrap_with_lock(init)
    (n_dim, n_expanded, logp_pt, expand_pt, init_flat, shape_info,
     reparameterized) = cp._make_functions(model, mode="NUMBA", compute_grad=True, join_expanded=True,
                                           pymc_initial_point_fn=init, var_names=var_names)
    try:
        entries = _entry_points(n_dim, n_expanded, logp_pt, expand_pt)
    except Exception as exc:  # noqa: BLE001 — an unreadable cache entry must not cost the fit
        log.warning("compiled-model cache unusable (%s: %s); compiling without it", type(exc).__name__, exc)
        entries = None
    if entries is None:
        return nutpie.compile_pymc_model(model, var_names=var_names), "off"
    logp_c, expand_c, cache = entries
    dims, coords = cp._prepare_dims_and_coords(model, shape_info, reparameterized)
    compiled = cp.CompiledPyMCModel(
        _n_dim=n_dim, dims=dims, _coords=coords,
        _shapes={name: tuple(shape) for name, _, shape in zip(*shape_info)},
        compiled_logp_func=logp_c, compiled_expand_func=expand_c, initial_point_func=init_flat,
        shared_data={}, shared_var_keys={}, user_data=cp.make_user_data({}, {}),
        n_expanded=n_expanded, shape_info=shape_info, logp_func=logp_pt, expand_func=expand_pt,
        reparameterized_names=reparameterized)
    return compiled, cache


_LOGP_SRC = """
def feeler_nutpie_logp(dim, x_, out_, logp_, user_data_):
    if dim != {n}:
        return -1
    try:
        x = carray(x_, ({n},))
        out = carray(out_, ({n},))
        logp = carray(logp_, ())
        value, grad = inner(x)
        logp[()] = value
        out[...] = grad
        if not np.all(np.isfinite(out)):
            return 3
        if not np.isfinite(value):
            return 4
    except Exception:
        return 1
    return 0
"""

_EXPAND_SRC = """
def feeler_nutpie_expand(dim, expanded, x_, out_, user_data_):
    if dim != {n} or expanded != {m}:
        return -1
    try:
        x = carray(x_, ({n},))
        out = carray(out_, ({m},))
        (values,) = inner(x)
        out[...] = values
    except Exception:
        return -2
    return 0
"""


def _entry_points(n_dim, n_expanded, logp_pt, expand_pt):
    """nutpie's two C entry points (the same code as nutpie's own, for models without
    shared data), generated under cache keys derived from PyTensor's keys of the graphs
    they call; None when a graph has no key or reads shared data."""
    import numba
    import nutpie
    import pytensor
    from pytensor.link.numba.cache import CACHED_SRC_FUNCTIONS, compile_numba_function_src

    if logp_pt.get_shared() or expand_pt.get_shared():
        return None
    keys = [CACHED_SRC_FUNCTIONS.get(f.vm.jit_fn.py_func) for f in (logp_pt, expand_pt)]
    if None in keys:
        return None
    u64, f64p = numba.types.uint64, numba.types.CPointer(numba.types.double)
    made, hits = [], 0
    for src, name, inner, key, sig in (
            (_LOGP_SRC.format(n=n_dim), "feeler_nutpie_logp", logp_pt.vm.jit_fn, keys[0],
             numba.types.int64(u64, f64p, f64p, f64p, numba.types.voidptr)),
            (_EXPAND_SRC.format(n=n_dim, m=n_expanded), "feeler_nutpie_expand", expand_pt.vm.jit_fn, keys[1],
             numba.types.int64(u64, u64, f64p, f64p, numba.types.voidptr))):
        stamp = f"{_ENTRY_VERSION}-{nutpie.__version__}-{pytensor.__version__}-{numba.__version__}"
        fn = compile_numba_function_src(src, name, global_env={"__name__": __name__, "carray": numba.carray, "np": np,
                                                                 "inner": inner},
                                        cache_key=f"{name}-{n_dim}-{n_expanded}-{key}-{stamp}")
        # load PyTensor's build of the graph first: the entry point holds its own copy
        # (optimised after inlining, so rounding differently), and the process runs
        # whichever copy of the graph's symbol was loaded first — loading PyTensor's
        # first makes a fit independent of whether the entry point was cached
        try:
            inner(np.zeros(n_dim))
        except Exception:  # noqa: BLE001 — a graph may raise at this point; loading is what counts
            pass
        cf = numba.cfunc(sig, cache=True)(fn)
        hits += cf.cache_hits
        made.append(cf)
    return made[0], made[1], "hit" if hits == 2 else "miss"


def _pymc_layout(tree, var_names=None):
    """nutpie's tree with PyMC's group and stat names (posterior, sample_stats), the
    posterior cut to ``var_names`` as ``pm.sample`` does (nutpie keeps every free variable)."""
    import xarray as xr

    stats = tree["sample_stats"].to_dataset()
    keep = {old: new for old, new in _STAT_NAMES.items() if old in stats.data_vars}
    renamed = stats[list(keep)].rename(keep)
    if "tree_depth" in renamed:
        renamed["tree_depth"] = renamed["tree_depth"].astype(np.int64)
    if "n_steps" in renamed:
        renamed["n_steps"] = renamed["n_steps"].astype(np.int64)
    post = tree["posterior"].to_dataset()
    if var_names is not None:
        post = post[list(var_names)]
        post = post.drop_vars([c for c in post.coords if c not in post.dims])
    out = xr.DataTree.from_dict({"posterior": post, "sample_stats": renamed})
    out["posterior"].attrs.update(tree["posterior"].attrs)
    out["sample_stats"].attrs.update(tree["sample_stats"].attrs)
    return out


def _sample_pymc(model, *, draws, tune, chains, seed, target_accept, progress, var_names):
    import pymc as pm

    t0 = time.perf_counter()
    tree = pm.sample(draws=draws, tune=tune, chains=chains, cores=1, random_seed=seed,
                     progressbar=show_progress(progress), target_accept=target_accept,
                     compute_convergence_checks=False, model=model, var_names=var_names,
                     nuts_sampler="pymc")
    tree["sample_stats"].attrs.update({"compile_seconds": float("nan"),
                                       "sampling_seconds": time.perf_counter() - t0,
                                       "compile_cache": "off", "sampler": f"pymc {pm.__version__}"})
    return tree


class _Progress:
    """A tqdm bar fed by nutpie's progress callback (called from a sampler thread)."""

    def __init__(self, total: int):
        import sys

        from tqdm.auto import tqdm
        self.bar = tqdm(total=total, desc="NUTS", file=sys.stderr, leave=False, **bar_width())
        self.done = 0

    def __call__(self, chains) -> None:
        done = sum(int(c.finished_draws) for c in chains)
        divergences = sum(int(c.divergences) for c in chains)
        self.bar.update(done - self.done)
        self.bar.set_postfix_str(f"{divergences} divergences", refresh=False)
        self.done = done

    def close(self) -> None:
        self.bar.close()
