"""Reference timings that benchmark scripts compare against in the same run."""

from __future__ import annotations

import time

import gymnasium as gym
import numpy as np
import pybullet as p

import quad_wrench_env  # noqa: F401  (registers the env ids)
from quad_wrench_env.estimators import TruthFed, make_estimator
from quad_wrench_env.estimators.ukf import UnscentedFilterBank
from quad_wrench_env.rotations import quat_exp, quat_multiply
from quad_wrench_env.vehicle import GRAVITY, make_vehicle


def bare_pybullet_step_seconds(steps: int, bodies: int = 1) -> float:
    """Seconds per PyBullet step of a world of ``bodies`` box bodies (10 m apart, no ground), each
    with an applied force and torque and a state read: the floor under any simulator built on
    PyBullet. Divide by ``bodies`` for the cost per body."""
    cid = p.connect(p.DIRECT)
    try:
        p.setGravity(0, 0, -9.81, physicsClientId=cid)
        p.setTimeStep(1 / 200, physicsClientId=cid)
        shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=(0.2, 0.2, 0.05), physicsClientId=cid)
        ids = [
            p.createMultiBody(0.42, shape, basePosition=(10.0 * k, 0, 1), physicsClientId=cid)
            for k in range(bodies)
        ]
        start = time.perf_counter()
        for _ in range(steps):
            for body in ids:
                position, _ = p.getBasePositionAndOrientation(body, physicsClientId=cid)
                p.getBaseVelocity(body, physicsClientId=cid)
                p.applyExternalForce(body, -1, (0, 0, 4.12), position, p.WORLD_FRAME, physicsClientId=cid)
                p.applyExternalTorque(body, -1, (0, 0, 0), p.WORLD_FRAME, physicsClientId=cid)
            p.stepSimulation(physicsClientId=cid)
        return (time.perf_counter() - start) / steps
    finally:
        p.disconnect(physicsClientId=cid)


def env_step_seconds(steps: int, resets: int = 20, **env_kwargs) -> tuple[float, float]:
    """Seconds per FanTracking policy step (resets excluded) and per reset (mean of ``resets``
    after the first), with zero actions."""
    env = gym.make("QuadWrench/FanTracking-v0", **env_kwargs)
    try:
        env.reset(seed=0)
        start = time.perf_counter()
        for seed in range(1, resets + 1):
            env.reset(seed=seed)
        reset = (time.perf_counter() - start) / resets
        action = np.zeros(4, dtype=np.float32)
        elapsed = 0.0
        start = time.perf_counter()
        for _ in range(steps):
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                elapsed += time.perf_counter() - start
                env.reset()
                start = time.perf_counter()
        elapsed += time.perf_counter() - start
        return elapsed / steps, reset
    finally:
        env.close()


def component_seconds(calls: int, **env_kwargs) -> dict[str, float]:
    """Seconds per call of each part of one physics step, timed in isolation on a live env."""
    env = gym.make("QuadWrench/FanTracking-v0", **env_kwargs)
    try:
        env.reset(seed=0, options={"offset_y": 0.4})
        base = env.unwrapped
        state = base.world.state()
        action = np.zeros(4)
        force, torque = base._external_loads(state)
        nominal = base.autopilot.mixer.wrench(base.rotors.speeds)
        parts = {
            "physics (PyBullet step + state read)": lambda: (
                base.world.step(force, torque, state.position),
                base.world.state(),
            ),
            "disturbances (wind, drag, point loads)": lambda: base._external_loads(state),
            "autopilot + motors": lambda: base.rotors.step(base.actions.motor_command(action, state)),
            "sensors": lambda: (
                base.mocap.measure(state.position, state.quaternion),
                base.motor_sensor.measure(base.rotors.speeds),
            ),
            f"estimator ({base.cfg.estimator})": lambda: base.estimator.step(
                nominal[0], nominal[1:], state.position, state.quaternion
            ),
            "observation (per policy step)": lambda: base._observation(base.estimator.estimate),
        }
        out = {}
        for name, call in parts.items():
            start = time.perf_counter()
            for _ in range(calls):
                call()
            out[name] = (time.perf_counter() - start) / calls
        return out
    finally:
        env.close()


def filter_bank_step_seconds(count: int, steps: int, seed: int = 0, dt: float = 0.005) -> float:
    """Seconds per step of a bank of ``count`` UKFs (all of them) fed hovering vehicles' noisy poses."""
    vehicle = make_vehicle("ardrone2")
    bank = UnscentedFilterBank(vehicle, dt, None, count)
    rng = np.random.default_rng(seed)
    positions, quaternions = np.tile((0.0, 0.0, 1.0), (count, 1)), np.tile((1.0, 0.0, 0.0, 0.0), (count, 1))
    bank.reset(slice(None), positions, quaternions)
    thrusts, torques = np.full(count, vehicle.mass * GRAVITY), np.zeros((count, 3))
    noisy = positions + 5e-4 * rng.standard_normal((steps, count, 3))
    start = time.perf_counter()
    for k in range(steps):
        bank.step(thrusts, torques, noisy[k], quaternions)
    return (time.perf_counter() - start) / steps


def estimator_step_seconds(name: str, steps: int, seed: int = 0, dt: float = 0.005) -> float:
    """Seconds per ``step`` of estimator ``name`` fed a hovering vehicle's noisy pose (0.5 mm, 2 mrad)."""
    vehicle = make_vehicle("ardrone2")
    est = make_estimator(name, vehicle, dt)
    rng = np.random.default_rng(seed)
    position, q = np.array((0.0, 0.0, 1.0)), np.array((1.0, 0.0, 0.0, 0.0))
    positions = position + 5e-4 * rng.standard_normal((steps, 3))
    quaternions = [quat_multiply(q, quat_exp(2e-3 * rng.standard_normal(3))) for _ in range(steps)]
    est.reset(position, q)
    if isinstance(est, TruthFed):
        est.observe_truth(est.state, np.zeros(3), np.zeros(3))
    thrust, torque = vehicle.mass * GRAVITY, np.zeros(3)
    start = time.perf_counter()
    for k in range(steps):
        est.step(thrust, torque, positions[k], quaternions[k])
    return (time.perf_counter() - start) / steps
