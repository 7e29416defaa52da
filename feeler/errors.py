"""One exception hierarchy for the whole project.

Bad input is a ``ValueError`` subclass whose one-line message names the file or
argument, the value and what is allowed. Errors carry their data as attributes so a
caller can act on them without parsing the message.
"""
from __future__ import annotations

import os

__all__ = [
    "FeelerError",
    "InputError",
    "ArgumentError",
    "SceneError",
    "DataFileError",
    "OverwriteError",
    "CalibrationFailed",
    "SolverError",
]


class FeelerError(Exception):
    """Base of every error raised on purpose by feeler."""


class InputError(FeelerError, ValueError):
    """Bad input supplied by a user or a caller (a ``ValueError``)."""


class ArgumentError(InputError):
    """A function or CLI argument with a value outside what is allowed.

    Attributes:
        name (str): the argument's name, e.g. ``"tau"``.
        value (object): the offending value (possibly abbreviated); None when the argument
            is missing (the message then names only the argument).
        allowed (str): what would have been accepted.
    """

    def __init__(self, name: str, value: object, allowed: str):
        self.name, self.value, self.allowed = name, value, allowed
        super().__init__(f"argument {name}: {allowed}" if value is None else
                         f"argument {name}={_short(value)}: {allowed}")


class SceneError(InputError):
    """A scene file that does not validate.

    Attributes:
        path (str): the scene file.
        key (str): dotted key inside the file, e.g. ``"noise.uy_sd_mm"``.
        problem (str): what is wrong and what is allowed.
    """

    def __init__(self, path: object, key: str, problem: str):
        self.path, self.key, self.problem = str(path), key, problem
        where = f"{self.path}: {key}" if key else self.path
        super().__init__(f"{where}: {problem}")


class DataFileError(InputError):
    """A data file (CSV, JSON, NetCDF, video, ...) that is missing, corrupt or malformed."""

    def __init__(self, path: object, problem: str):
        self.path, self.problem = str(path), problem
        super().__init__(f"{self.path}: {problem}")


class OverwriteError(InputError):
    """Refusing to overwrite existing data without ``--force``."""

    def __init__(self, path: object, advice: str = "pass --force to overwrite it"):
        self.path = str(path)
        super().__init__(f"{self.path}: already exists; {advice}")


def _short(value: object, limit: int = 60) -> str:
    """``repr(value)`` within ``limit`` characters: a long path keeps its end (the file
    that names it, whatever directory the checkout lies in), anything else its start."""
    if type(value).__module__ == "numpy" and getattr(value, "ndim", None) == 0:
        value = value.item()                     # inf, not np.float64(inf)
    if isinstance(value, os.PathLike):
        value = os.fspath(value)
    text = repr(value)
    if isinstance(value, str) and " " in value and len(text) <= 4 * limit:
        return text                              # a value described in words: cut, it lost its meaning ('deco...')
    if len(text) <= limit:
        return text
    if isinstance(value, str) and ("/" in value or os.sep in value):
        return text[0] + "..." + text[-(limit - 4):]
    return text[: limit - 3] + "..."


class CalibrationFailed(FeelerError):
    """A posterior failed its diagnostics and was used without ``--accept-failed``.

    Attributes:
        verdict: the :class:`feeler.calib.diagnostics.Verdict` (``ok``, ``problems``).
    """

    def __init__(self, verdict, what: str = "calibration"):
        self.verdict = verdict
        first = verdict.problems[0] if verdict.problems else "unknown problem"
        more = f" (+{len(verdict.problems) - 1} more)" if len(verdict.problems) > 1 else ""
        super().__init__(f"{what} failed its diagnostics: {first}{more}; "
                         f"pass --accept-failed to use it anyway")


class SolverError(FeelerError):
    """A numerical solver did not reach its tolerance (e.g. the skin model's contact).

    Attributes:
        solver (str): which solver.
        residual (float): the remaining violation, in the solver's units.
    """

    def __init__(self, solver: str, residual: float, unit: str = ""):
        self.solver, self.residual = solver, residual
        super().__init__(f"{solver} did not converge: residual {residual:.3g}{' ' + unit if unit else ''}")
