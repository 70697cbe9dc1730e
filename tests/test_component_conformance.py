"""Every component's kernels against the same component's state-wise methods, one conformance test per
seam: a wind field's ``velocity`` kernel against ``velocity_at``, a point load's ``load`` kernel against
the resultant of ``point_load``, a rotor modifier's ``thrust`` kernel against ``added_thrust``, on
random states of several vehicles (each with its own table and state rows), to 1e-9. The physics step
runs the kernels, an episode's start (the trim) the methods: both must give the same air and loads.
Every registered wind model is here with its default settings (a new registration is tested at once),
beside the package's own fields, loads and rotor modifiers set to act. What each one's physics is, is
checked against references written apart from it (``tests/test_disturbances.py``, ``test_fan.py``,
``test_jet_turbulence.py``, ``test_sensors_payload.py``)."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

from quad_wrench_env.disturbances.base import resultant
from quad_wrench_env.disturbances.dryden import DrydenConfig, DrydenGust
from quad_wrench_env.disturbances.fan import FanConfig, FanJet
from quad_wrench_env.disturbances.ground_effect import GroundEffect
from quad_wrench_env.disturbances.jet import Jet, JetConfig
from quad_wrench_env.disturbances.payload import Payload, PayloadConfig
from quad_wrench_env.disturbances.wrench_profile import WrenchProfile
from quad_wrench_env.registry import registered
from quad_wrench_env.rotations import quat_from_euler_zyx, rotation_matrices
from quad_wrench_env.scene import Table, surface_tops
from quad_wrench_env.tasks.force_exertion import ConstantPush

COUNT, POINTS = 6, 5
NO_ARRAY = np.zeros((1, 0))


def _kernel(component, role: str):
    form = component.compiled
    module, _, function = dict(form.kernels)[role].rpartition(":")
    return getattr(importlib.import_module(module or form.module), function)


def _arrays(component) -> tuple[np.ndarray, np.ndarray]:
    """The component's table and state, as the engine hands them to its kernels."""
    form = component.compiled
    table = getattr(component, form.table) if form.table else NO_ARRAY
    state = getattr(component, form.state) if form.state else NO_ARRAY
    return table, state


def _started(component, rng: np.random.Generator):
    for index in range(COUNT):
        component.reset(index, rng)
    return component


def _winds() -> dict[str, object]:
    rng = np.random.default_rng(0)
    winds = {
        f"{name} (registered, defaults)": cls(cls.config_class(), COUNT)
        for name, cls in registered("wind").items()
    }
    winds["dryden in a mean wind, weather per vehicle"] = DrydenGust(
        DrydenConfig(w20=3.0, altitude=1.5, mean=(1.2, -0.7, 0.1)), COUNT
    )
    winds["dryden in a mean wind, weather per vehicle"].weather[::2] = np.column_stack(
        (rng.normal(0.0, 1.5, (3, 3)), rng.uniform(0.0, 2.0, 3))
    )
    turbulent = JetConfig(position=(2.3, -1.0, 1.0), direction=(0.2, 1.0, 0.1), turbulence_intensity=0.2)
    winds["turbulent jet, speed per vehicle"] = Jet(turbulent, COUNT)
    winds["turbulent jet, speed per vehicle"].speed_scale[:, 0] = rng.uniform(0.0, 2.0, COUNT)
    winds["turbulent fan"] = FanJet(FanConfig(turbulence_intensity=0.15), COUNT)
    for wind in winds.values():
        _started(wind, rng)
    return winds


WINDS = _winds()


def _states(rng: np.random.Generator):
    """Random rigid-body states of COUNT vehicles near the fan's axis and the jets (world frame)."""
    position = np.column_stack(
        (rng.uniform(0.5, 3.5, COUNT), rng.uniform(-1.0, 1.0, COUNT), rng.uniform(0.5, 1.5, COUNT))
    )
    angles = rng.uniform(-0.4, 0.4, (COUNT, 3))
    rotation = rotation_matrices(np.array([quat_from_euler_zyx(*a) for a in angles]))
    return position, rng.normal(0.0, 1.0, (COUNT, 3)), rng.normal(0.0, 2.0, (COUNT, 3)), rotation


@pytest.mark.parametrize("name", sorted(WINDS))
def test_a_wind_fields_velocity_kernel_is_its_velocity_at(name):
    wind = WINDS[name]
    rng = np.random.default_rng(1)
    position = _states(rng)[0]
    points = position[:, None, :] + rng.normal(0.0, 0.3, (COUNT, POINTS, 3))
    time = rng.uniform(0.0, 10.0, COUNT)
    out = rng.standard_normal(points.shape)  # the kernel adds to what is there
    before = out.copy()
    _kernel(wind, "velocity")(wind.kernel_parameters(), *_arrays(wind), points, time, out)
    expected = wind.velocity_at(points, time, slice(None))
    np.testing.assert_allclose(out - before, expected, atol=1e-9)
    if name.startswith(("turbulent", "dryden")):
        assert np.abs(expected).max() > 0.1, "the sample must reach the field"


LOADS = {
    "payload under a rotor": Payload(
        PayloadConfig(mass=0.053, point=(0.129, 0.129, -0.02), attach_time=2.0, release_time=8.0)
    ),
    "scheduled wrench": WrenchProfile(
        [[1.0, 6.0, 0.3, -0.2, 0.1, 0.01, -0.02, 0.03], [4.0, 9.0, 0.0, 0.5, 0.0, 0.0, 0.0, -0.01]]
    ),
    "push per vehicle": ConstantPush(COUNT),
}
LOADS["push per vehicle"].force[:] = np.random.default_rng(2).normal(0.0, 1.0, (COUNT, 3))


@pytest.mark.parametrize("name", sorted(LOADS))
def test_a_point_loads_kernel_is_the_resultant_of_its_point_load(name):
    load = LOADS[name]
    rng = np.random.default_rng(3)
    position, velocity, angular_velocity, rotation = _states(rng)
    time = np.linspace(0.0, 10.0, COUNT)
    body = type("Body", (), {})()
    body.position, body.velocity, body.angular_velocity, body.rotation = (
        position,
        velocity,
        angular_velocity,
        rotation,
    )
    out = rng.standard_normal((COUNT, 6))
    before = out.copy()
    _kernel(load, "load")(
        load.kernel_parameters(), *_arrays(load), time, position, velocity, angular_velocity, rotation, out
    )
    acting = load.point_load(time, body, slice(None))
    expected = np.zeros((COUNT, 6)) if acting is None else np.concatenate(resultant(*acting), axis=1)
    np.testing.assert_allclose(out - before, expected, atol=1e-9)
    assert np.abs(expected).max() > 0.01  # the sample reaches its action


def test_a_rotor_modifiers_kernel_is_its_added_thrust():
    tops = surface_tops(
        [
            Table(center=(2.0, 0.0), size=(1.0, 0.6), height=0.75),
            Table(center=(2.2, 0.2), size=(0.4, 0.4), height=0.9),
        ]
    )
    effect = GroundEffect(0.1, tops)
    rng = np.random.default_rng(4)
    hubs = np.column_stack(
        (
            rng.uniform(1.3, 2.7, 4 * COUNT),
            rng.uniform(-0.5, 0.5, 4 * COUNT),
            rng.uniform(0.01, 1.2, 4 * COUNT),
        )
    ).reshape(COUNT, 4, 3)
    rotation = _states(rng)[3]
    thrusts = rng.uniform(0.5, 1.5, (COUNT, 4))
    out = rng.standard_normal((COUNT, 4))
    before = out.copy()
    _kernel(effect, "thrust")(effect.kernel_parameters(), *_arrays(effect), hubs, rotation, thrusts, out)
    expected = effect.added_thrust(hubs, rotation, thrusts)
    assert np.abs(expected).max() > 0.05
    np.testing.assert_allclose(out - before, expected, atol=1e-9)


def test_every_component_of_the_package_has_a_conformance_case():
    """Every class under ``quad_wrench_env.disturbances`` and ``quad_wrench_env.tasks`` with a compiled
    form is flown by a case above (registered wind models come in by themselves; a new point load or
    rotor modifier fails here until it has one)."""
    import inspect
    import pkgutil

    import quad_wrench_env.disturbances
    import quad_wrench_env.tasks
    from quad_wrench_env.disturbances.base import CompiledForm

    found = set()
    for package in (quad_wrench_env.disturbances, quad_wrench_env.tasks):
        for info in pkgutil.iter_modules(package.__path__):
            module = importlib.import_module(f"{package.__name__}.{info.name}")
            for _, cls in inspect.getmembers(module, inspect.isclass):
                if cls.__module__ == module.__name__ and isinstance(
                    getattr(cls, "compiled", None), CompiledForm
                ):
                    found.add(cls)
    covered = {type(c) for c in (*WINDS.values(), *LOADS.values())} | {GroundEffect}
    assert found, "no compiled components found: the scan is broken"
    assert not found - covered, (
        f"components without a conformance case: {sorted(c.__name__ for c in found - covered)}"
    )
