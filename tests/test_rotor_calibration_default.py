"""``rotor_calibration: "preset"`` (the default): the 27 g crazyflie2 flies calibrated rotors, the others the
nominal mixer; the filters report the calibration's residual."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from quad_wrench_env.vehicle import CALIBRATED_ROTORS, Mixer

FAN_TRACKING = "QuadWrench/FanTracking-v1"


@pytest.mark.parametrize(
    ("settings", "calibration", "spread"),
    [
        ({"vehicle": "crazyflie2"}, CALIBRATED_ROTORS["crazyflie2"], CALIBRATED_ROTORS["crazyflie2"]),
        ({"vehicle": "ardrone2"}, None, 0.02),
        ({"vehicle": "crazyflie2", "rotor_calibration": None}, None, 0.02),
        ({"vehicle": "ardrone2", "rotor_calibration": 0.005}, 0.005, 0.005),
        ({"vehicle": "crazyflie2", "estimator_params": {"rotor_spread": 0.01}}, 0.002, 0.01),
        ({"vehicle": "crazyflie2", "estimator": "ekf"}, 0.002, 0.002),
    ],
)
def test_the_preset_says_whether_its_rotors_are_calibrated(settings, calibration, spread):
    """The calibration the rotors fly (the estimators' mixer differs from the nominal one exactly when
    calibrated) and the spread the filter reports: the residual's, unless given."""
    env = gym.make(FAN_TRACKING, **settings)
    try:
        env.reset(seed=0)
        fleet = env.unwrapped.fleet
        assert env.unwrapped.cfg.resolved_rotor_calibration() == calibration
        assert fleet.estimator.noise.rotor_spread == spread
        nominal = np.array_equal(fleet.rotors.sensed_allocations[0], Mixer(fleet.vehicle).allocation)
        assert nominal == (calibration is None)
    finally:
        env.close()


def test_the_observer_and_the_oracle_fly_a_calibrated_crazyflie2():
    for estimator in ("observer", "oracle"):
        env = gym.make(FAN_TRACKING, vehicle="crazyflie2", estimator=estimator)
        env.reset(seed=0)
        env.step(np.zeros(4, dtype=np.float32))
        env.close()


@pytest.mark.parametrize("value", ["presets", -0.1, 0.5, True])
def test_a_bad_calibration_is_refused_by_name(value):
    with pytest.raises(ValueError, match=f"rotor_calibration={value!r} must be"):
        gym.make(FAN_TRACKING, rotor_calibration=value)
