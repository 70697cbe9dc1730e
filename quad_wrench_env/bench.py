"""Reference timings that benchmark scripts compare against in the same run."""

from __future__ import annotations

import time

import numpy as np
import pybullet as p

from quad_wrench_env.estimators import TruthFed, make_estimator
from quad_wrench_env.rotations import quat_exp, quat_multiply
from quad_wrench_env.vehicle import GRAVITY, make_vehicle


def bare_pybullet_step_seconds(steps: int) -> float:
    """Seconds per PyBullet step of one box body with an applied force and torque and a state read:
    the floor under any simulator of one rigid body built on PyBullet."""
    cid = p.connect(p.DIRECT)
    try:
        p.setGravity(0, 0, -9.81, physicsClientId=cid)
        p.setTimeStep(1 / 200, physicsClientId=cid)
        shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=(0.2, 0.2, 0.05), physicsClientId=cid)
        body = p.createMultiBody(0.42, shape, basePosition=(0, 0, 1), physicsClientId=cid)
        start = time.perf_counter()
        for _ in range(steps):
            position, _ = p.getBasePositionAndOrientation(body, physicsClientId=cid)
            p.getBaseVelocity(body, physicsClientId=cid)
            p.applyExternalForce(body, -1, (0, 0, 4.12), position, p.WORLD_FRAME, physicsClientId=cid)
            p.applyExternalTorque(body, -1, (0, 0, 0), p.WORLD_FRAME, physicsClientId=cid)
            p.stepSimulation(physicsClientId=cid)
        return (time.perf_counter() - start) / steps
    finally:
        p.disconnect(physicsClientId=cid)


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
