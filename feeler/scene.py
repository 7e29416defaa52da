"""Scene files: TOML declarations of one experiment, validated on load.

A scene file has a ``[scene]`` table naming its ``kind``; the kind's schema lives in
``feeler/scenes/<kind with - as _>.py`` as a frozen dataclass called ``Scene``. Every
table of the file maps onto a nested frozen dataclass; fields declare their range,
choices and unit through :func:`param`. Validation is strict: an unknown key, a missing
field, a wrong type, a value out of range or an impossible combination raises
:class:`feeler.errors.SceneError` whose one-line message names the file and the dotted
key.

Example::

    @dataclass(frozen=True)
    class Noise:
        uy_sd_mm: float = param(lo=0.0, hi=1.0, doc="white noise on U_y")

    scene = load_scene("datasets-synthetic/four-plates.toml")
"""
from __future__ import annotations

import dataclasses
import importlib
import pkgutil
import tomllib
import types
import typing
from pathlib import Path
from typing import Any

from feeler.errors import SceneError

__all__ = ["param", "param_bounds", "load_scene", "parse_table", "scene_kinds", "scene_as_dict", "SceneError",
           "SEED_MAX"]

_MISSING = dataclasses.MISSING

#: the largest seed: a TOML integer is a signed 64-bit one, and scene.toml records the seed
SEED_MAX = 2**63 - 1


def param(default: Any = _MISSING, *, lo: float | None = None, hi: float | None = None,
          lo_open: bool = False, choices: tuple | None = None, doc: str = "",
          min_len: int = 0) -> Any:
    """A validated scene field.

    Args:
        default: value when the key is absent; omit to make the key required.
        lo, hi (float): inclusive bounds for numbers (and for every item of a list).
        lo_open (bool): make ``lo`` exclusive (``> lo`` instead of ``>= lo``).
        choices (tuple): the allowed values of a string field.
        doc (str): one line with the unit, shown in error messages.
        min_len (int): the least number of items of a list field.
    """
    meta = {"lo": lo, "hi": hi, "lo_open": lo_open, "choices": choices, "doc": doc,
            "min_len": min_len}
    if isinstance(default, (list, dict)):
        raise TypeError("use a tuple for a default sequence")
    return dataclasses.field(default=default, metadata=meta)


def param_bounds(table: type, name: str) -> tuple[float, float]:
    """The (lo, hi) a scene schema table allows for its field ``name`` (its :func:`param`)."""
    meta = {f.name: f for f in dataclasses.fields(table)}[name].metadata
    return float(meta["lo"]), float(meta["hi"])


def scene_kinds() -> list[str]:
    """The scene kinds this installation knows (one module each in ``feeler.scenes``)."""
    import feeler.scenes as pkg
    return sorted(m.name.replace("_", "-") for m in pkgutil.iter_modules(pkg.__path__)
                  if not m.name.startswith("_"))


def load_scene(path: str | Path) -> Any:
    """Read and validate a scene file; returns the kind's frozen ``Scene`` dataclass.

    Raises:
        SceneError: unreadable TOML, unknown kind, or any invalid key (one line naming
            the file and key).
    """
    path = Path(path)
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SceneError(path, "", "no such scene file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(path, "", f"cannot read: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(path, "", f"not valid TOML: {exc}") from None
    head = raw.get("scene")
    if not isinstance(head, dict) or "kind" not in head:
        raise SceneError(path, "scene.kind", f"missing; allowed kinds: {', '.join(scene_kinds())}")
    kind = head["kind"]
    kinds = scene_kinds()
    if kind not in kinds:
        raise SceneError(path, "scene.kind", f"{kind!r} is not a known kind; allowed: {', '.join(kinds)}")
    module = importlib.import_module(f"feeler.scenes.{kind.replace('-', '_')}")
    scene = parse_table(module.Scene, raw, path=path, prefix="")
    check = getattr(scene, "check", None)
    if check is not None:
        check(path)
    return scene


def parse_table(cls: type, table: Any, *, path: Path | str, prefix: str) -> Any:
    """Validate one TOML table against the dataclass ``cls`` and build it."""
    if not isinstance(table, dict):
        raise SceneError(path, prefix.rstrip("."), f"must be a table, got {type(table).__name__}")
    fields = {f.name: f for f in dataclasses.fields(cls)}
    hints = typing.get_type_hints(cls)
    for key in table:
        if key not in fields:
            allowed = ", ".join(fields)
            raise SceneError(path, prefix + key, f"unknown key; allowed here: {allowed}")
    values = {}
    for name, f in fields.items():
        key = prefix + name
        if name not in table:
            if f.default is _MISSING and f.default_factory is _MISSING:  # type: ignore[misc]
                doc = f.metadata.get("doc", "")
                raise SceneError(path, key, f"missing required field{' (' + doc + ')' if doc else ''}")
            continue
        values[name] = _coerce(hints[name], table[name], f, path=path, key=key)
    return cls(**values)


def _coerce(hint: Any, value: Any, f: dataclasses.Field, *, path, key: str) -> Any:
    if dataclasses.is_dataclass(hint):
        return parse_table(hint, value, path=path, prefix=key + ".")
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        return _coerce(args[0], value, f, path=path, key=key)
    if origin is tuple:
        item = typing.get_args(hint)[0]
        if not isinstance(value, list):
            raise SceneError(path, key, f"must be a list, got {value!r}")
        if len(value) < f.metadata.get("min_len", 0):
            raise SceneError(path, key, f"needs at least {f.metadata['min_len']} items, got {len(value)}")
        return tuple(_coerce(item, v, f, path=path, key=f"{key}[{i}]") for i, v in enumerate(value))
    if hint is bool:
        if not isinstance(value, bool):
            raise SceneError(path, key, f"must be true or false, got {value!r}")
        return value
    if hint in (int, float):
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        if hint is int:
            ok = isinstance(value, int) and not isinstance(value, bool)
        if not ok:
            raise SceneError(path, key, f"must be {'an integer' if hint is int else 'a number'}, got {value!r}")
        value = hint(value)
        _check_range(value, f, path=path, key=key)
        return value
    if hint is str:
        if not isinstance(value, str):
            raise SceneError(path, key, f"must be a string, got {value!r}")
        choices = f.metadata.get("choices")
        if choices and value not in choices:
            raise SceneError(path, key, f"{value!r} is not allowed; allowed: {', '.join(map(str, choices))}")
        return value
    raise TypeError(f"scene schema field {key} has an unsupported type {hint!r}")


def _check_range(value: float, f: dataclasses.Field, *, path, key: str) -> None:
    lo, hi, lo_open = f.metadata.get("lo"), f.metadata.get("hi"), f.metadata.get("lo_open")
    doc = f.metadata.get("doc", "")
    unit = f" ({doc})" if doc else ""
    if value != value or value in (float("inf"), float("-inf")):
        raise SceneError(path, key, f"must be finite, got {value!r}{unit}")
    if lo is not None and (value <= lo if lo_open else value < lo):
        raise SceneError(path, key, f"{value!r} out of range: must be {'>' if lo_open else '>='} {lo}{unit}")
    if hi is not None and value > hi:
        raise SceneError(path, key, f"{value!r} out of range: must be <= {hi}{unit}")


def scene_as_dict(scene: Any) -> dict:
    """The scene as plain nested dicts (for ``truth.json`` and reports)."""
    return dataclasses.asdict(scene)
