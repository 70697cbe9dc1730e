"""Reference timings that benchmark scripts compare against in the same run."""

from __future__ import annotations

import time
from typing import Any

import gymnasium as gym
import numpy as np
import pybullet as p

import quad_wrench_env  # noqa: F401  (registers the env ids)
from quad_wrench_env.config import build
from quad_wrench_env.control.residual import BASES
from quad_wrench_env.envs.simulation import observations
from quad_wrench_env.estimators import EstimatorInputs, TruthFed, make_estimator, make_estimator_bank
from quad_wrench_env.estimators.ukf_kernel import ukf_bank_step
from quad_wrench_env.rotations import quat_exp, quat_multiply
from quad_wrench_env.vehicle import GRAVITY, make_vehicle

FLOORS = ("four rotor forces", "resultant force and torque")
"""What a bare step applies to each body: the issue's limit (a force at each of the four rotor hubs)
or what the envs apply (one resultant force at the centre of mass and one torque)."""


def bare_pybullet_step_seconds(steps: int, bodies: int = 1, floor: str = FLOORS[0]) -> float:
    """Seconds per PyBullet step of a world of ``bodies`` box bodies (10 m apart, no ground), each
    with its state read (pose and velocity) and the loads of ``floor`` applied, each call as fast as
    PyBullet takes it (client id positional): the limit under any simulator built on PyBullet. Divide
    by ``bodies`` for the cost per body."""
    if floor not in FLOORS:
        raise ValueError(f"floor={floor!r}; allowed: {list(FLOORS)}")
    hubs = [(0.13, 0.13, 0.0), (-0.13, 0.13, 0.0), (-0.13, -0.13, 0.0), (0.13, -0.13, 0.0)]
    cid = p.connect(p.DIRECT)
    try:
        p.setGravity(0, 0, -9.81, physicsClientId=cid)
        p.setTimeStep(1 / 200, physicsClientId=cid)
        shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=(0.2, 0.2, 0.05), physicsClientId=cid)
        ids = [
            p.createMultiBody(0.42, shape, basePosition=(10.0 * k, 0, 1), physicsClientId=cid)
            for k in range(bodies)
        ]
        four = floor == FLOORS[0]
        start = time.perf_counter()
        for _ in range(steps):
            for body in ids:  # the client id positionally, as the envs pass it (world.py)
                position, _ = p.getBasePositionAndOrientation(body, cid)
                p.getBaseVelocity(body, cid)
                if four:
                    for hub in hubs:
                        p.applyExternalForce(body, -1, (0, 0, 1.03), hub, p.LINK_FRAME, cid)
                else:
                    p.applyExternalForce(body, -1, (0, 0, 4.12), position, p.WORLD_FRAME, cid)
                    p.applyExternalTorque(body, -1, (0, 0, 0), p.WORLD_FRAME, cid)
            p.stepSimulation(cid)
        return (time.perf_counter() - start) / steps
    finally:
        p.disconnect(physicsClientId=cid)


def env_step_seconds(steps: int, resets: int = 20, **env_kwargs) -> tuple[float, float]:
    """Seconds per FanTracking policy step (resets excluded) and per reset (mean of ``resets``
    after the first), with zero actions."""
    env = gym.make("QuadWrench/FanTracking-v1", **env_kwargs)
    try:
        env.reset(seed=0)
        env.step(np.zeros(4, dtype=np.float32))  # compiled kernels load on first use
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


def paired_step_seconds(steps: int, blocks: int, settings: list[dict[str, Any]]) -> list[float]:
    """Seconds per FanTracking policy step (zero actions, episodes restarted as they end) of one env per
    ``settings``, all built first and then timed in turn, ``blocks`` blocks of ``steps`` steps each
    (A B A B ...): the least block of each. Alternating blocks in one process keeps a ratio between
    them meaningful on a machine whose speed drifts."""
    envs = [gym.make("QuadWrench/FanTracking-v1", **kwargs) for kwargs in settings]
    try:
        action = np.zeros(4, dtype=np.float32)
        for env in envs:
            env.reset(seed=0)
            env.step(action)  # compiled kernels load on first use
        best = [float("inf")] * len(envs)
        for _ in range(blocks):
            for k, env in enumerate(envs):
                start = time.perf_counter()
                for _ in range(steps):
                    *_, terminated, truncated, _ = env.step(action)
                    if terminated or truncated:
                        env.reset()
                best[k] = min(best[k], (time.perf_counter() - start) / steps)
        return best
    finally:
        for env in envs:
            env.close()


def paired_floor_shares(steps: int, blocks: int, **env_kwargs: Any) -> dict[str, float]:
    """Seconds per physics step of the FanTracking env (zero actions) and each floor's share of it,
    the env and the bare steps timed in alternating blocks in one process (the least block of each):
    a share that a machine drifting between separate runs cannot move."""
    env = gym.make("QuadWrench/FanTracking-v1", **env_kwargs)
    substeps = env.unwrapped.fleet.substeps
    try:
        env.reset(seed=0)
        action = np.zeros(4, dtype=np.float32)
        env.step(action)
        best = {"env": float("inf"), **{floor: float("inf") for floor in FLOORS}}
        for _ in range(blocks):
            start = time.perf_counter()
            for _ in range(steps):
                *_, terminated, truncated, _ = env.step(action)
                if terminated or truncated:
                    env.reset()
            best["env"] = min(best["env"], (time.perf_counter() - start) / steps / substeps)
            for floor in FLOORS:
                best[floor] = min(best[floor], bare_pybullet_step_seconds(substeps * steps, floor=floor))
    finally:
        env.close()
    return {"physics step": best["env"], **{floor: best[floor] / best["env"] for floor in FLOORS}}


def vector_step_seconds(steps: int, num_envs: int, **env_kwargs) -> float:
    """Seconds per policy step of the FanTracking vector env of ``num_envs`` vehicles with zero
    actions (episode ends and their resets included, as they happen)."""
    venv = gym.make_vec(
        "QuadWrench/FanTracking-v1", num_envs=num_envs, vectorization_mode="vector_entry_point", **env_kwargs
    )
    try:
        venv.reset(seed=0)
        action = np.zeros((num_envs, 4), dtype=np.float32)
        venv.step(action)
        start = time.perf_counter()
        for _ in range(steps):
            venv.step(action)
        return (time.perf_counter() - start) / steps
    finally:
        venv.close()


def _time(call, calls: int, repeats: int = 3) -> float:
    """Seconds per call of ``call``: the least of ``repeats`` runs of ``calls`` calls."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(calls):
            call()
        best = min(best, (time.perf_counter() - start) / calls)
    return best


def component_seconds(calls: int, num_envs: int = 1, **env_kwargs) -> dict[str, float]:
    """Seconds per call and vehicle of each part of a step, timed in isolation on a live env: the
    single env, or with ``num_envs`` > 1 the vector env. The parts of one physics step (PyBullet's
    calls as the compiled step makes them, the estimator, the kernels and glue as the rest of the whole
    step), then the per-policy-step work."""
    if num_envs == 1:
        env = gym.make("QuadWrench/FanTracking-v1", **env_kwargs)
        env.reset(seed=0, options={"offset_y": 0.4})
        base = env.unwrapped
        infos = base._info
    else:
        env = gym.make_vec(
            "QuadWrench/FanTracking-v1",
            num_envs=num_envs,
            vectorization_mode="vector_entry_point",
            **env_kwargs,
        )
        env.reset(seed=0)
        base = env.unwrapped
        infos = base._infos
    try:
        fleet = base.fleet
        action = np.zeros((num_envs, 4))
        base.step(action[0] if num_envs == 1 else action)
        compiled = fleet.compiled  # PyBullet's calls as the step makes them (one vehicle: step_one)
        parts_one = (compiled.forces, compiled.torques, fleet.state.position)
        loads = [tuple(part[0].tolist()) for part in parts_one]
        parts = {
            "compiled: autopilot, motors, disturbances": lambda: compiled.physics_steps(action, 1),
            "PyBullet apply + step": (
                (lambda: fleet.world.step_one(*loads))
                if compiled.single
                else lambda: fleet.world.step(compiled.forces, compiled.torques, fleet.state.position)
            ),
            "PyBullet read": compiled.read_world,
        }
        out = {f"physics step: {name}": _time(call, calls) for name, call in parts.items()}
        whole = out.pop("physics step: compiled: autopilot, motors, disturbances")  # less what is timed alone
        estimator = _time(compiled.estimate, calls)
        pybullet = out["physics step: PyBullet apply + step"] + out["physics step: PyBullet read"]
        rest = whole - pybullet - estimator
        out["physics step: kernels (autopilot, motors, disturbances, sensors) + glue"] = rest
        out[f"physics step: estimator ({fleet.estimator.name}, compiled)"] = estimator

        def policy_part() -> None:
            view = fleet.view()
            record = base.task.step(view, action, fleet.terminations() > 0)
            observations(fleet, view, record.blocks, action)
            infos()

        out["policy step: observation, reward, termination, info"] = _time(policy_part, calls)
        return {name: seconds / num_envs for name, seconds in out.items()}
    finally:
        env.close()


def filter_bank_step_seconds(
    count: int,
    steps: int,
    seed: int = 0,
    dt: float = 0.005,
    filter_by_filter: bool = False,
    name: str = "ukf",
) -> float:
    """Seconds per step of a bank of ``count`` estimators ``name`` (all of them; UKFs by default) fed
    hovering vehicles' noisy poses; ``filter_by_filter`` runs a UKF bank on the filter-by-filter kernel
    even where it would run on SIMD lanes (the baseline of the lanes)."""
    vehicle = make_vehicle("ardrone2")
    bank = make_estimator_bank(name, vehicle, dt, count)
    if filter_by_filter:
        bank._step_kernel = ukf_bank_step
    rng = np.random.default_rng(seed)
    positions, quaternions = np.tile((0.0, 0.0, 1.0), (count, 1)), np.tile((1.0, 0.0, 0.0, 0.0), (count, 1))
    bank.reset(slice(None), positions, quaternions)
    thrusts, torques = np.full(count, vehicle.mass * GRAVITY), np.zeros((count, 3))
    noisy = positions + 5e-4 * rng.standard_normal((steps, count, 3))
    start = time.perf_counter()
    for k in range(steps):
        bank.step(EstimatorInputs(thrusts, torques, noisy[k], quaternions))
    return (time.perf_counter() - start) / steps


def estimator_step_seconds(
    name: str, steps: int, seed: int = 0, dt: float = 0.005, vehicle: str = "ardrone2", **settings: Any
) -> float:
    """Seconds per ``step`` of estimator ``name`` (with its ``settings``) fed a hovering ``vehicle``'s noisy
    pose (0.5 mm, 2 mrad)."""
    vehicle = make_vehicle(vehicle)
    est = make_estimator(name, vehicle, dt, **settings)
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


def recorded_observations(
    base: str, params: dict[str, Any], count: int, steps: int, seed: int = 0
) -> tuple[Any, np.ndarray]:
    """(the vector env's unwrapped attributes, (steps, count, width) observations): ``count`` vehicles of
    DisturbanceRejection-v0 (``attitude`` action) flown for ``steps`` control steps by the batched
    ``base`` controller (:data:`quad_wrench_env.control.residual.BASES`) with gains ``params``, from
    ``seed``; the env is closed, its layout, vehicle, period and scaling kept."""
    venv = gym.make_vec(
        "QuadWrench/DisturbanceRejection-v0",
        num_envs=count,
        vectorization_mode="vector_entry_point",
        action_type="attitude",
    )
    try:
        controller = controller_batch(base, params, count, venv)
        observations, _ = venv.reset(seed=seed)
        recorded = []
        for _ in range(steps):
            recorded.append(observations)
            observations, *_ = venv.step(controller.actions(observations))
        return venv.unwrapped, np.array(recorded)
    finally:
        venv.close()


def controller_batch(base: str, params: dict[str, Any], count: int, env: Any) -> Any:
    """A batched ``base`` controller of ``count`` vehicles with gains ``params``, configured for ``env``
    (a vector env or its unwrapped attributes)."""
    controller_class, gains_class = BASES[base]
    env = getattr(env, "unwrapped", env)
    controller = controller_class(build(gains_class, params, prefix=f"{base}."), count)
    tilt = np.radians(env.cfg.action_limits.max_tilt_deg)
    controller.configure(env.obs_layout, env.vehicle, env.dt, env.action_scaling, float(tilt))
    return controller


def controller_step_seconds(
    base: str, params: dict[str, Any], env: Any, observations: np.ndarray, batched: bool
) -> float:
    """Seconds per vehicle-step of the ``base`` controller over recorded ``observations`` (steps, count,
    width): one batch of ``count`` vehicles (``batched``) or ``count`` controllers of one vehicle each,
    all fresh (set-up not timed)."""
    steps, count = observations.shape[:2]
    if batched:
        batch = controller_batch(base, params, count, env)
        start = time.perf_counter()
        for frame in observations:
            batch.actions(frame)
    else:
        singles = [controller_batch(base, params, 1, env) for _ in range(count)]
        start = time.perf_counter()
        for frame in observations:
            for vehicle, single in enumerate(singles):
                single.actions(frame[vehicle : vehicle + 1])
    return (time.perf_counter() - start) / (steps * count)
