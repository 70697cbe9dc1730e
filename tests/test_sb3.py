"""The training pipeline end to end, learned policies as agents, and what SB3VecEnv forwards."""

from __future__ import annotations

import csv
import math
from functools import partial

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3 import PPO

from quad_wrench_cli.train import summary
from quad_wrench_env.agents import SHIPPED, make_agent, shipped_agents
from quad_wrench_env.agents.evaluate import evaluate
from quad_wrench_env.agents.sb3 import SB3Policy, TrainConfig, TrainingConfigError, train
from quad_wrench_env.agents.sb3_policy import load_policy
from quad_wrench_env.config import build, load_yaml
from quad_wrench_env.envs.sb3_vec_env import SB3VecEnv
from tests.conftest import FAN_TRACKING

SMALL = {
    "env": {"episode_seconds": 6.0, "observe_wrench": False},  # not the default: checked on reload
    "num_envs": 4,
    "checkpoint_every_steps": 1024,
    "evaluation": {
        "seeds": [1],
        "every_steps": 1024,
        "metric": "mean_abs_error_after_5s",
        "lower_is_better": True,
    },
}
HYPERPARAMETERS = {
    "ppo": {"n_steps": 256, "batch_size": 256, "n_epochs": 2},
    "sac": {
        "learning_starts": 256,
        "buffer_size": 4096,
        "batch_size": 64,
        "train_freq": 1,
        "gradient_steps": 1,
    },
}


def _curve(folder) -> list[dict[str, str]]:
    with (folder / "curve.csv").open() as handle:
        return list(csv.DictReader(handle))


@pytest.mark.parametrize("algorithm", ["ppo", "sac"])
def test_config_to_run_folder_to_reloaded_agent_to_evaluation(tmp_path, algorithm):
    config = build(
        TrainConfig,
        {**SMALL, "algorithm": algorithm, "total_steps": 2048, "hyperparameters": HYPERPARAMETERS[algorithm]},
    )
    folder = train(config, tmp_path / "run", progress=False)
    assert load_yaml(folder / "config.yaml")["algorithm"] == algorithm  # the config it ran with
    assert (folder / "commit.txt").read_text().strip()
    for part in ("final/model.zip", "final/scaling.npz", "final/vecnormalize.pkl", "best/model.zip"):
        assert (folder / part).is_file(), part
    assert any((folder / "tensorboard").iterdir())
    rows = _curve(folder)
    assert int(rows[-1]["steps"]) >= 2048 and all(math.isfinite(float(r["metric"])) for r in rows)
    policy = make_agent(str(folder))
    assert isinstance(policy, SB3Policy) and policy.scaling is not None
    result = evaluate(policy, FAN_TRACKING, [5], episode_seconds=6.0, observe_wrench=False)
    assert math.isfinite(result.per_seed[0]["mean_abs_error_after_5s"])
    trained = [float(r["metric"]) for r in rows if int(r["steps"]) > config.num_envs]
    best = min(trained)  # the kept model is the best trained one on the eval seeds
    again = evaluate(load_policy(folder), FAN_TRACKING, [1], episode_seconds=6.0, observe_wrench=False)
    assert again.per_seed[0]["mean_abs_error_after_5s"] == pytest.approx(best, rel=1e-6)


def test_a_run_resumes_from_its_newest_model_and_keeps_its_best(tmp_path):
    values = {**SMALL, "total_steps": 1024, "hyperparameters": HYPERPARAMETERS["ppo"]}
    folder = train(build(TrainConfig, values), tmp_path / "run", progress=False)
    with pytest.raises(TrainingConfigError, match="not empty"):
        train(build(TrainConfig, values), folder, progress=False)
    before = _curve(folder)
    best_before = min(float(r["metric"]) for r in before if int(r["steps"]) > 4)
    train(build(TrainConfig, {**values, "total_steps": 2048}), folder, resume=True, progress=False)
    assert PPO.load(folder / "final" / "model.zip").num_timesteps >= 2048
    rows = _curve(folder)
    steps = [int(r["steps"]) for r in rows]
    walls = [float(r["wall_seconds"]) for r in rows]
    assert steps == sorted(steps) and steps[-1] >= 2048 and walls == sorted(walls)
    after = [float(r["metric"]) for r in rows[len(before) :]]
    kept = evaluate(
        load_policy(folder), FAN_TRACKING, [1], episode_seconds=6.0, observe_wrench=False
    ).per_seed[0]
    assert kept["mean_abs_error_after_5s"] == pytest.approx(min([best_before, *after]), rel=1e-6)


def test_an_untrained_policy_is_never_kept_and_unnormalised_runs_work(tmp_path):
    values = {
        **SMALL,
        "total_steps": 4,
        "normalize_observations": False,
        "hyperparameters": HYPERPARAMETERS["ppo"],
    }
    folder = train(build(TrainConfig, values), tmp_path / "run", progress=False)
    first = _curve(folder)[0]
    assert int(first["steps"]) == 4  # the evaluation of the untrained policy, at the first step ...
    best = PPO.load(folder / "best" / "model.zip")
    assert best.num_timesteps > 4  # ... is never the kept one, even where it scored best
    kept = load_yaml(folder / "best" / "evaluation.yaml")  # what the summary names: the kept model
    assert kept["steps"] == best.num_timesteps
    assert f"kept best/: mean_abs_error_after_5s {kept['value']:.4g} at {kept['steps']} steps" in summary(
        folder, 1.0
    )
    policy = load_policy(folder)
    assert policy.scaling is None and not (folder / "best" / "scaling.npz").exists()


def test_learning_rate_end_lowers_the_optimisers_rate_linearly_over_the_run(tmp_path):
    """With ``learning_rate_end`` the optimiser's rate follows the line from the start rate to the end
    rate over the run's progress (SB3 sets it before each update from the steps taken so far: the last
    update, after the last rollout, runs at the end rate)."""
    start, end, total = 1e-3, 1e-5, 2048
    hyperparameters = {**HYPERPARAMETERS["ppo"], "learning_rate": start}
    values = {**SMALL, "total_steps": total, "hyperparameters": hyperparameters, "learning_rate_end": end}
    folder = train(build(TrainConfig, values), tmp_path / "run", progress=False)
    model = PPO.load(folder / "final" / "model.zip")
    assert model.policy.optimizer.param_groups[0]["lr"] == pytest.approx(end, rel=1e-9)
    assert model.lr_schedule(0.25) == pytest.approx(start + 0.75 * (end - start), rel=1e-9)
    folder = train(build(TrainConfig, {**values, "learning_rate_end": None}), tmp_path / "c", progress=False)
    constant = PPO.load(folder / "final" / "model.zip")
    assert constant.policy.optimizer.param_groups[0]["lr"] == start
    with pytest.raises(ValueError, match="learning_rate_end=-1"):
        build(TrainConfig, {"learning_rate_end": -1.0})
    with pytest.raises(ValueError, match="learning_rate=True is not one"):
        build(TrainConfig, {"learning_rate_end": 0.0, "hyperparameters": {"learning_rate": True}})
    for change in ({"learning_rate_end": 1e-4}, {"total_steps": 2 * total}):  # the saved model keeps its line
        with pytest.raises(TrainingConfigError, match="would change its learning-rate schedule"):
            train(build(TrainConfig, {**values, **change}), tmp_path / "run", resume=True, progress=False)


def test_bad_training_config_names_the_key():
    with pytest.raises(ValueError, match="algorithm='a2c'"):
        build(TrainConfig, {"algorithm": "a2c"})
    with pytest.raises(ValueError, match="num_envs=0"):
        build(TrainConfig, {"num_envs": 0})
    with pytest.raises(ValueError, match="every_steps='1e5'"):
        build(TrainConfig, {"evaluation": {"every_steps": "1e5"}})
    with pytest.raises(ValueError, match="lower_is_better='yes'"):
        build(TrainConfig, {"evaluation": {"lower_is_better": "yes"}})


@pytest.mark.parametrize("name", shipped_agents())
def test_shipped_agents_load_and_act_on_their_env(name):
    policy = make_agent(name)
    config = load_yaml(SHIPPED / name / "config.yaml")
    env = gym.make(config["env_id"], **config["env"])
    try:
        obs, _ = env.reset(seed=0)
        policy.reset(env)
        for _ in range(5):
            action = policy.act(obs)
            assert action.shape == (4,) and np.all(np.abs(action) <= 1.0)
            obs, *_ = env.step(action)
    finally:
        env.close()
    with pytest.raises(ValueError, match="takes no parameters"):
        make_agent(name, k_p=1.0)


def test_a_policy_refuses_an_env_whose_actions_or_observations_mean_otherwise(make_env):
    """Same shapes, other meanings: a policy trained without the wrench (or on the velocity action)
    is refused on an env with the wrench (or the attitude action), naming the setting to use."""
    policy = make_agent("ppo_fan_tracking_no_wrench")
    policy.reset(make_env(observe_wrench=False))
    with pytest.raises(ValueError, match="observe_wrench=False, the env has observe_wrench=True"):
        policy.reset(make_env())
    with pytest.raises(ValueError, match="trained with action_type='velocity'"):
        policy.reset(make_env(observe_wrench=False, action_type="attitude"))


def test_a_policy_trained_on_the_tracking_error_refuses_the_reference(make_env):
    """DisturbanceRejection's ``observe_tracking_error`` changes what its last six columns mean, and
    ``action_limits`` what an action commands: a policy trained with either is refused on an env
    without it (same shapes), and a key that another task's config lacks is not asked of it."""
    rejection = "QuadWrench/DisturbanceRejection-v0"
    trained = {"action_type": "velocity", "observe_tracking_error": True}
    env = make_env(rejection, **trained)
    policy = SB3Policy(PPO("MlpPolicy", env, n_steps=64, device="cpu"), trained_on=trained)
    policy.reset(env)
    assert policy.env_settings() == trained
    with pytest.raises(
        ValueError, match="observe_tracking_error=True, the env has observe_tracking_error=False"
    ):
        policy.reset(make_env(rejection, action_type="velocity"))
    limits = {"max_speed_xy": 2.0, "max_speed_z": 2.0}  # what an action in [-1, 1] commands, m/s
    faster = SB3Policy(policy.model, trained_on={**trained, "action_limits": limits})
    faster.reset(make_env(rejection, **trained, action_limits=limits))
    assert faster.env_settings() == {**trained, "action_limits": limits}
    with pytest.raises(ValueError, match="the env has action_limits=.*make the env with action_limits="):
        faster.reset(env)
    fan = make_env(observe_wrench=False)
    SB3Policy(PPO("MlpPolicy", fan, n_steps=64, device="cpu"), trained_on={"observe_wrench": False}).reset(
        fan
    )


def test_ppo_fan_tracking_is_shipped():
    assert "ppo_fan_tracking" in shipped_agents()


def test_unknown_agent_lists_what_is_allowed():
    with pytest.raises(ValueError, match="unknown agent 'nope'.*admittance"):
        make_agent("nope")


def test_a_bare_sb3_model_is_evaluated_like_any_agent():
    env = gym.make(FAN_TRACKING)
    model = PPO("MlpPolicy", env, n_steps=64, device="cpu")
    env.close()
    result = evaluate(model, FAN_TRACKING, [0], episode_seconds=1.0)
    assert result.per_seed[0]["episode_seconds"] > 0


def _lockstep(step_infos: bool):
    """An ``SB3VecEnv`` and the raw vector env of the same seeds, stepped alike (zero actions) across
    an episode end: (SB3's step, the raw step) per step."""
    make = partial(
        gym.make_vec, FAN_TRACKING, num_envs=3, vectorization_mode="vector_entry_point", episode_seconds=0.1
    )
    env, raw = SB3VecEnv(make(), step_infos=step_infos), make()
    try:
        env.seed(0)
        env.reset()
        raw.reset(seed=0)
        for _ in range(6):  # an episode is 5 steps: the fifth ends all three and restarts them
            yield env, env.step(np.zeros((3, 4))), raw.step(np.zeros((3, 4)))
    finally:
        env.close()
        raw.close()


def test_sb3_vec_env_forwards_reward_terms_and_task_entries_every_step():
    """Each ``infos[i]`` holds the step's reward terms and the task's numbers (an ended episode's own
    numbers, from the vector env's ``final_info``), and SB3's terminal observation and time-out flag."""
    for _, (obs, rewards, dones, infos), (raw_obs, raw_rewards, terminated, truncated, info) in _lockstep(
        True
    ):
        np.testing.assert_array_equal(obs, raw_obs)
        np.testing.assert_allclose(rewards, raw_rewards, rtol=1e-6)
        np.testing.assert_array_equal(dones, terminated | truncated)
        source = info["final_info"] if dones.any() else info
        for i, entry in enumerate(infos):
            assert sum(entry["reward_terms"].values()) == pytest.approx(rewards[i], rel=1e-6)
            assert set(entry["reward_terms"]) == {"tracking", "standoff", "effort", "crash"}
            assert entry["axis_error"] == source["axis_error"][i]
            if dones[i]:
                np.testing.assert_array_equal(entry["terminal_observation"], info["final_obs"][i])
                assert entry["TimeLimit.truncated"] == (truncated[i] and not terminated[i])


def test_sb3_vec_env_without_step_infos_keeps_the_numbers_as_arrays():
    """``step_infos=False`` (training): ``infos[i]`` holds only what SB3 reads, the same numbers are
    arrays over vehicles."""
    for env, (_, rewards, dones, infos), (_, _, _, _, info) in _lockstep(False):
        source = info["final_info"] if dones.any() else info
        np.testing.assert_allclose(sum(env.reward_terms.values()), rewards, rtol=1e-6)
        np.testing.assert_array_equal(env.task_entries["axis_error"], source["axis_error"])
        for i, entry in enumerate(infos):
            assert set(entry) == ({"terminal_observation", "TimeLimit.truncated"} if dones[i] else set())


def test_the_train_command_refuses_an_unknown_key_with_exit_code_2():
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    command = [sys.executable, "-m", "quad_wrench_env", "train", "configs/train_fan_tracking.yaml", "--set"]
    done = subprocess.run([*command, "nonsense=1"], cwd=root, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert "'nonsense'" in done.stderr


def test_a_lone_evaluation_flies_a_shipped_policy_in_its_training_world(capsys):
    """ppo_disturbance_rejection was trained with the jet from either side and the figure-8 wind from
    any heading: `quad-wrench evaluate` of it on its env flies that world unless told otherwise (a
    section given is merged key by key) and prints it; a comparison (no env id) and another env keep
    their own world."""
    import gymnasium as gym

    from quad_wrench_cli.main import main
    from quad_wrench_env.agents import make_agent
    from quad_wrench_env.agents.evaluate import flying_settings

    policy = make_agent("ppo_disturbance_rejection")
    env_id = "QuadWrench/DisturbanceRejection-v0"
    world = {"jet_crossing": {"jet_sides": ["-y", "+y"]}, "figure8": {"wind_heading_spread": math.pi}}
    alone = flying_settings(policy, {}, env_id)
    assert {key: alone[key] for key in world} == world
    assert alone["estimator"] == "ekf" and alone["observe_tracking_error"] is True
    speeds = flying_settings(policy, {"jet_crossing": {"jet_speeds": [5.0]}}, f"quad_wrench_env:{env_id}")
    assert speeds["jet_crossing"] == {"jet_sides": ["-y", "+y"], "jet_speeds": [5.0]}
    assert flying_settings(policy, {"jet_crossing": {"jet_sides": ["+y"]}}, env_id)["jet_crossing"] == {
        "jet_sides": ["+y"]
    }
    for compared in (flying_settings(policy, {}), flying_settings(policy, {}, "QuadWrench/FanTracking-v1")):
        assert not set(world) & set(compared)
    env = gym.make(env_id, **alone)
    try:
        assert env.unwrapped.cfg.jet_crossing.jet_sides == ("-y", "+y")
        assert env.unwrapped.cfg.figure8.wind_heading_spread == pytest.approx(math.pi)
    finally:
        env.close()
    args = ["evaluate", "ppo_disturbance_rejection", env_id, "--seeds", "3", "--no-progress"]
    assert main([*args, "--env", "episode_seconds=0.1"]) == 0
    assert "'jet_sides': ['-y', '+y']" in capsys.readouterr().out


def test_a_shipped_policy_flies_with_its_training_envs_meaning_unless_told_otherwise():
    """ppo_fan_tracking_no_wrench was trained with observe_wrench=false, the velocity action and the UKF
    with fixed walks: by name it flies so with no settings given (its estimator's settings too, where it
    flies with that estimator; another estimator flies with its own defaults, and settings given win,
    key by key);
    a contradicting meaning is refused by name."""
    from quad_wrench_env.agents import make_agent
    from quad_wrench_env.agents.evaluate import evaluate, flying_settings

    policy = make_agent("ppo_fan_tracking_no_wrench")
    meaning = {"observe_wrench": False, "action_type": "velocity"}
    fixed = {"estimator": "ukf", "estimator_params": {"adaptive_walks": False}}
    assert flying_settings(policy, {"vehicle": "ardrone2"}) == {**meaning, **fixed, "vehicle": "ardrone2"}
    assert flying_settings(policy, {"estimator": "ukf"}) == {**meaning, **fixed}
    assert flying_settings(policy, {"estimator": "oracle"}) == {**meaning, "estimator": "oracle"}
    given = {"estimator_params": {"force_walk": 0.01}}  # merged into the trained settings, key by key
    merged = {"estimator_params": {"adaptive_walks": False, "force_walk": 0.01}}
    assert flying_settings(policy, given) == {**meaning, **fixed, **merged}
    result = evaluate(policy, "QuadWrench/FanTracking-v1", [3], episode_seconds=0.2)
    assert result.per_seed[0]["episode_seconds"] == pytest.approx(0.2)
    refused = "trained with observe_wrench=False, the env has observe_wrench=True"
    with pytest.raises(ValueError, match=refused):
        evaluate(policy, "QuadWrench/FanTracking-v1", [3], episode_seconds=0.2, observe_wrench=True)
