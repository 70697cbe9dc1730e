"""The PyBullet world: one client, a ground plane, the static scene parts and the rigid bodies of N
vehicles.

Every PyBullet call passes ``physicsClientId``; the calls of every physics step (:meth:`World.step`,
:meth:`World.read`) pass it as their last positional argument, which PyBullet parses faster than the
keyword. :meth:`World.close` is guarded and idempotent. All
loads act on each body as one resultant force through its centre of mass and one torque, both in the
world frame: callers sum forces applied at body points (``r × F``) before handing them over, which is
exactly what PyBullet does with a force at a point, in one call instead of one per point.

The vehicles share the world, its ground and one copy of the scene, all at PyBullet's origin, but
never touch each other (collision groups: a vehicle collides with the ground and the scene parts
only), so each body integrates exactly as it would alone, in the same coordinates, with the same
rounding: vehicle i of a fleet gives the same bits as a fleet of one (``tests/test_determinism.py``).
The contact solver always runs its iterations (``solverResidualThreshold=0``): stopping once a
residual summed over every contact of the world is small made one vehicle's contact forces depend
on the others' contacts.
Frames an arena apart (each vehicle shifted by its own origin) would cost each position the
rounding of the shift's magnitude (1e-14 m at 10 m) and break that; coinciding vehicles cost
Bullet's broadphase the pairs of overlapping bounding boxes it finds and then discards (a small cost
per body and physics step: docs/architecture.md, "Measurements behind the hot paths"). The body is built once
and later episodes put it back in place (``resetBasePositionAndOrientation`` and
``resetBaseVelocity`` fix every degree of freedom of a free body, so nothing of an earlier episode
survives).
"""

from __future__ import annotations

import contextlib
import os
import sys
from dataclasses import dataclass

import numpy as np
import pybullet as p

from quad_wrench_env.rotations import from_pybullet, rotation_matrices, to_pybullet
from quad_wrench_env.scene import ScenePart, touch_of
from quad_wrench_env.vehicle import GRAVITY, VehicleParams

_GROUND_GROUP, _VEHICLE_GROUP = 1, 2

_CONTACT_THRESHOLD = 0.02
"""Bullet's contact breaking threshold (m): the farthest a reported contact point can be apart."""

_MAX_FALL_SPEED = 20.0
"""Vertical speed (m/s) no vehicle reaches in the arenas here (a free fall from 20 m): bounds how far
a body can have moved between PyBullet's collision detection and the pose read after the step."""


@dataclass(frozen=True)
class RigidBodyState:
    """True states of N bodies (world frame, quaternions ``[w, x, y, z]`` body -> world), arrays with
    a leading dimension N."""

    position: np.ndarray
    quaternion: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray
    """Angular velocity in the world frame (rad/s)."""
    rotation: np.ndarray
    """(N, 3, 3) body -> world rotation matrices."""
    body_rates: np.ndarray
    """(N, 3) angular velocity in the body frame (rad/s), McKinnon & Schoellig's (2016) ``omega``."""

    @classmethod
    def from_motion(
        cls, position: np.ndarray, quaternion: np.ndarray, velocity: np.ndarray, angular_velocity: np.ndarray
    ) -> RigidBodyState:
        rotation = rotation_matrices(quaternion)
        body_rates = np.einsum("nji,nj->ni", rotation, angular_velocity)
        return cls(position, quaternion, velocity, angular_velocity, rotation, body_rates)

    @classmethod
    def from_pybullet(cls, raw: np.ndarray) -> RigidBodyState:
        """States from (N, 13) rows ``[position, quaternion (x, y, z, w), velocity, angular velocity]``
        as PyBullet reports them."""
        return cls.from_motion(raw[:, 0:3], from_pybullet(raw[:, 3:7]), raw[:, 7:10], raw[:, 10:13])

    @classmethod
    def at_rest(cls, position: np.ndarray, quaternion: np.ndarray) -> RigidBodyState:
        """Bodies at rest at (N, 3) positions and (N, 4) attitudes."""
        return cls.from_motion(position, quaternion, np.zeros_like(position), np.zeros_like(position))

    def assign(self, other: RigidBodyState, index: np.ndarray | slice = slice(None)) -> None:
        """Copy ``other``'s states into the rows ``index`` of these arrays, in place (a fleet's state
        is views of its buffer)."""
        for name in ("position", "quaternion", "velocity", "angular_velocity", "rotation", "body_rates"):
            getattr(self, name)[index] = getattr(other, name)

    def select(self, index: np.ndarray | slice) -> RigidBodyState:
        """The states of the bodies ``index``."""
        return RigidBodyState(
            self.position[index],
            self.quaternion[index],
            self.velocity[index],
            self.angular_velocity[index],
            self.rotation[index],
            self.body_rates[index],
        )


@dataclass(frozen=True)
class Tool:
    """The tool's tip as the world builds it: ``offset`` (3,) in the body frame, radius, friction (m)."""

    offset: np.ndarray
    radius: float
    friction: float


class World:
    """A PyBullet client holding a ground plane and ``count`` vehicle bodies."""

    def __init__(
        self,
        vehicle: VehicleParams,
        dt: float,
        count: int = 1,
        gui: bool = False,
        scene: list[ScenePart] | None = None,
        tool: Tool | None = None,
    ) -> None:
        if not (isinstance(count, int) and count >= 1):
            raise ValueError(f"count={count!r} must be an integer >= 1 (vehicles in the world)")
        self.vehicle = vehicle
        self.dt = dt
        self.count = count
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
        self.scene = list(scene or [])
        self.tool = tool
        self.bodies: list[int] = []
        self.plane = -1
        self._crash_bodies: list[int] = []
        """The ground and the scene parts whose contact ends an episode, once built."""
        self._reported_bodies: list[list[int]] = []
        """Each ``touch="report"`` part's bodies, in scene order, once built."""
        self._index_of: dict[int, int] = {}
        self.half_extents = (vehicle.arm + vehicle.rotor_radius,) * 2 + (0.5 * vehicle.hull_height,)
        """Half extents (m) of each vehicle's collision box."""
        highest = max([0.0] + [c[2] + h[2] for part in self.scene for c, h in part.boxes()])
        reach = float(np.linalg.norm(self.half_extents))
        if tool is not None:
            reach = max(reach, float(np.linalg.norm(tool.offset)) + tool.radius)
        self.clear_height = highest + reach + _CONTACT_THRESHOLD + _MAX_FALL_SPEED * dt
        """Height (m) of a body's centre above which it cannot touch the ground or a scene part: the
        highest top, the body's bounding radius (tool included), the contact threshold and one step's
        fall. The envs ask for contacts only below it."""

    @property
    def built(self) -> bool:
        return bool(self.bodies)

    def build(self) -> None:
        """Reset the simulation and create the ground, the scene and the vehicles (at rest)."""
        cid = self.client
        p.resetSimulation(physicsClientId=cid)
        p.setGravity(0.0, 0.0, -GRAVITY, physicsClientId=cid)
        p.setPhysicsEngineParameter(
            fixedTimeStep=self.dt,
            numSubSteps=1,
            deterministicOverlappingPairs=1,
            solverResidualThreshold=0.0,
            physicsClientId=cid,
        )
        plane_shape = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid)
        # a static rigid body (maximal coordinates), not a fixed multibody: less work per step
        self.plane = p.createMultiBody(0.0, plane_shape, useMaximalCoordinates=1, physicsClientId=cid)
        p.setCollisionFilterGroupMask(self.plane, -1, _GROUND_GROUP, _VEHICLE_GROUP, physicsClientId=cid)
        self._crash_bodies = [self.plane]
        self._reported_bodies = []
        for part in self.scene:  # one copy, shared by every vehicle
            crash = touch_of(part) == "crash"
            if not crash:
                self._reported_bodies.append([])
            for centre, half in part.boxes():
                shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=cid)
                look = p.createVisualShape(
                    p.GEOM_BOX, halfExtents=half, rgbaColor=(0.55, 0.45, 0.35, 1.0), physicsClientId=cid
                )
                body = p.createMultiBody(
                    0.0, shape, look, basePosition=list(centre), useMaximalCoordinates=1, physicsClientId=cid
                )
                p.setCollisionFilterGroupMask(body, -1, _GROUND_GROUP, _VEHICLE_GROUP, physicsClientId=cid)
                p.changeDynamics(body, -1, lateralFriction=part.friction, physicsClientId=cid)
                (self._crash_bodies if crash else self._reported_bodies[-1]).append(body)
        v, half_extents, tool = self.vehicle, self.half_extents, self.tool
        colour = (0.2, 0.2, 0.25, 1.0)
        if tool is None:
            hull = p.createCollisionShape(p.GEOM_BOX, halfExtents=half_extents, physicsClientId=cid)
            visual = p.createVisualShape(
                p.GEOM_BOX, halfExtents=half_extents, rgbaColor=colour, physicsClientId=cid
            )
        else:  # one rigid body: the hull's box and the tip's sphere (a compound shape)
            frames = [[0.0, 0.0, 0.0], list(tool.offset)]
            hull = p.createCollisionShapeArray(
                [p.GEOM_BOX, p.GEOM_SPHERE],
                halfExtents=[half_extents, [0.0] * 3],
                radii=[0.0, tool.radius],
                collisionFramePositions=frames,
                physicsClientId=cid,
            )
            visual = p.createVisualShapeArray(
                [p.GEOM_BOX, p.GEOM_SPHERE],
                halfExtents=[half_extents, [0.0] * 3],
                radii=[0.0, tool.radius],
                visualFramePositions=frames,
                rgbaColors=[colour, (0.9, 0.5, 0.1, 1.0)],
                physicsClientId=cid,
            )
        self.bodies = []
        for _ in range(self.count):
            body = p.createMultiBody(v.mass, hull, visual, basePosition=(0.0, 0.0, 1.0), physicsClientId=cid)
            p.changeDynamics(
                body,
                -1,
                localInertiaDiagonal=v.inertia,
                linearDamping=0.0,
                angularDamping=0.0,
                physicsClientId=cid,
            )
            if tool is not None:
                p.changeDynamics(body, -1, lateralFriction=tool.friction, physicsClientId=cid)
            p.setCollisionFilterGroupMask(body, -1, _VEHICLE_GROUP, _GROUND_GROUP, physicsClientId=cid)
            self.bodies.append(body)
        self._index_of = {body: i for i, body in enumerate(self.bodies)}

    def place(self, index: np.ndarray, positions: np.ndarray, quaternions: np.ndarray) -> None:
        """Put the vehicles ``index`` at rest at (n, 3) positions and (n, 4) attitudes ``[w, x, y, z]``;
        builds the world on first use."""
        if not self.built:
            self.build()
        cid = self.client
        index = np.asarray(index)
        xyzw = to_pybullet(quaternions).tolist()
        for i, position, orientation in zip(index.tolist(), positions.tolist(), xyzw, strict=True):
            body = self.bodies[i]
            p.resetBasePositionAndOrientation(body, position, orientation, physicsClientId=cid)
            p.resetBaseVelocity(body, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), physicsClientId=cid)

    def read(self) -> np.ndarray:
        """(N, 13) rows ``[position, quaternion (x, y, z, w), velocity, angular velocity]`` of the
        vehicles as PyBullet reports them."""
        return self.read_flat().reshape(self.count, 13)

    def read_first(self) -> tuple[tuple, tuple]:
        """Vehicle 0's ``((position, quaternion (x, y, z, w)), (velocity, angular velocity))`` as
        PyBullet returns them. A world of one
        vehicle hands them to the compiled step as they are, instead of :meth:`read_flat`'s row, so
        that Python builds no array."""
        body, cid = self.bodies[0], self.client
        return p.getBasePositionAndOrientation(body, cid), p.getBaseVelocity(body, cid)

    def read_flat(self) -> np.ndarray:
        """The rows of :meth:`read` one after another, (13 N,): what the compiled step takes."""
        cid = self.client
        pose, twist = p.getBasePositionAndOrientation, p.getBaseVelocity
        flat: list[float] = []
        for body in self.bodies:  # the client id positionally (see the module docstring)
            position, orientation = pose(body, cid)
            linear, angular = twist(body, cid)
            flat += position + orientation + linear + angular
        return np.fromiter(flat, float, 13 * self.count)

    def state(self) -> RigidBodyState:
        """The true states of all vehicles."""
        return RigidBodyState.from_pybullet(self.read())

    def step(self, forces: np.ndarray, torques: np.ndarray, centres_of_mass: np.ndarray) -> None:
        """Apply (N, 3) world-frame forces at the centres of mass (their current positions) and (N, 3)
        world-frame torques, then advance the simulation one step."""
        cid = self.client
        world_frame = p.WORLD_FRAME
        apply_force, apply_torque = p.applyExternalForce, p.applyExternalTorque
        for body, force, torque, com in zip(
            self.bodies, forces.tolist(), torques.tolist(), centres_of_mass.tolist(), strict=True
        ):
            apply_force(body, -1, force, com, world_frame, cid)  # client id positionally (module doc)
            apply_torque(body, -1, torque, world_frame, cid)
        p.stepSimulation(cid)

    def step_one(self, force: tuple, torque: tuple, centre_of_mass: tuple) -> None:
        """:meth:`step` for a world of one vehicle, with its loads as the sequences PyBullet takes:
        what the compiled step of a single env calls, with no arrays to build."""
        if self.count != 1:
            raise ValueError(f"step_one steps a world of one vehicle; this world has {self.count}")
        cid = self.client
        body = self.bodies[0]
        p.applyExternalForce(body, -1, force, centre_of_mass, p.WORLD_FRAME, cid)
        p.applyExternalTorque(body, -1, torque, p.WORLD_FRAME, cid)
        p.stepSimulation(cid)

    def crash_contacts(self) -> np.ndarray:
        """(N,) bool: which vehicles touch the ground or a scene part with anything but the tool's tip."""
        touching = np.zeros(self.count, dtype=bool)
        tips = self._tips() if self.tool is not None else None
        for body in self._crash_bodies:
            for contact in p.getContactPoints(bodyA=body, physicsClientId=self.client):
                index = self._index_of.get(contact[2])
                if index is not None and not (tips is not None and self._at_tip(contact[6], tips[index])):
                    touching[index] = True
        return touching

    @property
    def reported_parts(self) -> int:
        """How many scene parts report their touches (``touch="report"``), once built."""
        return len(self._reported_bodies)

    def touches(self) -> np.ndarray:
        """(N, K) bool: which vehicle touches (with anything) which of the K ``touch="report"`` parts."""
        touching = np.zeros((self.count, len(self._reported_bodies)), dtype=bool)
        for k, bodies in enumerate(self._reported_bodies):
            for body in bodies:
                for contact in p.getContactPoints(bodyA=body, physicsClientId=self.client):
                    index = self._index_of.get(contact[2])
                    if index is not None:
                        touching[index, k] = True
        return touching

    def _tips(self) -> np.ndarray:
        """(N, 3) world positions of the tool tips' centres."""
        cid = self.client
        tips = np.empty((self.count, 3))
        for i, body in enumerate(self.bodies):
            position, orientation = p.getBasePositionAndOrientation(body, cid)
            rotation = np.reshape(p.getMatrixFromQuaternion(orientation, physicsClientId=cid), (3, 3))
            tips[i] = np.asarray(position) + rotation @ self.tool.offset
        return tips

    def _at_tip(self, point: tuple, tip: np.ndarray) -> bool:
        """Whether a contact point on a vehicle lies on its tool's tip (within 5 mm of the sphere)."""
        return float(np.linalg.norm(np.asarray(point) - tip)) < self.tool.radius + 0.005

    def add_contact_loads(
        self, wrench: np.ndarray, tip_force: np.ndarray, position: np.ndarray, rotation: np.ndarray
    ) -> None:
        """Add to (N, 6) ``wrench`` the force and torque about the centre of mass (world frame) that
        PyBullet's contact solver applied to each vehicle in the last step, and write into (N, 3)
        ``tip_force`` the part of the force on the tool's tip; ``position`` (N, 3) and ``rotation``
        (N, 3, 3) are the vehicles' states after that step (read from the world already). Per contact
        point: the normal force along the normal on the other body (pointing at the vehicle) plus both
        lateral friction forces along their directions, as Bullet reports them for the vehicle (body
        A): a tip held still against a sideways push of 0.3 N reads friction -0.3 N along the push
        (tests/test_contacts.py)."""
        cid = self.client
        tip_force[:] = 0.0
        tips = position + rotation @ self.tool.offset if self.tool is not None else None
        for i, body in enumerate(self.bodies):
            for c in p.getContactPoints(bodyA=body, physicsClientId=cid):
                force = c[9] * np.asarray(c[7]) + c[10] * np.asarray(c[11]) + c[12] * np.asarray(c[13])
                wrench[i, :3] += force
                wrench[i, 3:] += np.cross(np.asarray(c[5]) - position[i], force)
                if tips is not None and self._at_tip(c[5], tips[i]):
                    tip_force[i] += force

    def close(self) -> None:
        """Disconnect; safe to call any number of times."""
        if self.client is not None:
            if p.isConnected(physicsClientId=self.client):
                p.disconnect(physicsClientId=self.client)
            self.client = None

    def __del__(self) -> None:
        with contextlib.suppress(Exception):  # at interpreter shutdown pybullet may be gone already
            self.close()
