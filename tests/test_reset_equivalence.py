"""Nothing carries over from one episode to the next: an episode flown after another and a reset gives,
bit for bit, the numbers of the same episode flown by fresh objects (issue 51, item 1).

Every class of the package that keeps state between steps (one that defines ``reset``, ``restart`` or
``reset_vehicle``) is listed in :data:`STATEFUL` with the case that covers it; a class that is not
listed fails ``test_every_stateful_class_has_a_case``. The cases fly an episode of one seed, reset to
another and fly it, and compare that second episode with fresh objects' (the env or the vector env and,
for an agent with memory, the agent): observations, rewards, flags, every number of ``info`` at the
reset and at every step, and the task's metrics of the episode (``longest_contact_loss_s`` among them).
"""

from __future__ import annotations

import importlib
import inspect
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import quad_wrench_env
from quad_wrench_env.agents import make_agent
from quad_wrench_env.agents.evaluate import episode_metrics, run_episode
from scripts.same_numbers import EVERYTHING  # every configurable disturbance at once

FAN_TRACKING = "QuadWrench/FanTracking-v1"
REJECTION = "QuadWrench/DisturbanceRejection-v0"
EXERTION = "QuadWrench/ForceExertion-v0"
STEPS = 40
FIRST, SECOND = 11, 12
RESIDUAL_PID = {"action_type": "residual", "residual": {"base": "pid", "params": {"compensation": True}}}
RESIDUAL_MPC = {
    "action_type": "residual",
    "residual": {"base": "mpc", "params": {"compensation": True, "slack": True}},
}
ENV_CASES = {  # (env id, env settings)
    "fan tracking, ukf": (FAN_TRACKING, {"estimator": "ukf"}),
    "fan tracking, ukf, matched walks": (FAN_TRACKING, {"estimator_params": {"adaptive_walks": True}}),
    "fan tracking, ekf, onboard state estimator": (
        FAN_TRACKING,
        {"estimator": "ekf", "sensors": {"state_estimator": True}},
    ),
    "fan tracking, observer, latency": (
        FAN_TRACKING,
        {"estimator": "observer", "sensors": {"latency_steps": 2}},
    ),
    "fan tracking, oracle, history": (FAN_TRACKING, {"estimator": "oracle", "history": 3}),
    "fan tracking, sensor history": (
        FAN_TRACKING,
        {"sensor_history": 6, "sensors": {"state_estimator": True}},
    ),
    "fan tracking, calibrated crazyflie2": (FAN_TRACKING, {"vehicle": "crazyflie2"}),
    "fan tracking, every disturbance": (FAN_TRACKING, EVERYTHING),
    "disturbance rejection": (REJECTION, {"action_type": "attitude"}),
    "disturbance rejection, learned estimator": (
        REJECTION,
        {"action_type": "attitude", "estimator": "learned"},
    ),
    "force exertion, pressing": (EXERTION, {"action_type": "wrench", "start_gap": 0.0}),
    "disturbance rejection, residual pid": (REJECTION, RESIDUAL_PID),
    "disturbance rejection, residual mpc": (REJECTION, RESIDUAL_MPC),
}
AGENT_CASES = {  # (agent, its parameters, env id, env settings)
    "pid": ("pid", {"compensation": True}, REJECTION, {"action_type": "attitude"}),
    "mpc": ("mpc", {"compensation": True, "slack": True}, REJECTION, {"action_type": "attitude"}),
    "ida_pbc": (
        "ida_pbc",
        {},
        EXERTION,
        {"action_type": "wrench", "start_gap": 0.0},
    ),  # in contact at the end
    "admittance": ("admittance", {}, FAN_TRACKING, {}),
    "hold": ("hold", {}, FAN_TRACKING, {}),
    "history policy": ("ppo_fan_tracking_history", {}, FAN_TRACKING, {}),
    "recurrent policy": ("ppo_fan_tracking_recurrent", {}, FAN_TRACKING, {}),
}
STATEFUL = {  # every stateful class: the case that flies it
    "agents.admittance.AdmittancePolicy": "agent: admittance",
    "agents.base.Policy": "protocol: each agent's case",
    "control.guidance.ReferenceExtrapolator": "agent: pid, mpc (their reference's acceleration)",
    "control.pid_controller.PIDController": "agent: pid; env, vector env: residual pid",
    "control.residual.ResidualActions": "env and vector env: disturbance rejection, residual pid, mpc",
    "control.mpc_controller.MPCController": "agent: mpc; env, vector env: residual mpc (warm starts)",
    "agents.hover.PositionHoldPolicy": "agent: hold",
    "agents.ida_pbc.IDAPBCPolicy": "agent: ida_pbc",
    "agents.mpc.MPCPolicy": "agent: mpc (its warm start)",
    "agents.pid.PIDPolicy": "agent: pid (its integral)",
    "agents.sb3_policy.SB3Policy": "agent: history policy, recurrent policy (its hidden state)",
    "agents.sb3._Still": "stateless apart from the action shape (training's first evaluation)",
    "autopilot.Autopilot": "env: every case (its integrals and yaw set-point)",
    "engine.fleet.Fleet": "env: every case (the contact force: force exertion)",
    "engine.draws.NoiseBlocks": "env: every case",
    "engine.observation.ObservationHistory": "env: fan tracking, oracle, history",
    "envs.base.QuadWrenchEnv": "env: every case",
    "envs.vector.QuadWrenchVectorEnv": "vector env",
    "envs.sb3_vec_env.SB3VecEnv": "vector env, through SB3's interface",
    "estimators.bank.EstimatorBank": "protocol: each bank's case",
    "estimators.bank.OracleBank": "env: fan tracking, oracle, history",
    "estimators.bank.TruthRecorder": "forwards reset to the oracle bank it wraps (fit-estimator's test)",
    "estimators.bank.BankOfOne": "single estimators: test_a_single_estimator_restarts_as_new",
    "estimators.base.Estimator": "protocol: test_a_single_estimator_restarts_as_new",
    "estimators.ekf.ExtendedFilterBank": "env: fan tracking, ekf, onboard state estimator",
    "estimators.learned.LearnedBank": (
        "env: disturbance rejection, learned estimator (its memory, frame, trail and trackers)"
    ),
    "estimators.observer.ObserverBank": "env: fan tracking, observer, latency",
    "estimators.oracle.OracleEstimator": "single estimators: test_a_single_estimator_restarts_as_new",
    "estimators.ukf.UnscentedFilterBank": "env: fan tracking, ukf (and its matched walks)",
    "flight_log.FlightRecorder": "test_a_flight_recorder_records_the_episode_after_a_reset_as_new",
    "rotors.Rotors": "env: every case (calibrated crazyflie2 too)",
    "sensors.MotionCapture": "env: fan tracking, observer, latency (its delay line)",
    "tasks.base.Task": "protocol: each task's case",
    "tasks.disturbance_rejection.DisturbanceRejection": "env: disturbance rejection",
    "tasks.fan_tracking.FanTracking": "env: fan tracking (the fan's turbulence)",
    "tasks.force_exertion.ForceExertion": "env: force exertion, pressing",
    "disturbances.base.WindField": "protocol: env: fan tracking, every disturbance",
    "disturbances.base.Steady": "env: fan tracking, every disturbance",
    "disturbances.dryden.DrydenGust": "env: fan tracking, every disturbance",
    "disturbances.fan.FanJet": "env: fan tracking (the turbulence)",
    "disturbances.jet.Jet": "env: fan tracking, every disturbance",
}
"""Class (its module under ``quad_wrench_env``): the case that covers it."""
STATE_METHODS = ("reset", "restart", "reset_vehicle")


def stateful_classes() -> set[str]:
    """Every class of the package that defines one of :data:`STATE_METHODS` itself."""
    root = Path(quad_wrench_env.__file__).parent
    found = set()
    for path in sorted(root.rglob("*.py")):
        parts = path.relative_to(root.parent).with_suffix("").parts
        if parts[-1] == "__main__":
            continue
        module_name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        module = importlib.import_module(module_name)
        for name, value in vars(module).items():
            own = inspect.isclass(value) and value.__module__ == module_name
            if own and any(method in vars(value) for method in STATE_METHODS):
                found.add(f"{module_name.removeprefix('quad_wrench_env.')}.{name}")
    return found


def test_every_stateful_class_has_a_case():
    """A class that keeps state (it defines ``reset``, ``restart`` or ``reset_vehicle``) and is not in
    STATEFUL fails here: give it a case below."""
    found = stateful_classes()
    missing = sorted(found - set(STATEFUL))
    assert not missing, f"stateful classes without a reset-equivalence case: {missing}"
    assert not sorted(set(STATEFUL) - found), "STATEFUL lists classes that are gone"


def _numbers(value) -> list:
    """Every number in ``value`` (dicts by sorted key, sequences, arrays), as bytes-comparable arrays."""
    if isinstance(value, dict):
        return [item for key in sorted(value) for item in [key, *_numbers(value[key])]]
    if isinstance(value, (list, tuple)):
        return [item for element in value for item in _numbers(element)]
    if isinstance(value, np.ndarray) and value.dtype != object:
        return [value.copy()]
    if isinstance(value, (int, float, bool, np.number, np.bool_)):
        return [np.asarray(value)]
    return [repr(value)]


def _same(first: list, second: list) -> None:
    assert len(first) == len(second)
    for k, (a, b) in enumerate(zip(first, second, strict=True)):
        if isinstance(a, np.ndarray):
            np.testing.assert_array_equal(a, b, err_msg=f"item {k}")
        else:
            assert a == b, k


class _Replay:
    """A policy of seeded random actions, the same sequence every episode (stateless across episodes by
    construction: what differs is the env's)."""

    def reset(self, env) -> None:
        self.rng, self.shape = np.random.default_rng(5), env.action_space.shape

    def act(self, observation):
        return self.rng.uniform(-0.6, 0.6, self.shape).astype(np.float32)


def _episode(policy, env, seed: int) -> list:
    """The numbers of one episode of ``policy`` (cut at :data:`STEPS`) and its metrics."""
    env = gym.wrappers.TimeLimit(env, STEPS)
    trace = []
    episode = run_episode(policy, env, seed, on_step=lambda e, info: trace.append(_numbers(info)))
    metrics = episode_metrics(env.unwrapped.task, episode)
    return [item for numbers in trace for item in numbers] + _numbers(episode.trace) + _numbers(metrics)


@pytest.mark.parametrize("case", list(ENV_CASES))
def test_an_env_after_an_episode_and_a_reset_is_a_fresh_env(case):
    env_id, settings = ENV_CASES[case]
    used, fresh = gym.make(env_id, **settings), gym.make(env_id, **settings)
    try:
        _episode(_Replay(), used, FIRST)
        _same(_episode(_Replay(), used, SECOND), _episode(_Replay(), fresh, SECOND))
    finally:
        used.close()
        fresh.close()


@pytest.mark.parametrize("case", list(AGENT_CASES))
def test_an_agent_after_an_episode_and_a_reset_is_a_fresh_agent(case):
    """The same agent object flies two episodes: the second is a fresh agent's (a PID's integral, an
    MPC's warm start, a recurrent policy's hidden state start over)."""
    name, params, env_id, settings = AGENT_CASES[case]
    agent, env = make_agent(name, **params), gym.make(env_id, **settings)
    fresh_agent, fresh_env = make_agent(name, **params), gym.make(env_id, **settings)
    if hasattr(agent, "env_settings"):  # a learned policy flies with its training env's settings
        env.close()
        fresh_env.close()
        env, fresh_env = (gym.make(env_id, **agent.env_settings(settings), **settings) for _ in range(2))
    try:
        _episode(agent, env, FIRST)
        _same(_episode(agent, env, SECOND), _episode(fresh_agent, fresh_env, SECOND))
    finally:
        env.close()
        fresh_env.close()


@pytest.mark.parametrize(
    ("env_id", "settings"),
    [(FAN_TRACKING, {}), (EXERTION, {}), (REJECTION, RESIDUAL_PID), (REJECTION, RESIDUAL_MPC)],
)
def test_a_vector_env_after_episodes_and_a_reset_is_a_fresh_one(env_id, settings):
    """Every vehicle of a vector env (its own and SB3's interface) restarts as new on ``reset``."""
    from quad_wrench_env.envs.sb3_vec_env import SB3VecEnv

    def fly(env, seeds):
        rng = np.random.default_rng(3)
        observations, info = env.reset(seed=seeds)
        trace = [observations, *_numbers(info)]
        for _ in range(STEPS):
            observations, reward, terminated, truncated, info = env.step(
                rng.uniform(-0.6, 0.6, (3, 4)).astype(np.float32)
            )
            trace += [observations, reward, terminated, truncated, *_numbers(info)]
        return trace

    def make():
        return gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point", **settings)

    used, fresh = make(), make()
    try:
        fly(used, [1, 2, 3])
        _same(fly(used, [4, 5, 6]), fly(fresh, [4, 5, 6]))
    finally:
        used.close()
        fresh.close()
    stepped = []
    for _ in range(2):
        venv = SB3VecEnv(make())
        venv.seed(4)
        venv.reset()
        for _ in range(STEPS // 2):
            venv.step(np.full((3, 4), 0.3, dtype=np.float32))
        venv.seed(7)
        stepped.append(venv.reset())
        venv.close()
    second = SB3VecEnv(make())
    second.seed(7)
    np.testing.assert_array_equal(stepped[0], second.reset())
    second.close()


@pytest.mark.parametrize("name", ["ukf", "ekf", "observer", "oracle", "learned"])
def test_a_single_estimator_restarts_as_new(name):
    """A single-vehicle estimator fed one flight, reset, and fed another gives a fresh one's estimates."""
    from quad_wrench_env.estimators import make_estimator
    from quad_wrench_env.estimators.base import TruthFed
    from quad_wrench_env.vehicle import GRAVITY, make_vehicle

    vehicle = make_vehicle("ardrone2")

    def fly(estimator, seed):
        rng = np.random.default_rng(seed)
        estimator.reset(np.array((0.0, 0.0, 1.0)), np.array((1.0, 0.0, 0.0, 0.0)))
        out = []
        for _ in range(100):
            position = np.array((0.0, 0.0, 1.0)) + 5e-4 * rng.standard_normal(3)
            if isinstance(estimator, TruthFed):
                estimator.observe_truth(estimator.state, rng.standard_normal(3), rng.standard_normal(3))
            thrust = vehicle.mass * GRAVITY * (1.0 + 0.05 * rng.standard_normal())
            w = estimator.step(
                thrust, 0.001 * rng.standard_normal(3), position, np.array((1.0, 0.0, 0.0, 0.0))
            )
            out += [w.force, w.torque]
        return out

    used = make_estimator(name, vehicle, 0.005, adaptive_walks=True) if name == "ukf" else None
    used = used or make_estimator(name, vehicle, 0.005)
    fresh = make_estimator(name, vehicle, 0.005, adaptive_walks=True) if name == "ukf" else None
    fresh = fresh or make_estimator(name, vehicle, 0.005)
    fly(used, 1)
    _same(fly(used, 2), fly(fresh, 2))


def test_a_flight_recorder_records_the_episode_after_a_reset_as_new():
    """A recorder's log after a reset holds the new flight alone, as a fresh recorder's."""
    from quad_wrench_env.flight_log import FlightRecorder

    def record(env, seeds):
        recorder = FlightRecorder(env)
        for seed in seeds:
            run_episode(_Replay(), gym.wrappers.TimeLimit(env, STEPS), seed, on_step=recorder.on_step)
        log = recorder.log()
        return [log.time, log.position, log.quaternion, log.motor_speeds, log.wrench]

    used, fresh = gym.make(FAN_TRACKING), gym.make(FAN_TRACKING)
    try:
        _same(record(used, [FIRST, SECOND]), record(fresh, [SECOND]))
    finally:
        used.close()
        fresh.close()
