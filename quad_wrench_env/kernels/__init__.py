"""Compiled (numba) forms of the per-step hot paths: the estimators' kernels and the helpers every
kernel shares (this package holds no engine or task code).

numba is a core dependency: the compiled path is the product's speed. The engine's numpy code stays
the reference, selectable and tested (config ``backend``: ``"auto"`` picks numba when it imports,
``"numpy"`` forces the reference, ``"numba"`` requires it; ``QUAD_WRENCH_DISABLE_NUMBA=1`` makes
``"auto"`` pick numpy, e.g. to check the reference alone); the tests run both paths and compare
them. The estimators have one implementation, their kernels, on every backend (each loops over the
filters of a bank; the UKF of a larger bank runs eight filters at a time on SIMD lanes,
:mod:`.lanes`). Under numba's ``NUMBA_DISABLE_JIT=1`` (or without numba) :func:`njit` leaves a
kernel a plain Python function, to step through in a debugger: the same code, slower by orders of
magnitude (:data:`COMPILED` is then False and the UKF bank runs filter by filter, the lanes having no
Python form). Compiled code is cached on disk (numba's ``cache=True``), so the compile cost (seconds)
is paid once per machine, not per env.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable
from functools import partial
from typing import Any

BACKENDS = ("auto", "numpy", "numba")

try:  # a core dependency, but the numpy reference runs without it (e.g. where numba has no wheel)
    import numba as _numba
except ImportError:  # pragma: no cover - exercised where numba is absent
    _numba = None

NUMBA_AVAILABLE = _numba is not None and os.environ.get("QUAD_WRENCH_DISABLE_NUMBA", "") != "1"

COMPILED = _numba is not None and not _numba.config.DISABLE_JIT
"""Whether :func:`njit` compiles: numba imports and ``NUMBA_DISABLE_JIT`` is not set (module docstring)."""

_warned_missing = False
"""Whether ``backend="auto"`` has said that numba does not import (once per process)."""


def resolve_backend(backend: str) -> str:
    """``"numpy"`` or ``"numba"`` for a configured backend; bad names and a missing numba are refused."""
    if backend not in BACKENDS:
        raise ValueError(f"backend={backend!r} is unknown; allowed: {list(BACKENDS)}")
    if backend == "auto":
        global _warned_missing
        if _numba is None and not _warned_missing:  # not silently 30-50x slower; the env var is a choice
            _warned_missing = True
            warnings.warn(
                "numba does not import: backend='auto' runs the numpy reference, 30-50x slower, and the "
                "estimators' kernels as plain Python, slower still (pip install numba, a dependency of "
                "quad-wrench-env)",
                stacklevel=2,
            )
        return "numba" if NUMBA_AVAILABLE else "numpy"
    if backend == "numba" and not NUMBA_AVAILABLE:
        raise ValueError(
            "backend='numba' needs numba (pip install numba, a dependency of quad-wrench-env); "
            "allowed without it: 'numpy', 'auto'"
        )
    return backend


def njit(function=None, *, inline: bool = False):
    """``numba.njit(cache=True)`` (IEEE arithmetic, no fast-math), or the function unchanged without
    numba; ``inline=True`` inlines a small helper into its callers (a call across modules otherwise
    costs more than a short loop). No kernel lets the compiler regroup sums (fast-math's
    ``reassoc``): the grouping would follow the CPU's vector width, and a vehicle of a vector env
    would no longer give the single env's bits on every host (``tests/test_determinism.py``)."""
    if function is None:
        return lambda f: njit(f, inline=inline)
    if _numba is None:
        return function
    return _numba.njit(
        cache=True,
        error_model="numpy",
        inline="always" if inline else "never",
        fastmath=False,
    )(function)


def specialised(kernel: Callable[..., Any], *arguments: Any) -> Callable[..., Any]:
    """``kernel``'s compiled form for the types of ``arguments`` (numba's ``Dispatcher.compile``,
    from the disk cache when there), to call with arguments of exactly those types: it skips the
    dispatcher's typing of the arguments on every call (about 80 ns per call and 10 ns per array;
    the unboxing, about 35 ns per array, remains: hence kernels with few array arguments).
    ``kernel`` itself without numba."""
    if _numba is None or not isinstance(kernel, _numba.core.registry.CPUDispatcher):
        return kernel
    compiled = kernel.compile(tuple(_numba.typeof(argument) for argument in arguments))
    return compiled if callable(compiled) else kernel  # what compile returns is not numba's documented API


def bind(kernel: Callable[..., Any], *arguments: Any) -> Callable[[], Any]:
    """``kernel`` called on ``arguments`` by a call without arguments, on its :func:`specialised` form:
    the arguments stay the same objects (arrays updated in place), so their types cannot change."""
    return partial(specialised(kernel, *arguments), *arguments)
