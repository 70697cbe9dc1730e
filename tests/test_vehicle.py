"""Presets and the mixer of McKinnon & Schoellig 2016 eqs. (1), (8)-(10)."""

from __future__ import annotations

import numpy as np
import pytest

from quad_wrench_env.vehicle import GRAVITY, PRESETS, Mixer, make_vehicle


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_presets_can_hover_with_margin(name):
    v = PRESETS[name]
    assert v.max_thrust / (v.mass * GRAVITY) > 1.5
    mixer = Mixer(v)
    hover = np.full(4, v.hover_rotor_speed)
    np.testing.assert_allclose(mixer.wrench(hover), (v.mass * GRAVITY, 0, 0, 0), atol=1e-12)


def test_papers_numbers():
    assert make_vehicle("ardrone2").hover_rotor_speed == pytest.approx(330, rel=0.01)
    yuksel = make_vehicle("yuksel1kg")
    assert (yuksel.mass, yuksel.inertia) == (1.0, (0.13, 0.13, 0.22))
    assert yuksel.max_thrust == pytest.approx(2 * GRAVITY)
    assert make_vehicle("crazyflie2").max_thrust / (0.027 * GRAVITY) == pytest.approx(2.25, rel=0.01)


def test_single_motor_torque_signs_follow_eqs_8_to_10():
    v = make_vehicle("ardrone2")
    mixer = Mixer(v)
    c = v.kf * 300.0**2
    for motor, (sx, sy, sz) in enumerate(((1, -1, 1), (1, 1, -1), (-1, 1, 1), (-1, -1, -1))):
        speeds = np.zeros(4)
        speeds[motor] = 300.0
        thrust, tx, ty, tz = mixer.wrench(speeds)
        assert thrust == pytest.approx(c)
        assert (tx, ty, tz) == pytest.approx((sx * v.arm * c, sy * v.arm * c, sz * v.km_over_kf * c))


def test_mixer_inverse_round_trip_with_per_rotor_coefficients():
    v = make_vehicle("hummingbird")
    mixer = Mixer(v, v.kf * np.array((1.01, 0.98, 1.02, 0.99)))
    speeds = np.array((400.0, 420.0, 380.0, 410.0))
    np.testing.assert_allclose(np.sqrt(mixer.inverse @ mixer.wrench(speeds)), speeds)


def test_bad_vehicle_input_names_the_value():
    with pytest.raises(ValueError, match="'bebop'.*allowed"):
        make_vehicle("bebop")
    with pytest.raises(ValueError, match="mass=-1"):
        make_vehicle("ardrone2", mass=-1.0)
    with pytest.raises(ValueError, match="wingspan"):
        make_vehicle("ardrone2", wingspan=1.0)
    with pytest.raises(ValueError, match="cannot lift"):
        make_vehicle("ardrone2", mass=5.0)
