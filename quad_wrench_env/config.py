"""Typed configuration: dataclasses with defaults, filled from YAML files or dicts.

Unknown keys are refused with a message that names them and lists the allowed ones, so that a
misspelt setting never silently falls back to a default.
"""

from __future__ import annotations

import dataclasses
import math
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

import yaml

T = TypeVar("T")


def load_yaml(path: str | Path) -> dict[str, Any]:
    """Read a YAML mapping from ``path``."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"config file {str(path)!r} does not exist")
    data = yaml.safe_load(path.read_text()) or {}
    if not isinstance(data, dict):
        raise ValueError(f"config file {str(path)!r} must hold a mapping, not {type(data).__name__}")
    return data


def section(source: str | Path | Mapping[str, Any] | None, name: str) -> dict[str, Any]:
    """The ``name`` section of a config file or mapping; a mapping without sections is taken whole."""
    if source is None:
        return {}
    data = load_yaml(source) if isinstance(source, (str, Path)) else dict(source)
    if name in data and isinstance(data[name], Mapping):
        return dict(data[name])
    return data


def build(cls: type[T], values: Mapping[str, Any] | None = None, prefix: str = "") -> T:
    """Instantiate dataclass ``cls`` from ``values``, recursing into nested dataclass fields."""
    values = dict(values or {})
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(values) - set(fields))
    if unknown:
        names = ", ".join(repr(prefix + k) for k in unknown)
        raise ValueError(f"unknown config key(s) {names}; allowed: {sorted(prefix + k for k in fields)}")
    hints = typing.get_type_hints(cls)
    kwargs: dict[str, Any] = {}
    for name, value in values.items():
        kind = hints[name]
        if dataclasses.is_dataclass(kind):
            if not isinstance(value, Mapping):
                raise ValueError(f"config key {prefix + name!r} must be a mapping, got {value!r}")
            value = build(kind, value, prefix=f"{prefix}{name}.")  # type: ignore[arg-type]
        kwargs[name] = value
    return cls(**kwargs)


def merged(base: Mapping[str, Any], update: Mapping[str, Any]) -> dict[str, Any]:
    """Recursive dict merge: ``update`` wins, nested mappings are merged key by key."""
    out = dict(base)
    for key, value in update.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = merged(out[key], value)
        else:
            out[key] = value
    return out


def check_numbers(owner: str, obj: Any, names: tuple[str, ...], *, positive: bool = True) -> None:
    """Raise ``ValueError`` naming ``owner.name=value`` unless each attribute is a finite number
    that is > 0 (``positive``) or >= 0."""
    for name in names:
        value = getattr(obj, name)
        ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
        if not (ok and (value > 0 if positive else value >= 0)):
            raise ValueError(
                f"{owner}.{name}={value!r} must be a finite number {'> 0' if positive else '>= 0'}"
            )
