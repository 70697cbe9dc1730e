"""Compiled (numba) forms of the per-step hot paths: the estimators' kernels and the helpers every
kernel shares (this package holds no engine or task code).

numba is a core dependency: the kernels (the engine's, the components', the tasks' and the
estimators') are the product's one implementation of the physics and the filters. Under numba's
``NUMBA_DISABLE_JIT=1`` :func:`njit` leaves a kernel a plain Python function, to step through in a
debugger: the same code, slower by orders of magnitude (:data:`COMPILED` is then False and the UKF
bank runs filter by filter, the lanes having no Python form). Compiled code is cached on disk
(numba's ``cache=True``), so the compile cost (seconds) is paid once per machine, not per env.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import Any

import numba as _numba

COMPILED = not _numba.config.DISABLE_JIT
"""Whether :func:`njit` compiles: ``NUMBA_DISABLE_JIT`` is not set (module docstring)."""


def njit(function=None, *, inline: bool = False):
    """``numba.njit(cache=True)`` (IEEE arithmetic, no fast-math; the function unchanged under
    ``NUMBA_DISABLE_JIT=1``); ``inline=True`` inlines a small helper into its callers (a call across
    modules otherwise costs more than a short loop). No kernel lets the compiler regroup sums (fast-math's
    ``reassoc``): the grouping would follow the CPU's vector width, and a vehicle of a vector env
    would no longer give the single env's bits on every host (``tests/test_determinism.py``)."""
    if function is None:
        return lambda f: njit(f, inline=inline)
    return _numba.njit(
        cache=True,
        error_model="numpy",
        inline="always" if inline else "never",
        fastmath=False,
    )(function)


def specialised(kernel: Callable[..., Any], *arguments: Any) -> Callable[..., Any]:
    """``kernel``'s compiled form for the types of ``arguments`` (numba's ``Dispatcher.compile``,
    from the disk cache when there), to call with arguments of exactly those types: it skips the
    dispatcher's typing of the arguments on every call (the unboxing of each array remains: hence
    kernels with few array arguments).
    ``kernel`` itself under ``NUMBA_DISABLE_JIT=1``."""
    if not isinstance(kernel, _numba.core.registry.CPUDispatcher):
        return kernel
    compiled = kernel.compile(tuple(_numba.typeof(argument) for argument in arguments))
    return compiled if callable(compiled) else kernel  # what compile returns is not numba's documented API


def bind(kernel: Callable[..., Any], *arguments: Any) -> Callable[[], Any]:
    """``kernel`` called on ``arguments`` by a call without arguments, on its :func:`specialised` form:
    the arguments stay the same objects (arrays updated in place), so their types cannot change."""
    return partial(specialised(kernel, *arguments), *arguments)
