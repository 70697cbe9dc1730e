"""The PyBullet world: one client, a ground plane and the rigid body of a vehicle.

Every PyBullet call passes ``physicsClientId``; :meth:`World.close` is guarded and idempotent. All
loads act on the body as one resultant force through the centre of mass and one torque, both in the
world frame: callers sum forces applied at body points (``r × F``) before handing them over, which is
exactly what PyBullet does with a force at a point, in one call instead of one per point.
"""

from __future__ import annotations

import contextlib
import os
import sys
from dataclasses import dataclass

import numpy as np
import pybullet as p

from quad_wrench_env.rotations import from_pybullet, rotation_matrix, to_pybullet
from quad_wrench_env.vehicle import GRAVITY, VehicleParams


@dataclass(frozen=True)
class RigidBodyState:
    """True state of the vehicle's body (world frame, quaternion ``[w, x, y, z]`` body -> world)."""

    position: np.ndarray
    quaternion: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray
    """Angular velocity in the world frame (rad/s)."""
    rotation: np.ndarray
    """Body -> world rotation matrix."""

    @property
    def body_rates(self) -> np.ndarray:
        """Angular velocity in the body frame (rad/s), paper 000's ``omega``."""
        return self.rotation.T @ self.angular_velocity


class World:
    """A PyBullet client holding a ground plane and one vehicle body."""

    def __init__(self, vehicle: VehicleParams, dt: float, gui: bool = False) -> None:
        self.vehicle = vehicle
        self.dt = dt
        self.client: int | None = None
        if gui and sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
            # PyBullet's GUI ends the whole process when it finds no X server: refuse first.
            raise RuntimeError(
                "render_mode='human' opens a PyBullet window and needs a display, but DISPLAY is unset; "
                "use render_mode='rgb_array' or run under a virtual display such as Xvfb"
            )
        self.client = p.connect(p.GUI if gui else p.DIRECT)
        if self.client < 0:
            raise RuntimeError("could not connect to a PyBullet physics server")
        self.body = -1
        self.plane = -1

    def build(self, position: np.ndarray, quaternion: np.ndarray) -> None:
        """Reset the simulation and create the ground and the vehicle at rest at the given pose."""
        cid = self.client
        p.resetSimulation(physicsClientId=cid)
        p.setGravity(0.0, 0.0, -GRAVITY, physicsClientId=cid)
        p.setPhysicsEngineParameter(
            fixedTimeStep=self.dt, numSubSteps=1, deterministicOverlappingPairs=1, physicsClientId=cid
        )
        plane_shape = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid)
        self.plane = p.createMultiBody(0.0, plane_shape, physicsClientId=cid)
        v = self.vehicle
        half_width = v.arm + v.rotor_radius
        hull = p.createCollisionShape(
            p.GEOM_BOX, halfExtents=(half_width, half_width, 0.5 * v.hull_height), physicsClientId=cid
        )
        visual = p.createVisualShape(
            p.GEOM_BOX,
            halfExtents=(half_width, half_width, 0.5 * v.hull_height),
            rgbaColor=(0.2, 0.2, 0.25, 1.0),
            physicsClientId=cid,
        )
        self.body = p.createMultiBody(
            v.mass,
            hull,
            visual,
            basePosition=tuple(position),
            baseOrientation=to_pybullet(quaternion),
            physicsClientId=cid,
        )
        p.changeDynamics(
            self.body,
            -1,
            localInertiaDiagonal=v.inertia,
            linearDamping=0.0,
            angularDamping=0.0,
            physicsClientId=cid,
        )

    def state(self) -> RigidBodyState:
        cid = self.client
        position, orientation = p.getBasePositionAndOrientation(self.body, physicsClientId=cid)
        velocity, angular_velocity = p.getBaseVelocity(self.body, physicsClientId=cid)
        q = from_pybullet(orientation)
        return RigidBodyState(
            np.array(position), q, np.array(velocity), np.array(angular_velocity), rotation_matrix(q)
        )

    def set_velocity(self, velocity: np.ndarray, angular_velocity: np.ndarray) -> None:
        p.resetBaseVelocity(self.body, tuple(velocity), tuple(angular_velocity), physicsClientId=self.client)

    def step(self, force: np.ndarray, torque: np.ndarray, centre_of_mass: np.ndarray) -> None:
        """Apply a world-frame force at the centre of mass (its current world position) and a
        world-frame torque, then advance the simulation one step."""
        cid = self.client
        p.applyExternalForce(
            self.body, -1, tuple(force), tuple(centre_of_mass), p.WORLD_FRAME, physicsClientId=cid
        )
        p.applyExternalTorque(self.body, -1, tuple(torque), p.WORLD_FRAME, physicsClientId=cid)
        p.stepSimulation(physicsClientId=cid)

    def ground_contact(self) -> bool:
        return bool(p.getContactPoints(self.body, self.plane, physicsClientId=self.client))

    def close(self) -> None:
        """Disconnect; safe to call any number of times."""
        if self.client is not None:
            if p.isConnected(physicsClientId=self.client):
                p.disconnect(physicsClientId=self.client)
            self.client = None

    def __del__(self) -> None:
        with contextlib.suppress(Exception):  # at interpreter shutdown pybullet may be gone already
            self.close()
