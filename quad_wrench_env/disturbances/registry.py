"""Wind models by name, discovered from the modules of :mod:`quad_wrench_env.disturbances`.

A wind model registers itself where it is defined (``@wind_model("dryden", DrydenConfig)``); nothing
lists them. ``wind=[{"model": "dryden", ...}, ...]`` in any env's config builds them by name.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable, Mapping
from typing import Any

from quad_wrench_env.config import build_named

WIND_MODELS: dict[str, tuple[type, Callable[..., Any]]] = {}
"""Model name -> (its config dataclass, its factory ``(config, count) -> WindField``)."""


def wind_model(name: str, config_class: type) -> Callable[[type], type]:
    """Class decorator: register a wind field class, built as ``cls(config, count)``, as ``name``."""

    def register(cls: type) -> type:
        cls.wind_model = (name, config_class)  # type: ignore[attr-defined]
        WIND_MODELS[name] = (config_class, cls)
        return cls

    return register


def _discover() -> None:
    """Register the package's own models: every class of its modules marked by :func:`wind_model`
    (read from the classes, so a registry emptied or replaced after their import is refilled)."""
    package = importlib.import_module("quad_wrench_env.disturbances")
    for info in pkgutil.iter_modules(package.__path__):
        module = importlib.import_module(f"{package.__name__}.{info.name}")
        for value in vars(module).values():
            mark = getattr(value, "wind_model", None) if isinstance(value, type) else None
            if mark is not None:
                WIND_MODELS.setdefault(mark[0], (mark[1], value))


def wind_config(spec: Mapping[str, Any], position: int = 0) -> tuple[str, Any]:
    """The model name and built config of one ``wind`` entry, bad names and keys named."""
    _discover()  # a model registered elsewhere first must not hide the package's own
    configs = {name: config for name, (config, _) in WIND_MODELS.items()}
    return build_named(spec, "model", configs, f"wind[{position}]")


def make_wind(spec: Mapping[str, Any], count: int, position: int = 0) -> Any:
    """The wind field of one ``wind`` entry for ``count`` vehicles."""
    name, config = wind_config(spec, position)
    return WIND_MODELS[name][1](config, count)
