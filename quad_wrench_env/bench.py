"""Reference timings that benchmark scripts compare against in the same run."""

from __future__ import annotations

import time

import pybullet as p


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
