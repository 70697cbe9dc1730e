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


class _Clock:
    """Seconds spent in each timed call of a step, by part."""

    def __init__(self) -> None:
        self.spent: dict[str, float] = {}

    def timed(self, name: str, call: Any) -> Any:
        """``call`` with its time added to part ``name`` at each call."""
        spent, clock = self.spent, time.perf_counter
        spent.setdefault(name, 0.0)

        def timed_call(*args: Any) -> Any:
            start = clock()
            try:
                return call(*args)
            finally:
                spent[name] += clock() - start

        return timed_call


PHYSICS_PARTS = {
    "_before": "controls and disturbance loads (kernel)",
    "read_world": "PyBullet read",
    "_after_kernel": "state, winds and sensors (kernel)",
    "estimate": "estimator (compiled)",
    "_record_sensors": "sensor block (kernel)",
    "_centre_wind": "air at the centres of mass (kernel)",
}
"""The compiled step's calls timed as parts of a physics step (attribute -> part), besides PyBullet's
step (``World.step_one`` or ``World.step``)."""

VIEW, TERMINATIONS = "policy: fleet view (estimates read)", "policy: engine terminations"
TASK_STEP, OBSERVATION = "policy: task step (reward terms, codes, blocks, info)", "policy: observation"
POLICY_CALLS = (VIEW, TERMINATIONS, TASK_STEP, OBSERVATION)
"""The simulation's timed calls besides the physics."""
SIMULATION_OWN = "policy: the simulation's own Python (the step's outcome kernel: counts, rewards, codes)"
ENV_OWN = "policy: the env's own Python (checks, clip, restarts, info dict)"
STEP_PARTS = (
    "physics: controls and disturbance loads (kernel)",
    "physics: PyBullet apply + step",
    "physics: PyBullet read",
    "physics: state, winds and sensors (kernel)",
    "physics: estimator (compiled)",
    "physics: sensor block (kernel)",
    "physics: air at the centres of mass (kernel)",
    "physics: the loop's own Python",
    *POLICY_CALLS,
    SIMULATION_OWN,
    "policy: info",
    ENV_OWN,
)
"""The parts :func:`step_parts_seconds` reports, in order; they add up to a timed step."""


def step_parts_seconds(steps: int, num_envs: int = 1, blocks: int = 3, **env_kwargs: Any) -> dict[str, float]:
    """Where a FanTracking policy step's time goes (seconds per vehicle and policy step, zero actions):
    each part of :data:`STEP_PARTS` timed inside real steps of the single env (``num_envs`` = 1) or the
    vector env, the calls of each layer timed and the layer's own Python the rest of it, so the parts add
    up to the timed step; ``"whole step (timed)"`` is their sum, ``"whole step"`` the same steps without
    timers (alternating blocks of ``steps`` steps, the least block of each) and ``"the timers' own cost"``
    the difference (spread over the parts, the Python ones mostly)."""
    if num_envs == 1:
        env = gym.make("QuadWrench/FanTracking-v1", **env_kwargs)
        base = env.unwrapped
        info_name, action = "_info", np.zeros(4, dtype=np.float32)
    else:
        env = gym.make_vec(
            "QuadWrench/FanTracking-v1",
            num_envs=num_envs,
            vectorization_mode="vector_entry_point",
            **env_kwargs,
        )
        base = env.unwrapped
        info_name, action = "_infos", np.zeros((num_envs, 4), dtype=np.float32)
    try:
        env.reset(seed=0)
        env.step(action)  # compiled kernels load on first use
        compiled = base.fleet.compiled
        best_plain, best_timed, parts = float("inf"), float("inf"), {}
        for _ in range(blocks):
            env.reset(seed=0)
            start = time.perf_counter()
            for _ in range(steps):
                env.step(action)
            best_plain = min(best_plain, time.perf_counter() - start)
            clock = _Clock()
            _instrument(clock, base, info_name)
            env.reset(seed=0)  # restarts rebind the compiled step: its parts timed again after each
            clock.spent.update(dict.fromkeys(clock.spent, 0.0))  # the reset's own calls not counted
            start = time.perf_counter()
            for _ in range(steps):
                env.step(action)
            whole = time.perf_counter() - start
            for owner, name in _timed_attributes(base, info_name):
                owner.__dict__.pop(name, None)
            compiled.rebind()
            if whole < best_timed:
                best_timed, parts = whole, _layers(clock.spent, whole)
        per = steps * num_envs
        out = {name: parts.get(name, 0.0) / per for name in STEP_PARTS}
        out["whole step (timed)"] = best_timed / per
        out["whole step"] = best_plain / per
        out["the timers' own cost"] = out["whole step (timed)"] - out["whole step"]
        return out
    finally:
        env.close()


def _timed_attributes(base: Any, info_name: str) -> list[tuple[Any, str]]:
    """``(object, attribute)`` of every call :func:`_instrument` wraps (instance attributes it sets)."""
    simulation, fleet = base.simulation, base.fleet
    return [
        (base, info_name),
        (simulation, "step"),
        (simulation, "_observe"),
        (simulation.task, "step"),
        (fleet, "view"),
        (fleet, "terminations"),
        (fleet.world, "step_one"),
        (fleet.world, "step"),
        (fleet.compiled, "rebind"),
        (fleet.compiled, "physics_steps"),
        *((fleet.compiled, name) for name in PHYSICS_PARTS),
    ]


def _instrument(clock: _Clock, base: Any, info_name: str) -> None:
    """Wrap every call of a step with ``clock`` (instance attributes shadowing the methods); the
    compiled step's bound calls wrapped again after each of its rebinds."""
    simulation, fleet = base.simulation, base.fleet
    compiled, world = fleet.compiled, fleet.world
    for owner, name, part in (
        (base, info_name, "policy: info"),
        (simulation, "step", "simulation"),
        (fleet, "view", VIEW),
        (fleet, "terminations", TERMINATIONS),
        (simulation.task, "step", TASK_STEP),
        (simulation, "_observe", OBSERVATION),
        (world, "step_one", "physics: PyBullet apply + step"),
        (world, "step", "physics: PyBullet apply + step"),
        (compiled, "physics_steps", "physics loop"),
    ):
        setattr(owner, name, clock.timed(part, getattr(owner, name)))
    rebind = type(compiled).rebind

    def rebind_timed() -> None:
        for name in PHYSICS_PARTS:
            compiled.__dict__.pop(name, None)
        rebind(compiled)
        for name, part in PHYSICS_PARTS.items():
            call = getattr(compiled, name)
            if call is not None:
                setattr(compiled, name, clock.timed(f"physics: {part}", call))

    compiled.rebind = rebind_timed


def _layers(spent: dict[str, float], whole: float) -> dict[str, float]:
    """The timed calls as :data:`STEP_PARTS` of a step that took ``whole``: each layer's own Python is
    its time less its timed calls' (the fleet's step, a call into the physics loop, is the simulation's
    own; the env's own is the step less the simulation's step and the info)."""
    parts = dict(spent)
    physics = [f"physics: {part}" for part in PHYSICS_PARTS.values()] + ["physics: PyBullet apply + step"]
    loop = parts.pop("physics loop", 0.0)
    parts["physics: the loop's own Python"] = loop - sum(parts.get(name, 0.0) for name in physics)
    simulation = parts.pop("simulation", 0.0)
    parts[SIMULATION_OWN] = simulation - loop - sum(parts.get(name, 0.0) for name in POLICY_CALLS)
    parts[ENV_OWN] = whole - simulation - parts.get("policy: info", 0.0)
    return parts


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


def solver_profile(base: str, params: dict[str, Any], env: Any, observations: np.ndarray) -> dict[str, float]:
    """What the QPs of a fresh batch of the ``mpc`` controller did over recorded ``observations``
    (steps, count, width), over all vehicle-steps: DAQP's own solve time (s, mean), the iterations
    (mean, median, max), the share of vehicle-steps solved in two stages (the hard problem was
    infeasible, the soft one was solved: :meth:`~quad_wrench_env.control.mpc_controller.
    PositionMPC.solve_prepared`) and the share of all iterations spent in those."""
    if base != "mpc":
        raise ValueError(f"solver_profile reads the MPC's QPs: base must be 'mpc', not {base!r}")
    batch = controller_batch(base, params, observations.shape[1], env)
    iterations, seconds, stages = [], [], []
    for frame in observations:
        batch.actions(frame)
        for qp in batch.qps:
            iterations.append(qp.iterations)
            seconds.append(qp.solve_time)
            stages.append(qp.stages)
    counts, two = np.array(iterations), np.array(stages) == 2
    return {
        "solve_seconds": float(np.mean(seconds)),
        "iterations_mean": float(counts.mean()),
        "iterations_median": float(np.median(counts)),
        "iterations_max": float(counts.max()),
        "two_stage_share": float(two.mean()),
        "two_stage_iteration_share": float(counts[two].sum() / counts.sum()),
    }


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
