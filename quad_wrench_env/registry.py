"""One registry of everything a config or a command names: wind models, scene parts, estimators, tasks
and agents.

Each entry registers itself where it is defined::

    @register("wind", "thermal")         # a wind field class with a ``config_class``:
    class Thermal: ...                   #   gym.make(id, wind=[{"model": "thermal", "speed": 2.0}])

    @register("load", "tether")          # a point load class with a ``config_class``:
    class Tether: ...                    #   gym.make(id, loads=[{"load": "tether", "length": 0.8}])

    @register("scene", "ramp")           # a scene-part dataclass: scene=[{"kind": "ramp", ...}]
    @register("agent", "compliant_hold") # a policy class: make_agent("compliant_hold", k=1.0)
    @register("task")                    # a task class, under its ``env_id``, which is then a Gymnasium
    class HoldPoint: ...                 #   id with a single and a vector entry point

    register("estimator", "quasi_static", EstimatorEntry(...))   # a value rather than a class

:func:`registered` gives a kind's entries (a live, read-only mapping: ``AGENTS``, ``ESTIMATORS`` and
``TASKS`` are such views) and :func:`lookup` one of them, an unknown name refused with the allowed ones.
Wherever a config or a command names an entry, ``"package.module:name"`` imports that module first (which
registers its entries) and then takes ``name``: a user's own estimator, wind model, scene part or agent
enters any config in one line, e.g. ``estimator="my_lab.estimators:quasi_static"``.
Both first import the package's own modules of that kind (:data:`HOMES`), so the package lists nothing
twice and never scans for modules. A name taken by another object is refused, naming both.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any, TypeVar

T = TypeVar("T")

HOMES: dict[str, tuple[str, ...]] = {
    "wind": (
        "quad_wrench_env.disturbances.dryden",
        "quad_wrench_env.disturbances.one_cosine",
        "quad_wrench_env.disturbances.jet",
    ),
    "load": (),
    "scene": ("quad_wrench_env.scene",),
    "estimator": ("quad_wrench_env.estimators",),
    "task": ("quad_wrench_env.tasks",),
    "agent": ("quad_wrench_env.agents",),
}
"""Each kind and the package's modules that register its entries (the package names no point load
(``"load"``): its payload and scheduled wrench have keys of their own)."""

_ENTRIES: dict[str, dict[str, Any]] = {kind: {} for kind in HOMES}
_NO_VALUE = object()


def _check_kind(kind: str) -> None:
    if kind not in HOMES:
        raise ValueError(f"unknown registry kind {kind!r}; allowed: {list(HOMES)}")


def _label(obj: Any) -> str:
    """``module.name`` of a class or function (of the type for other values)."""
    named = obj if hasattr(obj, "__qualname__") else type(obj)
    return f"{named.__module__}.{named.__qualname__}"


def register(kind: str, name: str | None = None, value: Any = _NO_VALUE) -> Any:
    """Register ``value`` as ``name`` of ``kind``, or, without a value, return a decorator that
    registers the class or function it decorates. A task's name is its ``env_id`` (``name`` may be
    left out) and registering it also registers that Gymnasium id."""
    _check_kind(kind)

    def add(obj: T) -> T:
        key = name
        if kind == "task":
            env_id = getattr(obj, "env_id", None)
            if not isinstance(env_id, str) or (key is not None and key != env_id):
                raise ValueError(f"a task registers under its env_id (got name={key!r}, env_id={env_id!r})")
            key = env_id
        if not (isinstance(key, str) and key):
            raise ValueError(f"{kind} entries need a non-empty name, got {key!r}")
        taken = _ENTRIES[kind].get(key)
        if taken is not None and taken is not obj and _label(taken) != _label(obj):
            raise ValueError(f"{kind} {key!r} is already registered as {_label(taken)}; pick another name")
        if kind == "task":
            _register_env_id(obj)
        _ENTRIES[kind][key] = obj
        return obj

    return add if value is _NO_VALUE else add(value)


def _load(kind: str) -> None:
    """Import the package's own modules of ``kind`` (a module being imported is left to finish)."""
    for module in HOMES[kind]:
        importlib.import_module(module)


def registered(kind: str) -> Mapping[str, Any]:
    """``kind``'s entries by name: a live, read-only view."""
    _check_kind(kind)
    _load(kind)
    return MappingProxyType(_ENTRIES[kind])


def resolve(name: Any) -> Any:
    """``name``, or for ``"package.module:name"`` the part after the colon once that module is imported
    (its entries registered); a module that does not import is refused, naming it."""
    if not (isinstance(name, str) and ":" in name):
        return name
    module, _, key = name.partition(":")
    try:
        importlib.import_module(module)
    except ImportError as error:
        raise ValueError(f"{name!r}: module {module!r} does not import ({error})") from None
    return key


def lookup(kind: str, name: str) -> Any:
    """The entry ``name`` of ``kind`` (or ``"module:name"``, :func:`resolve`); an unknown name is
    refused, listing the allowed ones."""
    name = resolve(name)
    entries = registered(kind)
    if name not in entries:
        raise ValueError(f"unknown {kind} {name!r}; allowed: {sorted(entries)}")
    return entries[name]


def bare_env_id(env_id: str) -> str:
    """``env_id`` without a ``module:`` prefix (``quad_wrench_env:QuadWrench/FanTracking-v1``: the
    ``QuadWrench/FanTracking-v1`` a task registers)."""
    return env_id.split(":", 1)[1] if ":" in env_id else env_id


def env_entry_points(task: type) -> tuple[str, str]:
    """The single and the vector entry point of ``task``'s env id (classes generated on first use by
    :mod:`quad_wrench_env.envs.env_classes`)."""
    module = "quad_wrench_env.envs.env_classes"
    return f"{module}:{task.__name__}Env", f"{module}:{task.__name__}VectorEnv"


def _register_env_id(task: type) -> None:
    from gymnasium.envs.registration import register as gym_register
    from gymnasium.envs.registration import registry as gym_registry

    clash = [
        t for t in _ENTRIES["task"].values() if t.__name__ == task.__name__ and _label(t) != _label(task)
    ]
    if clash:
        raise ValueError(
            f"task class name {task.__name__!r} is already taken by {_label(clash[0])}; its env classes "
            "are named after it, so rename one"
        )
    if task.env_id not in gym_registry:
        single, vector = env_entry_points(task)
        gym_register(id=task.env_id, entry_point=single, vector_entry_point=vector)
