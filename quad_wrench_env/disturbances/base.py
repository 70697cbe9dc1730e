"""The seams of the engine: what a wind field, a point load and a rotor modifier are.

Each kind of component is a small :class:`~typing.Protocol` and a compiled form
(:class:`CompiledForm`: numba kernels beside the component, named by module and function), which the
engine composes into its physics step (:mod:`quad_wrench_env.engine.compose`) without listing any
component itself. The protocols' methods (for N vehicles at once) give what the engine needs at an
episode's start, where the vehicle is placed trimmed in the loads: the air velocity, the loads and
the added thrust at a given state; every physics step runs on the kernels.

A :class:`WindField` gives the air velocity at world points; the body's drag (:mod:`.drag`) turns it
into forces at body points. A :class:`PointLoad` adds forces at body points (a payload, a scheduled
wrench). A :class:`RotorModifier` adds thrust to each rotor from the state (ground effect), applied
at the hubs. The resultant about the centre of mass (:func:`resultant`) is what the world applies
beyond the nominal rotors (``wrench_true``): torques are never written as formulas, they come out of
``Σ r_j × F_j``.

Compiled kernels take the component's packed numbers first, always in this order: ``params`` (1-D,
:meth:`kernel_parameters`), ``table`` ((N, W) per-vehicle numbers, :attr:`CompiledForm.table`, or an
empty (1, 0) array) and ``state`` ((N, width) per-vehicle state named by :attr:`CompiledForm.state`, a
view of the engine's step buffer; an empty (1, 0) array without state). Then, by role:

=====================  ===========================================================================
role                   kernel arguments after ``params, table, state``
=====================  ===========================================================================
wind ``velocity``      ``points`` (N, P, 3) world points, ``time`` (N,), ``out`` (N, P, 3): adds
                       the air velocity at each point to ``out``
wind ``advance``       ``position`` (N, 3), ``velocity`` (N, 3), ``dt``, ``normals`` (N, width): one
                       physics step of the field's random processes on its own standard normal draws
point load ``load``    ``time`` (N,), the vehicles' rigid-body state: ``position``, ``velocity``,
                       ``angular_velocity`` (N, 3, world frame) and ``rotation`` (N, 3, 3); ``out``
                       (N, 6): adds ``[F, τ]`` about the centre of mass (world frame)
rotor ``thrust``       ``hubs`` (N, 4, 3) world hub positions, ``rotation`` (N, 3, 3), ``thrusts``
                       (N, 4) true rotor thrusts (N), ``out`` (N, 4): adds thrust to each rotor
=====================  ===========================================================================
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from quad_wrench_env.config import build_named
from quad_wrench_env.numerics import njit
from quad_wrench_env.registry import lookup, registered, resolve
from quad_wrench_env.rotations import cross


@dataclass(frozen=True)
class CompiledForm:
    """Where a component's numba kernels live, and what of it they read besides its parameters."""

    module: str
    """Import path of the module holding the kernels (beside the component)."""
    kernels: tuple[tuple[str, str], ...]
    """``(role, function name)`` pairs; roles as in the module docstring's table. A name
    ``"module:function"`` takes the function from another module (e.g. :data:`STILL`)."""
    state: str | None = None
    """Name of the component's (N, width) state array, which the compiled step turns into a view of
    its buffer (the kernels update it in place), or None without state."""
    table: str | None = None
    """Name of the component's (N, W) per-vehicle table attribute (e.g. each vehicle's fan motion),
    read again at every episode start, or None."""


@runtime_checkable
class Component(Protocol):
    """What every component has: its name in errors, its compiled form and its packed numbers."""

    name: str
    compiled: CompiledForm
    """Its kernels (the engine refuses a component whose ``compiled`` is None, by name)."""

    def kernel_parameters(self) -> np.ndarray:
        """The component's numbers as its kernels read them (1-D float array), read again at every
        episode start (their count must not change; per-vehicle data belongs in the table)."""


@runtime_checkable
class WindField(Component, Protocol):
    """Air velocity over the world, possibly moving and turbulent, as each of N vehicles meets it
    (every vehicle flies in a copy of the field of its own, with its own time and random state)."""

    noise_width: int
    """Standard normal draws the field takes per vehicle and physics step (its own columns)."""

    def reset(self, index: int, rng: np.random.Generator) -> None:
        """Start a new episode of vehicle ``index``; its random draws at reset come from ``rng`` (its
        random processes then advance in the compiled ``advance`` kernel)."""

    def velocity_at(
        self, points: np.ndarray, t: np.ndarray, index: np.ndarray | slice, mean: bool = False
    ) -> np.ndarray:
        """(n, P, 3) air velocity (m/s, world frame) at (n, P, 3) world points of the vehicles
        ``index`` at their times ``t`` (n,) (s); ``mean=True`` leaves out the turbulent part."""


class BodyState(Protocol):
    """The vehicles' rigid-body state a point load reads (the engine's ``RigidBodyState``), world frame,
    each with a leading vehicle axis."""

    position: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray
    rotation: np.ndarray


@runtime_checkable
class PointLoad(Component, Protocol):
    """Forces at body points besides the air's (a hung payload, a scheduled wrench)."""

    def point_load(
        self, t: np.ndarray, body: BodyState, index: np.ndarray | slice = slice(None)
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """``(offsets (n, K, 3) from the centres of mass, forces (n, K, 3))``, world frame, for the n
        vehicles ``index`` at times ``t`` (n,) in the rigid-body states ``body`` (n: position, velocity,
        angular velocity, rotation, ...); None when it never acts."""


@runtime_checkable
class RotorModifier(Component, Protocol):
    """Thrust each rotor gains (or loses) from the state, e.g. ground effect; the engine applies it
    along the body z axis at the hubs, as an external load (it is in ``wrench_true``)."""

    def added_thrust(self, hubs: np.ndarray, rotation: np.ndarray, thrusts: np.ndarray) -> np.ndarray:
        """(n, 4) thrust (N) added to each rotor of n vehicles with world hub positions ``hubs``
        (n, 4, 3), attitudes ``rotation`` (n, 3, 3) and true rotor thrusts ``thrusts`` (n, 4)."""


class Steady:
    """What a wind field without random processes shares: no draws, nothing to reset, and the
    compiled ``advance`` that does nothing (:func:`still`)."""

    noise_width = 0

    def reset(self, index: int, rng: np.random.Generator) -> None:
        """Nothing random."""


@njit
def still(params, table, state, position, velocity, dt, normals):
    """The compiled ``advance`` of a :class:`Steady` field."""


STILL = ("advance", "quad_wrench_env.disturbances.base:still")
"""The ``advance`` entry of a :class:`Steady` field's :attr:`CompiledForm.kernels`."""


def resultant(offsets: np.ndarray, forces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Total force and torque about the centre of mass of forces applied at world offsets ``r_j``.

    Both arrays are (..., P, 3) in the world frame; returns ``(Σ F_j, Σ r_j × F_j)``, each (..., 3).
    """
    return forces.sum(axis=-2), cross(offsets, forces).sum(axis=-2)


@dataclass(frozen=True)
class Outlet:
    """A wind field's visible source (a fan's or a jet's outlet) as one vehicle sees it now: what the
    renderer draws, for any wind field that has one (:class:`Visible`)."""

    origin: np.ndarray
    """(3,) centre of the outlet (m, world frame)."""
    axis: np.ndarray
    """(3,) unit direction of the jet's axis as seen from the vehicle now."""
    facing: np.ndarray
    """(3,) unit direction the outlet faces (a moving fan's stays along +x whatever its axis does)."""
    radius: float
    """m: the outlet's radius."""
    spread: float
    """The jet's spreading rate (half-width growth per metre)."""
    active: bool = True
    """Whether it blows in the vehicle's episode."""
    moving: bool = False
    """Whether it moves (the camera keeps it in view first)."""


@runtime_checkable
class Visible(Protocol):
    """A wind field with a source to draw."""

    def outlet(self, vehicle: int, time: float, position: np.ndarray) -> Outlet | None:
        """Its outlet as vehicle ``vehicle`` at ``position`` (3,) sees it at its ``time``; None when
        there is none (e.g. a switched-off fan)."""


def named_config(kind: str, key: str, spec: Mapping[str, Any], where: str) -> tuple[str, Any]:
    """The name and built config of a config entry ``{key: name, **fields}`` naming a registered
    ``kind`` (each with its ``config_class``; ``"module:name"`` imports the module first), bad names and
    keys refused naming ``where`` (e.g. ``"wind[0]"``)."""
    if isinstance(spec, Mapping) and key in spec:
        spec = {**spec, key: resolve(spec[key])}
    configs = {name: cls.config_class for name, cls in registered(kind).items()}
    return build_named(spec, key, configs, where)


def wind_config(spec: Mapping[str, Any], position: int = 0) -> tuple[str, Any]:
    """The model name and built config of one ``wind`` entry, ``{"model": name, **fields}``."""
    return named_config("wind", "model", spec, f"wind[{position}]")


def make_wind(spec: Mapping[str, Any], count: int, position: int = 0) -> WindField:
    """The wind field of one ``wind`` entry for ``count`` vehicles."""
    name, config = wind_config(spec, position)
    return lookup("wind", name)(config, count)


def load_config(spec: Mapping[str, Any], position: int = 0) -> tuple[str, Any]:
    """The name and built config of one ``loads`` entry, ``{"load": name, **fields}``."""
    return named_config("load", "load", spec, f"loads[{position}]")


def make_load(spec: Mapping[str, Any], count: int, position: int = 0) -> PointLoad:
    """The point load of one ``loads`` entry for ``count`` vehicles."""
    name, config = load_config(spec, position)
    return lookup("load", name)(config, count)
