"""Drawing an env: the vehicle, its tool, the fan and jets, force arrows and the key numbers.

Everything drawn in 3D is a visual-only PyBullet body (no collision shape, no mass), created on the
first ``render()`` and never when no render mode is asked for, so training never pays for it:

- the vehicle as an X (its arm length from the preset): hull, two arms, four rotor discs (the front
  pair red), a red nose on the heading, and the tool (rod and tip) where the env has one; placed at
  the vehicle's pose each frame. The world's own box for the vehicle is hidden;
- each fan and fixed jet: its outlet on a stand and its axis; the jet itself as a translucent volume
  (its Gaussian speed profile, widening as ``b(x)``; painted by
  :func:`~quad_wrench_env.envs.overlay.paint_scene`); a moving fan's axis bends towards the retarded
  axis at the vehicle.

The camera follows the vehicle at ``3 × span`` (its size, rotor tip to rotor tip: 0.38 m for
crazyflie2, 3 m for yuksel1kg), from a side chosen at each episode's first frame, and aims between
the vehicle and the context (a fan, a jet's outlet, the nearest wall or ceiling) so that both are in
view: along a fan's jet towards the fan, across a fixed jet, along a wall, or under a ceiling.
``rgb_array`` frames (:data:`FRAME_SIZE`) add, with numpy and Pillow
(:mod:`~quad_wrench_env.envs.overlay`: TinyRenderer draws no lines, text or transparency), the ground
with the vehicle's shadow, arrows for the true and the estimated external force at the centre of mass
and, with a tool, the force the tip exerts and the target force at the tip (all ``force_scale`` m per
N, stated on the frame), an arrow of the air's velocity at the vehicle (upwind of it, pointing at
it; ``wind_scale`` m per m/s) where the env has winds, the time and the key numbers, and a legend.
``human`` (the GUI) shows the bodies and follows the vehicle.

What a task adds to its frames (:meth:`SceneRenderer.marks`): its ``render_marks(vehicle)``
(the ``Task`` protocol; ``TaskDefaults`` adds nothing) with any of ``label`` (a line for the panel,
e.g. the scenario flown), ``reference`` ((3,) where the vehicle should be now) and ``path`` ((K, 3) the
reference path over the episode), and ``info["reference_position"]`` as the reference where ``info``
has one. The reference shows as a ring on the path (or, out of view, a
pointer at the frame's edge with its distance).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
import pybullet as p

from quad_wrench_env.disturbances.base import Outlet, Visible
from quad_wrench_env.envs.overlay import (
    JET_COLOUR,
    Arrow,
    Camera,
    JetShape,
    draw_arrows,
    draw_panel,
    draw_reference,
    paint_scene,
)
from quad_wrench_env.rotations import to_pybullet
from quad_wrench_env.vehicle import GRAVITY

if TYPE_CHECKING:
    from quad_wrench_env.envs.base import QuadWrenchEnv

FRAME_SIZE = (640, 480)
"""Width and height (pixels) of ``rgb_array`` frames."""
JET_LENGTH = 3.0
"""How far (m) from its outlet a jet is drawn."""
SPREAD = 28.0
"""Largest angle (degrees) between the vehicle and the context (a fan, a surface) seen from the camera."""
TRUE, ESTIMATE, EXERTED, TARGET = (40, 170, 70), (250, 140, 20), (215, 50, 215), (150, 150, 150)
"""Arrow colours: true and estimated external force, tip force on the surface, target force."""
REFERENCE, WIND = (150, 70, 230), (0, 195, 210)
"""Colours of the reference (path and point) and of the air's velocity arrow."""
WIND_SHOWN = 0.5
"""Slowest air (m/s) drawn as an arrow."""
SURFACE = (0.8, 0.76, 0.7, 1.0)
"""The colour of the scene's tables, walls and ceilings."""
_HIDDEN = (0.0, 0.0, 0.0, 0.0)
_AXIS = (0.2, 0.45, 0.85, 1.0)
_NUMBERS = (
    ("axis_error", "axis error {:+.2f} m"),
    ("standoff_error", "stand-off error {:+.2f} m"),
    ("tracking_error", "tracking error {:.2f} m"),
)
"""Task numbers shown when ``info`` has them."""


def _towards(direction: np.ndarray) -> tuple[float, ...]:
    """Quaternion (x, y, z, w) turning +z onto ``direction``."""
    z = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    axis = np.cross((0.0, 0.0, 1.0), z)
    sine = float(np.linalg.norm(axis))
    if sine < 1e-9:
        return (0.0, 0.0, 0.0, 1.0) if z[2] > 0 else (1.0, 0.0, 0.0, 0.0)
    half = 0.5 * math.atan2(sine, z[2])
    return (*(axis / sine * math.sin(half)), math.cos(half))


def _body(cid: int, shapes: list[tuple]) -> int:
    """A visual-only body of ``(geometry, size, position, orientation, rgba)`` shapes; ``size`` is half
    extents for a box, ``(radius, length)`` for a cylinder, ``(radius,)`` for a sphere."""
    kinds, sizes, positions, orientations, colours = zip(*shapes, strict=True)
    visual = p.createVisualShapeArray(
        list(kinds),
        halfExtents=[list(s) if k == p.GEOM_BOX else [0.0] * 3 for k, s in zip(kinds, sizes, strict=True)],
        radii=[s[0] if k != p.GEOM_BOX else 0.0 for k, s in zip(kinds, sizes, strict=True)],
        lengths=[s[1] if k == p.GEOM_CYLINDER else 0.0 for k, s in zip(kinds, sizes, strict=True)],
        visualFramePositions=[list(v) for v in positions],
        visualFrameOrientations=[list(q) for q in orientations],
        rgbaColors=list(colours),
        physicsClientId=cid,
    )
    return p.createMultiBody(0.0, -1, visual, physicsClientId=cid)


def _vehicle_shapes(env: QuadWrenchEnv) -> list[tuple]:
    """The vehicle's look in its body frame (x forward, z up)."""
    v, tool = env.vehicle, env.world.tool
    hub, h, r = math.sqrt(2.0) * v.arm, v.hull_height, v.rotor_radius
    level = (0.0, 0.0, 0.0, 1.0)
    box, cylinder, sphere = p.GEOM_BOX, p.GEOM_CYLINDER, p.GEOM_SPHERE
    shapes = [(box, (0.35 * hub, 0.25 * hub, 0.5 * h), (0, 0, 0), level, (0.18, 0.19, 0.22, 1))]
    for yaw in (0.25 * math.pi, -0.25 * math.pi):
        turn = p.getQuaternionFromEuler((0.0, 0.0, yaw))
        shapes.append((box, (hub, 0.07 * hub, 0.2 * h), (0, 0, 0), turn, (0.28, 0.29, 0.33, 1)))
    for x, y in v.rotor_positions[:, :2]:
        colour = (0.92, 0.35, 0.3, 1) if x > 0 else (0.75, 0.78, 0.84, 1)
        shapes.append((cylinder, (r, 0.1 * h), (x, y, 0.45 * h), level, colour))
        shapes.append((cylinder, (0.15 * r, 0.5 * h), (x, y, 0.25 * h), level, (0.1, 0.1, 0.1, 1)))
    shapes.append((sphere, (0.14 * hub,), (0.38 * hub, 0, 0.3 * h), level, (0.85, 0.05, 0.05, 1)))
    if tool is not None:
        offset = np.asarray(tool.offset, dtype=float)
        rod = (max(0.3 * tool.radius, 0.004), float(np.linalg.norm(offset)))
        shapes.append((cylinder, rod, 0.5 * offset, _towards(offset), (0.45, 0.45, 0.5, 1)))
        tip = max(tool.radius, 0.02 * (hub + r))  # a tip smaller than that would not show
        shapes.append((sphere, (tip,), offset, level, (1.0, 0.6, 0.1, 1)))
    return shapes


def _outlet_shapes(radius: float, direction: np.ndarray, height: float) -> list[tuple]:
    """A fan's look in a frame whose z is ``direction``: rim, blade disc, hub and a stand down
    ``height`` to the ground (vertical in the world)."""
    cylinder, level = p.GEOM_CYLINDER, (0.0, 0.0, 0.0, 1.0)
    down = np.linalg.inv(np.reshape(p.getMatrixFromQuaternion(_towards(direction)), (3, 3))) @ (0, 0, -1)
    return [
        (cylinder, (1.08 * radius, 0.15 * radius), (0, 0, -0.08 * radius), level, (0.25, 0.27, 0.3, 1)),
        (cylinder, (radius, 0.02 * radius), (0, 0, 0.0), level, (0.6, 0.7, 0.85, 1)),
        (cylinder, (0.2 * radius, 0.12 * radius), (0, 0, 0.05 * radius), level, (0.15, 0.15, 0.18, 1)),
        (cylinder, (0.05 * radius, height), 0.5 * height * down, _towards(down), (0.35, 0.35, 0.38, 1)),
    ]


def nice_scale(value: float) -> float:
    """``value`` rounded (in log) to the nearest 1, 2 or 5 times a power of ten."""
    power = 10.0 ** math.floor(math.log10(value))
    return min((1.0, 2.0, 5.0, 10.0), key=lambda m: abs(math.log(value / (m * power)))) * power


def newtons(force: float) -> str:
    """A force for the panel: in mN below 0.1 N."""
    return f"{1e3 * force:.0f} mN" if force < 0.1 else f"{force:.2f} N"


class SceneRenderer:
    """Camera images (``rgb_array``) or a followed view in the GUI (``human``) of one env."""

    def __init__(self, env: QuadWrenchEnv, width: int = FRAME_SIZE[0], height: int = FRAME_SIZE[1]) -> None:
        self.env = env
        self.width = width
        self.height = height
        v = env.vehicle
        self.span = 2.0 * (math.sqrt(2.0) * v.arm + v.rotor_radius)
        """The vehicle's size (m), rotor tip to rotor tip across the X."""
        self.force_scale = nice_scale(4.0 * self.span / (v.mass * GRAVITY))
        """Arrow length (m) per newton: a force of a quarter of the weight is about one span long."""
        self.wind_scale = nice_scale(self.span / 10.0)
        """Air arrow length (m) per m/s: 10 m/s is about one span long."""
        self.distance = max(3.0 * self.span, 0.35)
        """The camera's distance from the vehicle (m)."""
        winds = env.fleet.components.winds
        self.windy = bool(winds)
        """Whether the env has winds (whose air at the vehicle is drawn)."""
        self.sources = [w for w in winds if isinstance(w, Visible)]
        """The wind fields with an outlet to draw (the ``Visible`` seam), moving ones first after a build."""
        self._outward: list[np.ndarray] = []
        """Each drawn outlet's facing direction (a moving fan's along +x, whatever its axis does)."""
        self._moving = 0
        """How many of the drawn outlets move (they come first)."""
        self._vehicle = -1
        self._drawn: list[tuple[int, int, list[tuple]]] = []
        """Each jet's outlet body, axis body and the outlet's shape colours."""
        self._direction: np.ndarray | None = None
        self.camera: Camera | None = None
        """The camera of the last frame."""
        boxes = [box for part in env.fleet.components.scene for box in part.boxes()]
        self._boxes = np.array([(np.subtract(c, h), np.add(c, h)) for c, h in boxes]).reshape(-1, 2, 3)
        """(K, 2, 3) lowest and highest corners of the scene's boxes."""

    # -- bodies ------------------------------------------------------------------------------------
    def build(self) -> None:
        """Create the bodies (once: the world is built once per env) and choose the camera's side again
        at the next frame (a new episode)."""
        self._direction = None
        if self._vehicle >= 0:
            self._show_jets()
            return
        cid = self.env.world.client
        self._recolour_world()
        self._vehicle = _body(cid, _vehicle_shapes(self.env))
        drawn = [(source, self._outlet_of(source)) for source in self.sources]
        drawn = sorted(((s, o) for s, o in drawn if o is not None), key=lambda pair: not pair[1].moving)
        self.sources = [source for source, _ in drawn]
        self._outward = [outlet.facing for _, outlet in drawn]
        self._moving = sum(outlet.moving for _, outlet in drawn)
        for jet, outward in zip(self._jet_shapes(), self._outward, strict=True):
            outlet = _outlet_shapes(jet.radius, outward, float(jet.origin[2]))
            rod = (0.012 * jet.radius, JET_LENGTH)
            axis = _body(cid, [(p.GEOM_CYLINDER, rod, (0, 0, 0.5 * JET_LENGTH), (0, 0, 0, 1), _AXIS)])
            self._drawn.append((_body(cid, outlet), axis, [shape[4] for shape in outlet]))
            self._place(len(self._drawn) - 1, jet)
        self._show_jets()

    def _recolour_world(self) -> None:
        """Hide the world's box for each vehicle (drawn as an X instead) and, for ``rgb_array``, its
        ground plane (painted instead); the scene's parts in :data:`SURFACE`."""
        world = self.env.world
        for index in range(p.getNumBodies(physicsClientId=world.client)):
            body = p.getBodyUniqueId(index, physicsClientId=world.client)
            if body == world.plane and self.env.render_mode != "rgb_array":
                continue
            look = _HIDDEN if body in world.bodies or body == world.plane else SURFACE
            p.changeVisualShape(body, -1, rgbaColor=look, physicsClientId=world.client)

    def _outlet_of(self, source: Visible) -> Outlet | None:
        env = self.env
        return source.outlet(0, float(env.fleet.time[0]), env.world.state().position[0])

    def _outlets_now(self) -> list[Outlet]:
        """The drawn sources' outlets now, moving ones first."""
        return [self._outlet_of(source) for source in self.sources]

    def _jet_shapes(self) -> list[JetShape]:
        """Each drawn outlet's jet envelope now (a moving fan's axis aimed at its retarded axis at the
        vehicle's distance)."""
        return [JetShape(o.origin, o.axis, o.radius, o.spread, JET_LENGTH) for o in self._outlets_now()]

    def _active(self) -> list[bool]:
        """Which jets blow for the vehicle, in drawing order."""
        return [o.active for o in self._outlets_now()]

    def _show_jets(self) -> None:
        """Show the jets that blow in this episode, hide the others."""
        cid = self.env.world.client
        for (outlet, axis, colours), active in zip(self._drawn, self._active(), strict=True):
            shapes = [(outlet, k, colour) for k, colour in enumerate(colours)] + [(axis, 0, _AXIS)]
            for body, k, colour in shapes:
                look = colour if active else _HIDDEN
                p.changeVisualShape(body, -1, shapeIndex=k, rgbaColor=look, physicsClientId=cid)

    def _place(self, index: int, jet: JetShape) -> None:
        outlet, axis, _ = self._drawn[index]
        cid, origin = self.env.world.client, jet.origin.tolist()
        p.resetBasePositionAndOrientation(axis, origin, _towards(jet.axis), physicsClientId=cid)
        p.resetBasePositionAndOrientation(outlet, origin, _towards(self._outward[index]), physicsClientId=cid)

    # -- camera ------------------------------------------------------------------------------------
    def _context(self, position: np.ndarray, jets: list[JetShape]) -> tuple[np.ndarray | None, tuple]:
        """What the camera keeps in view besides the vehicle (a fan's or an active jet's outlet, else the
        nearest surface within reach, else nothing), and how to look at it: the horizontal direction to
        the camera's side, the turn from it and the elevation (degrees)."""
        active = [jet for jet, on in zip(jets, self._active(), strict=True) if on]
        if self._moving:
            return jets[0].origin, (self._outward[0][:2], 40.0, 30.0)
        if active and np.hypot(*active[0].axis[:2]) > 1e-3:
            return active[0].origin, (active[0].axis[:2] / np.hypot(*active[0].axis[:2]), 60.0, 25.0)
        default = (np.array((0.0, -1.0)), 20.0, 20.0)
        if not len(self._boxes):
            return None, default
        nearest = np.clip(position, self._boxes[:, 0], self._boxes[:, 1])
        gaps = np.linalg.norm(nearest - position, axis=1)
        k = int(np.argmin(gaps))
        if gaps[k] > max(self.span, 0.5):  # too far to matter
            return None, default
        side = (position - nearest[k])[:2]
        if np.hypot(*side) > 1e-3:  # a wall: from the side, along its face
            return nearest[k], (side / np.hypot(*side), 80.0, 25.0)
        return nearest[k], (default[0], 20.0, -8.0 if nearest[k, 2] > position[2] else 30.0)

    def _direction_of(self, away: np.ndarray, turn: float, elevation: float, reach: float) -> np.ndarray:
        """Unit vector from the vehicle to the eye: ``away`` turned by ``turn`` and raised by
        ``elevation``, both scaled down where the context is far (``reach``, m) compared with the camera's
        distance, so that the vehicle and the context stay within :data:`SPREAD` of each other in view
        (law of sines: the angle off ``away`` that gives that is ``SPREAD + asin(sin SPREAD · d/reach)``)."""
        nominal = math.acos(math.cos(math.radians(turn)) * math.cos(math.radians(elevation)))
        spread = math.radians(SPREAD)
        needed = spread + math.asin(min(1.0, math.sin(spread) * self.distance / max(reach, 1e-6)))
        angle, rise = (math.radians(a) * min(1.0, needed / nominal) for a in (turn, elevation))
        cos, sin = math.cos(angle), math.sin(angle)
        horizontal = np.array((away[0] * cos - away[1] * sin, away[0] * sin + away[1] * cos))
        return np.array((*(math.cos(rise) * horizontal), math.sin(rise)))

    def _camera(self, position: np.ndarray, jets: list[JetShape]) -> Camera:
        """The camera of this frame: on the side chosen at the episode's first frame, aimed between the
        vehicle and the context so that both are in view."""
        context, look = self._context(position, jets)
        if self._direction is None:
            reach = math.inf if context is None else float(np.linalg.norm(context - position))
            self._direction = self._direction_of(*look, reach)
        eye = self._eye(position)
        target = position
        if context is not None:
            towards = [(point - eye) / np.linalg.norm(point - eye) for point in (position, context)]
            target = eye + towards[0] + towards[1]
        return Camera(eye, target, self.width, self.height)

    def _eye(self, position: np.ndarray) -> np.ndarray:
        """The camera's position: ``distance`` from the vehicle, below any box over the vehicle, above
        the ground."""
        eye = position + self.distance * self._direction
        low, high = self._boxes[:, 0], self._boxes[:, 1]
        over = np.all((low[:, :2] <= eye[:2]) & (eye[:2] <= high[:, :2]), axis=1) & (low[:, 2] > position[2])
        if np.any(over):
            eye[2] = min(eye[2], float(low[over, 2].min()) - 0.05)
        eye[2] = max(eye[2], 0.05)
        return eye

    # -- a frame -----------------------------------------------------------------------------------
    def render(self) -> np.ndarray | None:
        env = self.env
        if not env.world.built:
            raise RuntimeError("call reset() before render(): the world is built at the first reset")
        if self._vehicle < 0:
            self.build()
        cid = env.world.client
        state = env.world.state()
        position = state.position[0]
        p.resetBasePositionAndOrientation(
            self._vehicle,
            position.tolist(),
            to_pybullet(state.quaternion[:1])[0].tolist(),
            physicsClientId=cid,
        )
        jets = self._jet_shapes()
        for index in range(self._moving):
            self._place(index, jets[index])
        camera = self.camera = self._camera(position, jets)
        if env.render_mode == "human":
            offset = camera.eye - camera.target
            distance = float(np.linalg.norm(offset))
            dx, dy, dz = offset / distance
            yaw, pitch = math.degrees(math.atan2(dx, -dy)), -math.degrees(math.asin(dz))
            p.resetDebugVisualizerCamera(distance, yaw, pitch, camera.target.tolist(), physicsClientId=cid)
            return None
        return self._frame(camera, jets, position)

    def _frame(self, camera: Camera, jets: list[JetShape], position: np.ndarray) -> np.ndarray:
        """The camera's image with the ground, the jets, the arrows and the panels painted on."""
        env, (w, h) = self.env, (self.width, self.height)
        _, _, rgba, buffer, segments = p.getCameraImage(
            w,
            h,
            camera.view_matrix(),
            camera.projection_matrix(),
            renderer=p.ER_TINY_RENDERER,
            physicsClientId=env.world.client,
        )
        rgb = np.asarray(rgba, dtype=np.uint8).reshape(h, w, 4)[:, :, :3]
        depth = np.asarray(buffer, dtype=np.float32).reshape(h, w)
        segments = np.asarray(segments).reshape(h, w)
        active = [jet for jet, on in zip(jets, self._active(), strict=True) if on]
        shadow = (position[:2], 0.5 * self.span)
        image = paint_scene(rgb, depth, segments, camera, shadow, active, self._vehicle)
        info = env.simulation.info(vehicle=0)
        marks = self.marks(info)
        if marks.get("reference") is not None:
            draw_reference(
                image,
                camera,
                marks["reference"],
                marks.get("path"),
                position,
                REFERENCE,
                segments == self._vehicle,
            )
        draw_arrows(image, camera, [*self.wind_arrows(info), *self.arrows(info)])
        draw_panel(image, self._numbers(info, marks), [])
        scales = f"arrows {self.force_scale:g} m per N" + (
            f", {self.wind_scale:g} m per m/s" if self.windy else ""
        )
        draw_panel(image, [f"{scales}; red rotors: front"], self._legend(info, marks), top=False)
        return np.asarray(image)

    def marks(self, info: dict[str, Any]) -> dict[str, Any]:
        """What the task adds to this frame (module docstring): ``label``, ``reference``, ``path``."""
        marks = dict(self.env.task.render_marks(0))
        if marks.get("reference") is None and "reference_position" in info:
            marks["reference"] = np.asarray(info["reference_position"], dtype=float)
        return marks

    def wind_arrows(self, info: dict[str, Any]) -> list[Arrow]:
        """The air's velocity at the vehicle (none below :data:`WIND_SHOWN`), drawn upwind of the
        vehicle and pointing at it, clear of its rotors."""
        wind = np.asarray(info["wind_velocity"], dtype=float)
        speed = float(np.linalg.norm(wind))
        if not self.windy or speed < WIND_SHOWN:
            return []
        end = np.asarray(info["position"], dtype=float) - 0.6 * self.span * wind / speed
        return [Arrow(end - self.wind_scale * wind, self.wind_scale * wind, WIND, 0.8)]

    def arrows(self, info: dict[str, Any]) -> list[Arrow]:
        """This frame's force arrows (none for a force below 1 µN): the true and the estimated external
        force at the centre of mass; with a tool, the target force and the force the tip exerts on the
        surface, at the tip."""
        position = np.asarray(info["position"])
        items = [
            (position, info["wrench_true"][:3], TRUE, 1.4),
            (position, info["wrench_est"][:3], ESTIMATE, 0.6),
        ]
        tool = self.env.world.tool
        if tool is not None:
            tip = position + self.env.fleet.state.rotation[0] @ tool.offset
            if "target_force" in info:
                items.append((tip, info["target_force"], TARGET, 1.0))
            items.append((tip, -self.env.fleet.contact_force[0], EXERTED, 0.6))
        return [
            Arrow(origin, self.force_scale * np.asarray(force, dtype=float), colour, width)
            for origin, force, colour, width in items
            if np.linalg.norm(force) > 1e-6
        ]

    def _numbers(self, info: dict[str, Any], marks: dict[str, Any]) -> list[str]:
        """The top panel: env, vehicle, time, the task's label, the forces and the task's numbers."""
        env = self.env
        true, estimate = (float(np.linalg.norm(info[k][:3])) for k in ("wrench_true", "wrench_est"))
        lines = [
            f"{env.task.env_id.split('/')[-1]}  {env.cfg.vehicle}  t = {info['time']:.2f} s",
            *([marks["label"]] if marks.get("label") else []),
            f"|f| true {newtons(true)}, estimated {newtons(estimate)} ({env.cfg.estimator})",
            f"air at the vehicle {np.linalg.norm(info['wind_velocity']):.1f} m/s",
        ]
        lines += [text.format(info[key]) for key, text in _NUMBERS if key in info]
        if self.env.world.tool is not None:
            line = f"tip force {newtons(float(np.linalg.norm(self.env.fleet.contact_force[0])))}"
            if "target_force" in info:
                line += f", target {newtons(float(np.linalg.norm(info['target_force'])))}"
            lines.append(line)
        return lines

    def _legend(self, info: dict[str, Any], marks: dict[str, Any]) -> list[tuple[str, tuple[int, int, int]]]:
        legend = [("true external force", TRUE), ("estimated external force", ESTIMATE)]
        if self.windy:
            legend.append(("air at the vehicle (upwind)", WIND))
        if marks.get("reference") is not None:
            legend.append(("reference: now, path", REFERENCE))
        if self.env.world.tool is not None:
            legend.append(("tip force on the surface", EXERTED))
            if "target_force" in info:
                legend.append(("target force", TARGET))
        if any(self._active()):
            legend.append(("jet (shade: air speed)", JET_COLOUR))
        return legend
