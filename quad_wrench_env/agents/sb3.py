"""stable-baselines3 training runs.

:func:`train` runs PPO or SAC on any registered env id, batched through ``SB3VecEnv``, from one
:class:`TrainConfig`, into a run folder that holds what ran (config and commit), checkpoints, the
best model by the harness's own metric on fixed evaluation seeds, the curve and TensorBoard logs.
A run folder flies as an agent through :mod:`quad_wrench_env.agents.sb3_policy` (:class:`SB3Policy`,
:func:`load_policy`, imported here too).
"""

from __future__ import annotations

import csv
import dataclasses
import inspect
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import yaml
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.vec_env import VecNormalize

from quad_wrench_env.agents.distill import DaggerRecurrentPPO, DistillationSettings, Teacher
from quad_wrench_env.agents.normalize import CompiledVecNormalize
from quad_wrench_env.agents.sb3_policy import (
    MEANING_KEYS,
    ObservationScaling,
    SB3Policy,
    algorithm_class,
)
from quad_wrench_env.config import build, check_numbers, load_yaml, merged, set_keys


@dataclass
class EvaluationConfig:
    """Evaluation during training, on fixed seeds, with the harness's own metric."""

    seeds: list[int] = field(default_factory=lambda: [10_000, 10_001, 10_002, 10_003, 10_004])
    every_steps: int = 250_000
    options: dict[str, Any] = field(default_factory=dict)
    """Reset options of the evaluation episodes ({}: the env's default distribution)."""
    env: dict[str, Any] = field(default_factory=dict)
    """Env keyword arguments that replace the training env's in evaluation, e.g. to score a policy
    trained on an easier variant (a curriculum) on the task's own episodes."""
    metric: str = "return"
    """A metric of the harness's scores (``quad_wrench_env.agents.evaluate.episode_metrics``); the best
    checkpoint is the one with the best mean over the seeds."""
    lower_is_better: bool = False

    def __post_init__(self) -> None:
        seeds = self.seeds
        if not (isinstance(seeds, list) and seeds and all(_is_int(x) and x >= 0 for x in seeds)):
            raise ValueError(f"evaluation.seeds={seeds!r} must be a non-empty list of integers >= 0")
        if not (_is_int(self.every_steps) and self.every_steps >= 1):
            raise ValueError(f"evaluation.every_steps={self.every_steps!r} must be an integer >= 1")
        if not isinstance(self.env, dict):
            raise ValueError(f"evaluation.env={self.env!r} must be a mapping of env keyword arguments")
        if not isinstance(self.metric, str):
            raise ValueError(f"evaluation.metric={self.metric!r} must be a metric name")
        if not isinstance(self.lower_is_better, bool):
            raise ValueError(f"evaluation.lower_is_better={self.lower_is_better!r} must be true or false")


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


@dataclass
class TrainConfig:
    """Everything a training run is built from (one YAML file; see ``configs/train_*.yaml``)."""

    env_id: str = "QuadWrench/FanTracking-v1"
    env: dict[str, Any] = field(default_factory=dict)
    """Keyword arguments of the env (estimator, vehicle, action_type, any config key)."""
    algorithm: str = "ppo"
    num_envs: int = 32
    """Vehicles flown in one batched env (``SB3VecEnv``)."""
    total_steps: int = 1_000_000
    max_minutes: float = 0.0
    """Wall-clock budget (0: none): training stops at whichever of this and ``total_steps`` comes first."""
    seed: int = 0
    hyperparameters: dict[str, Any] = field(default_factory=dict)
    """Keyword arguments of the SB3 algorithm (``n_steps``, ``batch_size``, ``learning_rate``, ...)."""
    learning_rate_end: float | None = None
    """None: ``learning_rate`` stays constant; a number: the learning rate falls linearly from
    ``hyperparameters.learning_rate`` (or the algorithm's default) to this over ``total_steps``
    (:class:`LinearRate` on SB3's progress; a run stopped by ``max_minutes`` ends part way down). The
    schedule is the run's: resuming refuses another ``learning_rate``, ``learning_rate_end`` or
    ``total_steps`` for it."""
    net_arch: list[int] = field(default_factory=lambda: [64, 64])
    activation: str = "tanh"
    log_std_init: float = 0.0
    """PPO's initial log standard deviation of its Gaussian actions (SB3's default 0: σ = 1, half
    the [-1, 1] action range). Lower it where a random action of that size ends every episode."""
    privileged_critic: bool = False
    """An asymmetric actor-critic (PPO only): the env appends the truth (``env.privileged``, set by
    this), the critic reads it and the actor never does (:mod:`quad_wrench_env.agents.privileged`)."""
    normalize_observations: bool = True
    normalize_rewards: bool = True
    clip_observations: float = 10.0
    checkpoint_every_steps: int = 500_000
    evaluation: EvaluationConfig = field(default_factory=EvaluationConfig)
    init_from: str | None = None
    """A run folder or a shipped policy whose kept model starts this run: its network's weights and its
    observation statistics (this run's hyperparameters and optimiser). Its observations and actions
    must mean what this run's do (the estimator may differ: a policy flown on another estimator's
    output, rapid motor adaptation's deployment). With ``total_steps: 0`` the run keeps it as it is."""
    teacher: str | None = None
    """``algorithm: dagger``: the policy the student imitates (a run folder or a shipped policy,
    :class:`~quad_wrench_env.agents.distill.Teacher`)."""
    distillation: DistillationSettings = field(default_factory=DistillationSettings)
    """``algorithm: dagger``: how the student imitates (:mod:`quad_wrench_env.agents.distill`)."""
    threads: int = 1
    """Torch threads: 1 leaves the other core of a 2-core machine to a second run."""
    env_processes: int = 1
    """Processes the vehicles are stepped in at once (:class:`~quad_wrench_env.envs.processes.
    ProcessVectorEnv`): 1 steps them all in the learner's process; 2 uses both cores of a 2-core
    machine for one run (the same numbers, so the same model). Keep 1 where runs share the cores
    (``quad-wrench study`` and ``sweep`` with two runs at once)."""
    env_groups: list[dict[str, Any]] = field(default_factory=list)
    """Env settings of each process's vehicles on top of ``env`` (empty: none; else one mapping per
    process, ``env_processes`` of them), e.g. ``[{vehicle: ardrone2}, {vehicle: hummingbird}]``:
    one policy trained across two presets (each group's settings merged into ``env`` key by key).
    :data:`RUN_KEYS` are the run's, not a group's. The evaluation scores every group's env on its
    seeds and keeps the mean."""

    def __post_init__(self) -> None:
        if self.algorithm not in ALGORITHMS:
            raise ValueError(f"algorithm={self.algorithm!r}; allowed: {sorted(ALGORITHMS)}")
        if self.activation not in ACTIVATIONS:
            raise ValueError(f"activation={self.activation!r}; allowed: {sorted(ACTIVATIONS)}")
        for name in ("num_envs", "total_steps", "checkpoint_every_steps", "threads", "env_processes"):
            value = getattr(self, name)
            if name == "total_steps" and value == 0 and self.init_from is not None:
                continue  # the starting model kept as it is
            if not (_is_int(value) and value >= 1):
                raise ValueError(f"{name}={value!r} must be an integer >= 1 (0 only with init_from)")
        if self.env_processes > self.num_envs:
            raise ValueError(
                f"env_processes={self.env_processes} must be at most num_envs={self.num_envs} "
                "(each process flies at least one vehicle)"
            )
        if self.env_groups:
            if not (isinstance(self.env_groups, list) and all(isinstance(g, dict) for g in self.env_groups)):
                raise ValueError(f"env_groups={self.env_groups!r} must be a list of mappings of env settings")
            if len(self.env_groups) != self.env_processes:
                raise ValueError(
                    f"env_groups has {len(self.env_groups)} entries; give one per process "
                    f"(env_processes={self.env_processes})"
                )
            shared = sorted({key for group in self.env_groups for key in group} & set(RUN_KEYS))
            if shared:
                raise ValueError(
                    f"env_groups set {shared}: what an observation or action means and the control "
                    "period are the run's (set them in env), not a group's"
                )
        check_numbers("train", self, ("max_minutes",), positive=False)
        check_numbers("train", self, ("clip_observations",))
        if self.learning_rate_end is not None:
            check_numbers("train", self, ("learning_rate_end",), positive=False)
            start = self.hyperparameters.get("learning_rate", 0.0)
            if not isinstance(start, float | int) or isinstance(start, bool):
                raise ValueError(
                    f"learning_rate_end={self.learning_rate_end!r} schedules a number; "
                    f"hyperparameters.learning_rate={self.hyperparameters['learning_rate']!r} is not one"
                )
        if not (isinstance(self.log_std_init, (int, float)) and math.isfinite(self.log_std_init)):
            raise ValueError(f"log_std_init={self.log_std_init!r} must be a finite number")
        if self.log_std_init != 0.0 and self.algorithm == "sac":
            raise ValueError(f"log_std_init={self.log_std_init!r} is PPO's; {self.algorithm} learns its own")
        for name in ("normalize_observations", "normalize_rewards", "privileged_critic"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name}={getattr(self, name)!r} must be true or false")
        if (self.algorithm == "dagger") != (self.teacher is not None):
            raise ValueError(
                f"algorithm={self.algorithm!r} with teacher={self.teacher!r}: distillation needs a teacher "
                "and a teacher needs distillation; allowed: algorithm dagger with a teacher, or neither"
            )
        if self.privileged_critic and self.algorithm != "ppo":
            raise ValueError(
                f"privileged_critic=true with algorithm={self.algorithm!r}: only ppo's critic is built "
                "apart from its actor here; allowed: algorithm ppo"
            )
        if self.privileged_critic or self.algorithm == "dagger":  # the critic's or the teacher's truth
            if self.env.get("privileged", True) is not True:
                reader = "privileged_critic=true" if self.privileged_critic else "algorithm dagger"
                raise ValueError(f"{reader} needs env.privileged true, not {self.env['privileged']!r}")
            self.env = {**self.env, "privileged": True}
        elif self.env.get("privileged", False):
            raise ValueError(
                "env.privileged=true without privileged_critic: the actor would read the truth; allowed: "
                "privileged_critic: true (the critic alone reads it)"
            )


RUN_KEYS = (*MEANING_KEYS, "policy_hz", "physics_hz")
"""Env settings every vehicle of a run shares (:attr:`TrainConfig.env_groups` refuses them): what an
observation or an action means, and the control and physics periods."""

ALGORITHMS = ("ppo", "sac", "recurrent_ppo", "dagger")
"""The learners: stable-baselines3's PPO and SAC, sb3-contrib's ``RecurrentPPO`` (an LSTM policy:
memory of its own, reset at each episode start), and a ``RecurrentPPO`` student distilled from a
``teacher`` (:mod:`quad_wrench_env.agents.distill`)."""
POLICY_CLASSES = {
    "ppo": "MlpPolicy",
    "sac": "MlpPolicy",
    "recurrent_ppo": "MlpLstmPolicy",
    "dagger": "MlpLstmPolicy",
}
ACTIVATIONS = ("tanh", "relu")


def train_config(values: Mapping[str, Any], updates: Mapping[str, Any]) -> TrainConfig:
    """The :class:`TrainConfig` of the mapping ``values`` with the dotted keys of ``updates`` set."""
    return build(TrainConfig, set_keys(values, updates))


class TrainingConfigError(ValueError):
    """A training run refused before anything ran or was written (:func:`check_training`)."""


RESERVED_HYPERPARAMETERS = ("policy", "env", "seed", "device", "verbose", "policy_kwargs", "tensorboard_log")
"""Keyword arguments of the SB3 algorithm that :func:`train` sets itself from the config."""


class _Still:
    """A policy whose action is always zero (the middle of every action type's range)."""

    def reset(self, env: gym.Env) -> None:
        self.shape = env.action_space.shape

    def act(self, observation: np.ndarray) -> np.ndarray:
        return np.zeros(self.shape, dtype=np.float32)


def check_training(
    config: TrainConfig, folder: str | Path, resume: bool = False, sources: bool = True
) -> None:
    """Refuses, before anything runs or is written, what would otherwise fail in the run, by
    :class:`TrainingConfigError` naming the value and what is allowed: a run folder that is not empty
    (or, to resume, holds nothing to resume from), an env id that is not registered, env settings the
    task refuses, hyperparameters the algorithm does not take or refuses (the algorithm is built once
    on the run's env), and evaluation settings or a metric the harness does not have (one evaluation
    episode of 0.1 s with the evaluation's env settings lists the metrics), and with ``sources`` an
    ``init_from`` or ``teacher`` that cannot start or teach this run (False where a study trains them
    first)."""
    from stable_baselines3.common.vec_env import VecMonitor

    import quad_wrench_env  # noqa: F401  (registers the env ids)
    from quad_wrench_env.agents.evaluate import evaluate
    from quad_wrench_env.envs.sb3_vec_env import SB3VecEnv

    folder = Path(folder)
    try:
        if resume:
            latest_snapshot(folder)
            _check_schedule_kept(config, folder)
        elif folder.exists() and any(folder.iterdir()):
            raise ValueError(f"run folder {str(folder)!r} is not empty; resume it or give a new folder")
        try:
            gym.spec(config.env_id)
        except gym.error.Error as error:
            raise ValueError(f"env_id={config.env_id!r}: {error}") from None
        algorithm = algorithm_class(config.algorithm)
        parameters = inspect.signature(algorithm.__init__).parameters
        allowed = {name for name in parameters if not name.startswith("_")}
        allowed -= {"self", *RESERVED_HYPERPARAMETERS}
        unknown = sorted(set(config.hyperparameters) - allowed)
        if unknown:
            raise ValueError(
                f"hyperparameters {unknown} are not {algorithm.__name__}'s; allowed: {sorted(allowed)}"
            )
        venv = gym.make_vec(
            config.env_id, num_envs=config.num_envs, vectorization_mode="vector_entry_point", **config.env
        )
        try:
            policy = POLICY_CLASSES[config.algorithm]
            algorithm(policy, VecMonitor(SB3VecEnv(venv)), device="cpu", **config.hyperparameters)
        except (TypeError, ValueError, AssertionError) as error:
            raise ValueError(f"hyperparameters={config.hyperparameters!r}: {error}") from None
        finally:
            venv.close()
        if sources and config.teacher is not None:
            Teacher(config.teacher, config.env_id, config.env)
        if sources and config.init_from is not None:
            starting_policy(config)
        e = config.evaluation
        for settings in evaluation_envs(config):  # every group's env settings, as the task takes them
            metrics = evaluate(
                _Still(),
                config.env_id,
                e.seeds[:1],
                options=e.options,
                **{**settings, "episode_seconds": 0.1},
            ).mean
            if e.metric not in metrics:
                raise ValueError(
                    f"evaluation.metric={e.metric!r}; allowed for {config.env_id}: {sorted(metrics)}"
                )
    except (ValueError, FileNotFoundError) as error:
        raise TrainingConfigError(str(error)) from None


@dataclass(frozen=True)
class LinearRate:
    """A learning-rate schedule for SB3 (a callable of its ``progress_remaining``, 1 at the start of
    the run and 0 at ``total_steps``): ``start`` falling linearly to ``end``."""

    start: float
    end: float

    def __call__(self, progress_remaining: float) -> float:
        return self.end + (self.start - self.end) * progress_remaining


SCHEDULE_KEYS = ("hyperparameters.learning_rate", "learning_rate_end", "total_steps")
"""What fixes a run's learning-rate schedule when it has one (``learning_rate_end``)."""


def _check_schedule_kept(config: TrainConfig, folder: Path) -> None:
    """Refuse resuming a run whose schedule (:data:`SCHEDULE_KEYS`) the new config would change: the
    saved model keeps the one it started with, and a longer run would move its line."""
    saved = folder / "config.yaml"
    if not saved.is_file():
        return
    before = load_yaml(saved)
    now = dataclasses.asdict(config)
    if before.get("learning_rate_end") is None and config.learning_rate_end is None:
        return

    def value(values: dict, key: str) -> Any:
        section, _, name = key.rpartition(".")
        return (values.get(section) or {}).get(name) if section else values.get(name)

    changed = [
        f"{key}: {value(before, key)!r} -> {value(now, key)!r}"
        for key in SCHEDULE_KEYS
        if value(before, key) != value(now, key)
    ]
    if changed:
        raise ValueError(
            f"resuming {str(folder)!r} would change its learning-rate schedule ({'; '.join(changed)}); "
            "a run with learning_rate_end keeps the schedule it started with: train a new run instead"
        )


def _default(algorithm: type[BaseAlgorithm], name: str) -> Any:
    """The default of keyword argument ``name`` of ``algorithm``'s constructor."""
    return inspect.signature(algorithm.__init__).parameters[name].default


def _commit() -> str:
    """The project's commit (with ``+dirty`` when the tree has changes), or ``unknown``."""
    import subprocess

    root = Path(__file__).resolve().parents[2]  # the repository: quad_wrench_env/agents/sb3.py
    try:
        head = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"], cwd=root, capture_output=True, text=True
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("+dirty" if dirty else "")


def training_env(config: TrainConfig) -> tuple[Any, VecNormalize]:
    """The training path: the task's vector env of ``num_envs`` vehicles (in ``env_processes``
    processes) behind ``SB3VecEnv`` (its step's numbers as arrays, no per-vehicle infos),
    ``VecMonitor`` and ``VecNormalize`` (compiled: :class:`~quad_wrench_env.agents.normalize.
    CompiledVecNormalize`, the same numbers) as the config says, seeded with ``config.seed``;
    returns the adapter and the outermost env."""
    from stable_baselines3.common.vec_env import VecMonitor

    from quad_wrench_env.envs.processes import ProcessVectorEnv
    from quad_wrench_env.envs.sb3_vec_env import SB3VecEnv

    if config.env_processes > 1 or config.env_groups:
        venv = ProcessVectorEnv(
            config.env_id, config.num_envs, config.env_processes, config.env_groups or None, **config.env
        )
    else:
        venv = gym.make_vec(
            config.env_id, num_envs=config.num_envs, vectorization_mode="vector_entry_point", **config.env
        )
    adapter = SB3VecEnv(venv, step_infos=False)
    env = CompiledVecNormalize(
        VecMonitor(adapter),
        norm_obs=config.normalize_observations,
        norm_reward=config.normalize_rewards,
        clip_obs=config.clip_observations,
        gamma=config.hyperparameters.get("gamma", 0.99),
    )
    env.seed(config.seed)
    return adapter, env


def obs_layout(env: Any) -> dict[str, slice]:
    """The observation layout of the task env under the SB3 wrappers ``env``."""
    while not hasattr(env, "obs_layout"):
        env = env.venv
    return env.obs_layout


def starting_policy(config: TrainConfig) -> SB3Policy:
    """The policy ``init_from`` names, checked to read and act as this run does (its observation's and
    action's meaning, :data:`MEANING_KEYS`; the estimator may differ) and to be of this run's learner."""
    from quad_wrench_env.agents import make_agent

    policy = make_agent(config.init_from)
    if not isinstance(policy, SB3Policy):
        raise ValueError(f"init_from={config.init_from!r}: not a trained policy (run folder or shipped)")
    wanted = algorithm_class(config.algorithm)
    if type(policy.model) is not wanted:
        raise ValueError(
            f"init_from={config.init_from!r} is a {type(policy.model).__name__}; this run's algorithm "
            f"{config.algorithm!r} needs a {wanted.__name__}"
        )
    env = gym.make(config.env_id, **config.env)
    try:
        policy.reset(env)
    except ValueError as error:
        raise ValueError(f"init_from={config.init_from!r}: {error}") from None
    finally:
        env.close()
    return policy


def start_from(model: BaseAlgorithm, env: VecNormalize, policy: SB3Policy) -> None:
    """``model`` and the observation statistics of ``env`` from ``policy``'s (:attr:`TrainConfig.init_from`):
    the network's weights, and the means and variances as if from its training's samples."""
    model.policy.load_state_dict(policy.model.policy.state_dict())
    if policy.scaling is not None and env.norm_obs:
        env.obs_rms.mean = policy.scaling.mean.astype(np.float64).copy()
        env.obs_rms.var = policy.scaling.var.astype(np.float64).copy()
        env.obs_rms.count = float(max(policy.model.num_timesteps, 1))


def learner_class(name: str) -> type[BaseAlgorithm]:
    """The class that trains an ``algorithm`` (a distilled student's learner; the others fly as they
    learn, :func:`~quad_wrench_env.agents.sb3_policy.algorithm_class`)."""
    return DaggerRecurrentPPO if name == "dagger" else algorithm_class(name)


def new_model(config: TrainConfig, env: Any, tensorboard_log: str | None = None) -> BaseAlgorithm:
    """The config's untrained SB3 model on ``env`` (CPU, its network, seed and hyperparameters)."""
    import torch

    activation = {"tanh": torch.nn.Tanh, "relu": torch.nn.ReLU}[config.activation]
    policy_kwargs = {"net_arch": list(config.net_arch), "activation_fn": activation}
    if config.algorithm != "sac":
        policy_kwargs["log_std_init"] = config.log_std_init
    algorithm = learner_class(config.algorithm)
    policy: str | type = POLICY_CLASSES[config.algorithm]
    if config.privileged_critic:
        from quad_wrench_env.agents.privileged import PrivilegedCriticPolicy

        hidden = obs_layout(env)["privileged"]
        policy, policy_kwargs["privileged"] = PrivilegedCriticPolicy, (hidden.start, hidden.stop)
    elif config.algorithm == "dagger":
        from quad_wrench_env.agents.privileged import WithoutColumns

        hidden = obs_layout(env)["privileged"]
        policy_kwargs["features_extractor_class"] = WithoutColumns
        policy_kwargs["features_extractor_kwargs"] = {"hidden": (hidden.start, hidden.stop)}
    hyperparameters = dict(config.hyperparameters)
    if config.learning_rate_end is not None:
        start = hyperparameters.get("learning_rate", _default(algorithm, "learning_rate"))
        hyperparameters["learning_rate"] = LinearRate(float(start), float(config.learning_rate_end))
    return algorithm(
        policy,
        env,
        seed=config.seed,
        device="cpu",
        verbose=0,
        policy_kwargs=policy_kwargs,
        tensorboard_log=tensorboard_log,
        **hyperparameters,
    )


def train(config: TrainConfig, folder: str | Path, resume: bool = False, progress: bool = True) -> Path:
    """Train per ``config`` into the run ``folder``: ``config.yaml`` and ``commit.txt`` (what ran),
    ``checkpoints/``, ``best/`` and ``final/`` (each a ``model.zip`` with its ``scaling.npz`` and
    ``vecnormalize.pkl``), ``curve.csv`` (steps, wall seconds, evaluation metric, mean training
    return) and ``tensorboard/``. ``resume`` continues from the folder's last checkpoint."""
    import torch
    from stable_baselines3.common.callbacks import BaseCallback

    import quad_wrench_env  # noqa: F401  (registers the env ids)
    from quad_wrench_env.agents.evaluate import evaluate

    folder = Path(folder)
    check_training(config, folder, resume)
    torch.set_num_threads(config.threads)
    adapter, env = training_env(config)  # the adapter's arrays are read by Loop below
    start_steps = 0
    if resume:
        last = latest_snapshot(folder)
        env = CompiledVecNormalize.load(str(last / "vecnormalize.pkl"), env.venv)
        model = learner_class(config.algorithm).load(last / "model.zip", env=env, device="cpu")
        start_steps = model.num_timesteps
    else:
        model = new_model(config, env, tensorboard_log=str(folder / "tensorboard"))
        if config.init_from is not None:
            start_from(model, env, starting_policy(config))
        folder.mkdir(parents=True, exist_ok=True)
    if config.algorithm == "dagger":
        model.start_distillation(
            Teacher(config.teacher, config.env_id, config.env), config.distillation, obs_layout(env)
        )
    (folder / "config.yaml").write_text(yaml.safe_dump(dataclasses.asdict(config), sort_keys=False))
    (folder / "commit.txt").write_text(_commit() + "\n")
    e = config.evaluation
    started = time.perf_counter()
    budget = 60.0 * config.max_minutes
    curve = folder / "curve.csv"
    if not curve.exists():
        curve.write_text("steps,wall_seconds,metric,mean_training_return\n")
    with curve.open() as handle:
        earlier = list(csv.DictReader(handle))
    wall_before = float(earlier[-1]["wall_seconds"]) if earlier else 0.0
    scored = [  # the evaluation at the first step is of the untrained policy: never a candidate
        float(r["metric"])
        for r in earlier
        if int(r["steps"]) > config.num_envs and math.isfinite(float(r["metric"]))
    ]

    def scaling() -> ObservationScaling | None:
        return ObservationScaling.of(env) if env.norm_obs else None

    def save(name: str) -> None:
        target = folder / name
        target.mkdir(parents=True, exist_ok=True)
        model.save(target / "model.zip")
        env.save(str(target / "vecnormalize.pkl"))
        (target / "scaling.npz").unlink(missing_ok=True)
        if (current := scaling()) is not None:
            current.save(target / "scaling.npz")

    class Loop(BaseCallback):
        """Logs reward terms and task entries, evaluates, checkpoints, keeps the best, keeps the budget."""

        def __init__(self) -> None:
            super().__init__()
            worst = math.inf if e.lower_is_better else -math.inf
            self.best = (min if e.lower_is_better else max)(scored, default=worst)
            """The best metric so far, the resumed run's earlier evaluations included."""
            self.trained = resume or config.init_from is not None
            """Whether the model has been trained: an untrained policy is never kept as the best."""
            self.next_eval = start_steps
            self.next_checkpoint = start_steps + config.checkpoint_every_steps
            self.sums: dict[str, float] = {}
            self.count = 0

        def _on_step(self) -> bool:
            for key, values in adapter.task_entries.items():
                self.sums[f"task/{key}_abs"] = self.sums.get(f"task/{key}_abs", 0.0) + float(
                    np.abs(values).sum()
                )
            for key, values in adapter.reward_terms.items():
                self.sums[f"reward/{key}"] = self.sums.get(f"reward/{key}", 0.0) + float(np.sum(values))
            self.count += adapter.num_envs
            if self.num_timesteps >= self.next_eval:
                self.evaluate()
            if self.num_timesteps >= self.next_checkpoint:
                save(f"checkpoints/{self.num_timesteps:010d}")
                self.next_checkpoint += config.checkpoint_every_steps
            return not (budget and time.perf_counter() - started >= budget)

        def _on_rollout_end(self) -> None:
            self.trained = True  # the update follows the rollout, before the next step
            for key, total in self.sums.items():
                self.logger.record(key, total / max(self.count, 1))
            self.sums, self.count = {}, 0

        def evaluate(self) -> None:
            self.next_eval = self.num_timesteps + e.every_steps
            policy = SB3Policy(model, scaling(), trained_on=config.env, trained_env_id=config.env_id)
            value = float(  # check_training made sure the harness scores it
                np.mean(
                    [
                        evaluate(policy, config.env_id, e.seeds, options=e.options, **settings).mean[e.metric]
                        for settings in evaluation_envs(config)
                    ]
                )
            )
            self.logger.record(f"eval/{e.metric}", value)
            returns = [info["r"] for info in model.ep_info_buffer]
            mean_return = sum(returns) / len(returns) if returns else math.nan
            wall = wall_before + time.perf_counter() - started
            with curve.open("a") as handle:
                handle.write(f"{self.num_timesteps},{wall:.1f},{value},{mean_return}\n")
            if not self.trained:
                return
            if (value < self.best) if e.lower_is_better else (value > self.best):
                self.best = value
                save("best")
                kept = {"steps": self.num_timesteps, "metric": e.metric, "value": value, "seeds": e.seeds}
                (folder / "best" / "evaluation.yaml").write_text(yaml.safe_dump(kept, sort_keys=False))

    loop = Loop()
    # SB3 collects whole rollouts (PPO: n_steps on every vehicle; SAC: one step of every vehicle), so
    # it runs to the next whole rollout past total_steps: ask for that many, and the bar ends at 100 %.
    rollout = config.num_envs * getattr(model, "n_steps", 1)
    steps = math.ceil(max(config.total_steps - start_steps, 1) / rollout) * rollout
    if config.total_steps == 0:  # init_from's model kept as it is, its observation statistics too
        steps, env.training = 0, False
    model.learn(steps, callback=loop, progress_bar=progress, reset_num_timesteps=not resume)
    loop.evaluate()
    save("final")
    env.close()
    return folder


def evaluation_envs(config: TrainConfig) -> list[dict[str, Any]]:
    """The env settings the evaluation during training scores (the mean over them is kept): the
    training env (with an entry of ``env_groups`` merged in, once per entry, or once) and
    ``evaluation.env`` replacing its keys."""
    return [{**merged(config.env, group), **config.evaluation.env} for group in config.env_groups or [{}]]


def latest_snapshot(folder: Path) -> Path:
    """The newest of the run's checkpoints and its ``final/`` model, to resume from."""
    found = [p for p in (folder / "checkpoints").glob("*") if (p / "model.zip").is_file()]
    if (folder / "final" / "model.zip").is_file():
        found.append(folder / "final")
    if not found:
        raise FileNotFoundError(f"no checkpoint or final model to resume from in {str(folder)!r}")
    return max(found, key=_saved_steps)


def _saved_steps(snapshot: Path) -> int:
    """Environment steps of a saved model (from its zip's ``data``, without loading the networks)."""
    import json
    import zipfile

    with zipfile.ZipFile(snapshot / "model.zip") as archive:
        return int(json.loads(archive.read("data"))["num_timesteps"])
