"""The fixed jet's turbulence (quad_wrench_env/disturbances/jet.py): the intensity and length scale asked
for, through its compiled kernels; off by default; DisturbanceRejection's keys.

The expected numbers are written here from the jet's definition (``docs/physics.md``, "Fan": Gaussian profile,
``u_c = U0·min(1, D/(√2·b))``, ``b = sqrt((D/2)² + (c·x)²)``) and the statistics of a first-order
(AR(1)) process sampled every ``dt`` with ``a = exp(-dt·u/L)``: the variance of its sample variance is
``2σ⁴(1 + a²)/(N(1 - a²))`` and the variance of its sample autocorrelation at lag k is Bartlett's
``((1 + a²)(1 - a^{2k})/(1 - a²) - 2k·a^{2k})/N``, N the number of samples."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

from quad_wrench_env.disturbances.jet import Jet, JetConfig
from quad_wrench_env.disturbances.jet_kernels import fixed_jet_advance, fixed_jet_velocity

DT, STEPS, COPIES = 0.005, 20_000, 20
"""The physics step, steps per run (100 s) and independent copies (vehicles) of the field."""
ORIGIN, DIAMETER, SPREAD, SCALE = (0.0, 0.0, 1.0), 0.6, 0.42, 9.0
POINT = np.array((0.0, 1.0, 1.0))
"""A fixed point on the axis, 1 m from the outlet of a jet blowing along +y."""


def _axis_speed_and_half_width(distance: float) -> tuple[float, float]:
    b = math.sqrt((DIAMETER / 2) ** 2 + (SPREAD * distance) ** 2)
    return SCALE * min(1.0, DIAMETER / (math.sqrt(2.0) * b)), b


def _velocities(jet: Jet) -> np.ndarray:
    """(STEPS, COPIES, 3) air velocity at :data:`POINT` for each copy, stepped with its own draws."""
    rng = np.random.default_rng(11)
    for i in range(COPIES):
        jet.reset(i, rng)
    points = np.broadcast_to(POINT, (COPIES, 1, 3)).copy()
    position, velocity = points[:, 0, :].copy(), np.zeros((COPIES, 3))
    out = np.empty((STEPS, COPIES, 3))
    params, air, time = jet.kernel_parameters(), np.zeros((COPIES, 1, 3)), np.zeros(COPIES)
    for k in range(STEPS):
        normals = rng.standard_normal((COPIES, 3))
        fixed_jet_advance(params, jet.speed_scale, jet.turbulence, position, velocity, DT, normals)
        air[:] = 0.0
        fixed_jet_velocity(params, jet.speed_scale, jet.turbulence, points, time, air)
        out[k] = air[:, 0, :]
    return out


@pytest.mark.parametrize(("intensity", "length"), [(0.15, 0.3), (0.1, None)])
def test_the_jet_turbulence_has_the_intensity_and_length_scale_asked_for(intensity, length):
    """100 s of 20 copies at a point on the axis (outlet speed set per vehicle, as DisturbanceRejection
    does): each component's sd is ``I·u_c`` and its autocorrelation time ``L/u_c`` (L the half-width
    there when none is given), within 4 sd of their estimates for this many correlated samples."""
    config = JetConfig(
        position=ORIGIN,
        direction=(0.0, 1.0, 0.0),
        speed=1.0,
        diameter=DIAMETER,
        spread=SPREAD,
        turbulence_intensity=intensity,
        turbulence_length=length,
    )
    jet = Jet(config, COPIES)
    jet.speed_scale[:] = SCALE
    u, b = _axis_speed_and_half_width(1.0)
    time_scale = (b if length is None else length) / u
    a = math.exp(-DT / time_scale)

    air = _velocities(jet)
    np.testing.assert_allclose(air.mean(axis=(0, 1)), (0.0, u, 0.0), atol=0.02 * u)
    series = (air - air.mean(axis=0)).reshape(STEPS, -1)  # 60 series: 20 copies x 3 components
    samples = series.size
    sd = math.sqrt(float(np.mean(series**2)))
    sd_tolerance = 4.0 * 0.5 * math.sqrt(2.0 * (1 + a * a) / (samples * (1 - a * a)))
    assert sd == pytest.approx(intensity * u, rel=sd_tolerance)

    lag = round(time_scale / DT)
    rho = float(np.sum(series[lag:] * series[:-lag]) / np.sum(series[:-lag] ** 2))
    bartlett = ((1 + a * a) * (1 - a ** (2 * lag)) / (1 - a * a) - 2 * lag * a ** (2 * lag)) / samples
    measured_time = -lag * DT / math.log(rho)
    expected_rho = a**lag
    time_tolerance = 4.0 * math.sqrt(bartlett) / (expected_rho * abs(math.log(expected_rho)))
    assert measured_time == pytest.approx(time_scale, rel=time_tolerance)
    assert time_tolerance < 0.05 and sd_tolerance < 0.02  # the test can tell


def test_the_jet_is_steady_by_default_and_draws_nothing():
    """Without turbulence the jet keeps no state, draws no normals and has the steady compiled form, so
    flights without it keep their random numbers; turbulence needs an intensity in [0, 1) and a
    length > 0, named when wrong."""
    steady = Jet(JetConfig(), 2)
    assert steady.noise_width == 0 and steady.compiled.state is None
    turbulent = Jet(JetConfig(turbulence_intensity=0.1), 2)
    assert turbulent.noise_width == 3 and turbulent.compiled.state == "turbulence"
    with pytest.raises(ValueError, match=r"turbulence_intensity=1.2 must be in \[0, 1\)"):
        JetConfig(turbulence_intensity=1.2)
    with pytest.raises(ValueError, match=r"turbulence_length=0.0 must be a finite number > 0"):
        JetConfig(turbulence_intensity=0.1, turbulence_length=0.0)


def test_disturbance_rejection_takes_the_jet_turbulence_from_its_config():
    """``jet_crossing.jet_turbulence_intensity`` and ``jet_turbulence_length`` reach the task's jet (off
    by default), a bad value is refused by its key, and a turbulent crossing flies differently."""
    env_id = "QuadWrench/DisturbanceRejection-v0"
    finals = []
    for crossing in ({}, {"jet_turbulence_intensity": 0.2, "jet_turbulence_length": 0.4}):
        env = gym.make(env_id, jet_crossing=crossing, episode_seconds=2.0)
        try:
            jet = env.unwrapped.task.jets[0]
            assert jet.noise_width == (3 if crossing else 0)
            assert jet.config.turbulence_length == crossing.get("jet_turbulence_length")
            env.reset(seed=0, options={"jet_speed": 10.0})
            for _ in range(20):
                _, _, _, _, info = env.step(np.zeros(4, dtype=np.float32))
            finals.append(info["wrench_true"])
        finally:
            env.close()
    assert not np.allclose(finals[0], finals[1])
    with pytest.raises(ValueError, match=r"jet_crossing.jet_turbulence_intensity=-0.1"):
        gym.make(env_id, jet_crossing={"jet_turbulence_intensity": -0.1})
