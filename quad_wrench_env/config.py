"""Typed configuration: dataclasses with defaults, filled from YAML files or dicts.

Unknown keys are refused with a message that names them and lists the allowed ones, so that a
misspelt setting never silently falls back to a default.
"""

from __future__ import annotations

import dataclasses
import importlib.resources
import math
import numbers
import types
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
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except yaml.YAMLError as error:
        where = getattr(error, "problem_mark", None)
        at = f" at line {where.line + 1}, column {where.column + 1}" if where is not None else ""
        problem = getattr(error, "problem", None) or str(error).splitlines()[0]
        raise ValueError(f"config file {str(path)!r} is not valid YAML{at}: {problem}") from None
    if not isinstance(data, dict):
        raise ValueError(f"config file {str(path)!r} must hold a mapping, not {type(data).__name__}")
    return data


CONFIGS_PACKAGE = "quad_wrench_env.configs"
"""The repository's top-level ``configs/`` folder, installed with the package under this name."""


def shipped_configs() -> list[str]:
    """Names of the config files that ship with the package (``configs/``), e.g. ``"fan_tracking.yaml"``
    and ``"rl_zoo3/ppo.yml"``."""
    names: list[str] = []
    folders = [("", importlib.resources.files(CONFIGS_PACKAGE))]
    while folders:
        prefix, folder = folders.pop()
        for entry in folder.iterdir():
            if entry.is_dir() and entry.name != "__pycache__":
                folders.append((f"{prefix}{entry.name}/", entry))
            elif entry.is_file() and entry.name.endswith((".yaml", ".yml")):
                names.append(prefix + entry.name)
    return sorted(names)


def config_path(name: str) -> Path:
    """The path of the shipped config file ``name`` (a name of :func:`shipped_configs`), wherever the
    package is installed: ``load_yaml(config_path("fan_tracking.yaml"))``."""
    available = shipped_configs()
    if name not in available:
        raise ValueError(f"no shipped config {name!r}; available: {available}")
    return Path(importlib.resources.files(CONFIGS_PACKAGE) / name)  # type: ignore[arg-type]


def section(source: str | Path | Mapping[str, Any] | None, name: str) -> dict[str, Any]:
    """The ``name`` section of a config file or mapping; a mapping without sections is taken whole."""
    if source is None:
        return {}
    data = load_yaml(source) if isinstance(source, (str, Path)) else dict(source)
    if name in data and isinstance(data[name], Mapping):
        return dict(data[name])
    return data


def build(cls: type[T], values: Mapping[str, Any] | None = None, prefix: str = "") -> T:
    """Instantiate dataclass ``cls`` from ``values``, recursing into nested dataclass fields.

    Every value is checked against its field's annotation before ``cls`` is built, and one of the
    wrong type is refused with a ``ValueError`` that names its full dotted key (``prefix`` + name):
    a float field takes any real number (an int from YAML is fine), an int field an integer, a bool
    field ``True`` or ``False`` only, a str field a string, a tuple or list field a list or tuple, a
    dict field a mapping, a dataclass field a mapping of its own keys; ``X | None`` takes either.
    """
    values = dict(values or {})
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(values) - set(fields))
    if unknown:
        names = ", ".join(repr(prefix + k) for k in unknown)
        raise ValueError(f"unknown config key(s) {names}; allowed: {sorted(prefix + k for k in fields)}")
    hints = typing.get_type_hints(cls)
    kwargs = {name: _checked(hints[name], value, prefix + name) for name, value in values.items()}
    return cls(**kwargs)


def _checked(kind: Any, value: Any, key: str) -> Any:
    """``value`` for a field annotated ``kind`` (a nested dataclass built from its mapping), or a
    ``ValueError`` naming ``key`` when it is of the wrong type."""
    members = _members(kind)
    for member in members:
        if dataclasses.is_dataclass(member) and isinstance(value, Mapping):
            return build(member, value, prefix=f"{key}.")  # type: ignore[arg-type]
    if any(_accepts(member, value) for member in members):
        return value
    wanted = " or ".join(_describe(member) for member in members)
    raise ValueError(f"{key}={value!r} must be {wanted}; got {type(value).__name__}")


def _members(kind: Any) -> tuple[Any, ...]:
    """The alternatives of a union annotation (``X | None``, ``Optional[X]``), else ``(kind,)``."""
    if typing.get_origin(kind) in (typing.Union, types.UnionType):
        return typing.get_args(kind)
    return (kind,)


def _accepts(kind: Any, value: Any) -> bool:
    base = typing.get_origin(kind) or kind
    if kind is Any:
        return True
    if kind is type(None):
        return value is None
    if base is bool:
        return isinstance(value, bool)
    if isinstance(value, bool):
        return False  # a bool is an int to Python, never a number to a config
    if base is float:
        return isinstance(value, numbers.Real)
    if base is int:
        return isinstance(value, numbers.Integral)
    if base is str:
        return isinstance(value, str)
    if base in (tuple, list):
        return isinstance(value, (tuple, list))
    if base is dict:
        return isinstance(value, Mapping)
    if dataclasses.is_dataclass(base):
        return False  # only from a mapping (built in _checked)
    return isinstance(value, base) if isinstance(base, type) else True  # other annotations: unchecked


def _describe(kind: Any) -> str:
    base = typing.get_origin(kind) or kind
    name = getattr(kind, "__name__", None) if base is kind else None
    spelled = name or str(kind).replace("typing.", "")
    if kind is type(None):
        return "None"
    if base is bool:
        return "true or false (bool)"
    if base is float:
        return "a number (float)"
    if base is int:
        return "an integer (int)"
    if base is str:
        return "a string (str)"
    if base in (tuple, list):
        return f"a list ({spelled})"
    if base is dict:
        return f"a mapping ({spelled})"
    if dataclasses.is_dataclass(base):
        return f"a mapping of {base.__name__} keys"
    return f"a {spelled}"


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


def check_counts(owner: str | None, obj: Any, names: tuple[str, ...], *, minimum: int = 1) -> None:
    """Raise ``ValueError`` naming ``owner.name=value`` (``name=value`` without an owner) unless each
    attribute is an integer (not a bool) >= ``minimum``."""
    for name in names:
        value = getattr(obj, name)
        if not (isinstance(value, int) and not isinstance(value, bool) and value >= minimum):
            where = f"{owner}.{name}" if owner else name
            raise ValueError(f"{where}={value!r} must be an integer >= {minimum}")


def build_named(spec: Any, key: str, classes: Mapping[str, type], where: str) -> tuple[str, Any]:
    """``(name, built dataclass)`` of a config entry ``{key: name, **fields}`` whose name picks one of
    ``classes``; a bad entry, name or field is refused naming ``where`` (e.g. ``"wind[0]"``)."""
    if not isinstance(spec, Mapping) or key not in spec:
        raise ValueError(f"{where}={spec!r} must be a mapping with a {key!r}; allowed: {sorted(classes)}")
    fields = dict(spec)
    name = fields.pop(key)
    if name not in classes:
        raise ValueError(f"{where}: unknown {key} {name!r}; allowed: {sorted(classes)}")
    return name, build(classes[name], fields, prefix=f"{where}.")


def set_keys(values: Mapping[str, Any], updates: Mapping[str, Any]) -> dict[str, Any]:
    """``values`` with each dotted key of ``updates`` set (``hyperparameters.learning_rate``: the
    ``learning_rate`` of the ``hyperparameters`` section, made where missing); ``values`` is untouched."""
    out = dict(values)
    for key, value in updates.items():
        node = out
        *parents, leaf = key.split(".")
        for name in parents:
            node[name] = dict(node[name]) if isinstance(node.get(name), Mapping) else {}
            node = node[name]
        node[leaf] = value
    return out


def apply_overrides(values: Mapping[str, Any], overrides: list[str]) -> dict[str, Any]:
    """``values`` with each ``key.sub=value`` of ``overrides`` set (value parsed as YAML)."""
    updates = {}
    for item in overrides:
        key, sep, text = item.partition("=")
        if not sep or not key:
            raise ValueError(f"--set {item!r} must read key=value")
        updates[key] = yaml.safe_load(text)
    return set_keys(values, updates)
