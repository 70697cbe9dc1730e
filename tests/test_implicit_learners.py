"""The implicit arms' learners (issue 48): a run started from another's model (``init_from``), and a
recurrent student distilled from a teacher on its own rollouts (``algorithm: dagger``)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch
from sb3_contrib import RecurrentPPO
from stable_baselines3 import PPO

from quad_wrench_env.agents.distill import Teacher
from quad_wrench_env.agents.evaluate import evaluate
from quad_wrench_env.agents.sb3 import (
    TrainConfig,
    TrainingConfigError,
    new_model,
    obs_layout,
    train,
    training_env,
)
from quad_wrench_env.agents.sb3_policy import load_policy
from quad_wrench_env.agents.study import StudyConfig
from quad_wrench_env.config import build, load_yaml
from tests.conftest import FAN_TRACKING
from tests.test_sb3 import HYPERPARAMETERS, SMALL

SHORT = {"episode_seconds": 6.0}
ORACLE_POLICY = "ppo_fan_tracking_oracle"
"""A shipped policy trained on the oracle's wrench: a teacher whose actions are a real controller's."""


@pytest.fixture(scope="module")
def teacher(tmp_path_factory):
    """A tiny PPO run on the oracle's wrench (the teacher and the starting model)."""
    values = {
        **SMALL,
        "env": {**SHORT, "estimator": "oracle"},
        "total_steps": 2048,
        "hyperparameters": HYPERPARAMETERS["ppo"],
    }
    return train(build(TrainConfig, values), tmp_path_factory.mktemp("teacher") / "run", progress=False)


def test_a_run_started_from_another_keeps_its_weights_and_scaling_and_flies_another_estimator(
    teacher, tmp_path
):
    """``init_from`` with ``total_steps: 0``: the kept model is the teacher's network and observation
    scaling, flown on the UKF's estimate (rapid motor adaptation's deployment), evaluated once."""
    values = {
        **SMALL,
        "init_from": str(teacher),
        "env": {**SHORT, "estimator": "ukf"},
        "total_steps": 0,
        "hyperparameters": HYPERPARAMETERS["ppo"],
    }
    folder = train(build(TrainConfig, values), tmp_path / "run", progress=False)
    source, started = load_policy(teacher), load_policy(folder)
    for name, weight in source.model.policy.state_dict().items():
        torch.testing.assert_close(started.model.policy.state_dict()[name], weight, rtol=0, atol=0)
    np.testing.assert_array_equal(started.scaling.mean, source.scaling.mean)
    np.testing.assert_array_equal(started.scaling.var, source.scaling.var)
    assert load_yaml(folder / "config.yaml")["env"]["estimator"] == "ukf"
    assert len((folder / "curve.csv").read_text().splitlines()) == 2  # the header and one evaluation


def test_a_fine_tune_moves_the_starting_weights(teacher, tmp_path):
    values = {
        **SMALL,
        "init_from": str(teacher),
        "env": {**SHORT, "estimator": "ukf"},
        "total_steps": 1024,
        "hyperparameters": HYPERPARAMETERS["ppo"],
    }
    folder = train(build(TrainConfig, values), tmp_path / "run", progress=False)
    before = load_policy(teacher).model.policy.state_dict()
    after = PPO.load(folder / "final" / "model.zip", device="cpu").policy.state_dict()
    assert any(not torch.equal(before[name], after[name]) for name in before)


@pytest.mark.parametrize(
    ("values", "message"),
    [
        (
            {"init_from": "teacher", "env": {**SHORT, "observe_wrench": False}},
            "trained with observe_wrench=True",
        ),
        ({"init_from": "teacher", "algorithm": "sac"}, "this run's algorithm 'sac' needs a SAC"),
        ({"init_from": "no-such-run"}, "unknown agent 'no-such-run'"),
    ],
)
def test_a_starting_model_that_cannot_start_the_run_is_refused_before_training(
    teacher, tmp_path, values, message
):
    values = {**SMALL, "env": SHORT, **values, "total_steps": 0}
    if values["init_from"] == "teacher":
        values["init_from"] = str(teacher)
    with pytest.raises(TrainingConfigError, match=message):
        train(build(TrainConfig, values), tmp_path / "run", progress=False)
    assert not (tmp_path / "run").exists()


def test_the_teachers_frame_is_rebuilt_from_the_truth(teacher):
    """A student env on the UKF with sensors and the truth block, and the teacher's own env (the
    oracle, no sensors), flown with the same seed and actions: the frame the teacher is handed (its
    columns of the student's observation) is the teacher env's observation: the engine's blocks and
    the last action exactly; the task's blocks, computed from the estimated state, within the UKF's
    error."""
    student_env = {
        **SHORT,
        "estimator": "ukf",
        "observe_wrench": False,
        "sensor_history": 4,
        "privileged": True,
    }
    t = Teacher(str(teacher), FAN_TRACKING, student_env)
    student, own = gym.make(FAN_TRACKING, **student_env), gym.make(FAN_TRACKING, **SHORT, estimator="oracle")
    columns = t.columns(student.unwrapped.obs_layout)
    first, second = student.reset(seed=5)[0], own.reset(seed=5)[0]
    rng = np.random.default_rng(0)
    engine = own.unwrapped.obs_layout["last_action"].stop
    for _ in range(20):
        np.testing.assert_allclose(first[columns][:engine], second[:engine], rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(first[columns][engine:], second[engine:], atol=0.05)
        action = rng.uniform(-0.5, 0.5, 4).astype(np.float32)
        first, second = student.step(action)[0], own.step(action)[0]
    student.close()
    own.close()


def test_a_distilled_student_fits_the_teachers_labels_and_never_reads_the_truth():
    """Eight DAgger iterations of a student that reads the sensors, never the wrench or the truth: the
    imitation loss of the last iteration is below half the first's, and on its last rollout the
    student's actions (flown step by step from the LSTM state it had, as it flies) are within a third
    of the labels' mean square; changing the truth block leaves its actions as they are. (Whether a
    student generalises to new episodes is the study's question, on its budget, not this one's.)"""
    values = {
        **SMALL,
        "algorithm": "dagger",
        "teacher": ORACLE_POLICY,
        "env": {**SHORT, "action_type": "velocity", "observe_wrench": False, "sensor_history": 4},
        "total_steps": 4096,
        "hyperparameters": {"n_steps": 128, "learning_rate": 3e-3},
        "distillation": {"epochs": 8, "batch": 4},
    }
    config = build(TrainConfig, values)
    assert config.env["privileged"] is True
    _, env = training_env(config)
    model = new_model(config, env)
    teacher = Teacher(ORACLE_POLICY, FAN_TRACKING, config.env)
    model.start_distillation(teacher, config.distillation, obs_layout(env))
    model.learn(4096)
    losses = model.imitation_losses
    assert len(losses) == 8 and losses[-1] < 0.5 * losses[0], losses
    part = model._kept[-1]
    state = (part["hidden"][None], part["cell"][None])
    actions = []
    with torch.no_grad():
        for k in range(part["labels"].shape[1]):
            observation, start = part["observations"][:, k], part["starts"][:, k]
            distribution, state = model.policy.get_distribution(observation, state, start)
            actions.append(distribution.distribution.mean)
        blind = observation.clone()
        blind[:, obs_layout(env)["privileged"]] += 3.0
        again = [
            model.policy.get_distribution(o, state, start)[0].distribution.mean for o in (observation, blind)
        ]
    labels = part["labels"]
    error = torch.mean((torch.stack(actions, 1) - labels) ** 2)
    assert error < torch.mean(labels**2) / 3.0, (error, torch.mean(labels**2))
    torch.testing.assert_close(again[0], again[1], rtol=0, atol=0)
    env.close()


def test_a_distilled_run_is_saved_as_a_recurrent_policy_and_flies_by_folder(tmp_path):
    values = {
        **SMALL,
        "algorithm": "dagger",
        "teacher": ORACLE_POLICY,
        "env": {**SHORT, "action_type": "velocity", "observe_wrench": False, "sensor_history": 4},
        "total_steps": 1024,
        "hyperparameters": {"n_steps": 128},
    }
    folder = train(build(TrainConfig, values), tmp_path / "run", progress=False)
    student = load_policy(folder)
    assert type(student.model) is RecurrentPPO
    result = evaluate(student, FAN_TRACKING, [7], **{**values["env"], "privileged": True})
    assert np.isfinite(result.per_seed[0]["mean_abs_error_after_5s"])


@pytest.mark.parametrize(
    ("values", "message"),
    [
        ({"algorithm": "dagger"}, "distillation needs a teacher"),
        ({"teacher": "ppo_fan_tracking"}, "a teacher needs distillation"),
        ({"algorithm": "dagger", "teacher": "x", "env": {"privileged": False}}, "needs env.privileged true"),
        ({"distillation": {"teacher_decay": 1.5}}, "distillation.teacher_decay=1.5"),
        ({"distillation": {"epochs": 0}}, "distillation.epochs=0"),
        ({"total_steps": 0}, "0 only with init_from"),
    ],
)
def test_a_distillation_without_a_teacher_and_other_bad_learners_are_refused_by_name(values, message):
    with pytest.raises(ValueError, match=message):
        build(TrainConfig, values)


def test_a_study_arm_may_start_from_or_learn_from_another_arm_of_the_same_seed(tmp_path):
    """``"@<arm>"``: resolved to that arm's run of the same seed; an unknown arm, or one that itself
    starts from another, is refused by name."""
    arms = {
        "oracle": {"env.estimator": "oracle"},
        "adapted": {"init_from": "@oracle", "env.estimator": "ukf", "total_steps": 0},
        "student": {"algorithm": "dagger", "teacher": "@oracle", "env.observe_wrench": False},
    }
    comparison = {"env_id": FAN_TRACKING, "seeds": [5000], "cases": {"c": {}}}
    config = build(StudyConfig, {"base": {}, "arms": arms, "seeds": [0, 1], "comparison": comparison})
    assert config.sources("adapted") == {"init_from": "oracle"} and config.sources("oracle") == {}
    run = config.run_config("student", 1, tmp_path)
    assert run.teacher == str(tmp_path / "runs" / "oracle-seed1")
    for bad in ({**arms, "adapted": {"init_from": "@nobody"}}, {**arms, "again": {"teacher": "@adapted"}}):
        with pytest.raises(ValueError, match="allowed: an arm of this study that starts from no other arm"):
            build(StudyConfig, {"base": {}, "arms": bad, "seeds": [0], "comparison": comparison})
