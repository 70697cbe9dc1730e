"""``quad-wrench study``: arms x training seeds trained on a local Ray, every run and the classical
agents scored on the same held-out seeds, the table with the spread across training seeds, and a second
call that continues the study instead of starting it again."""

from __future__ import annotations

import csv

import pytest

from quad_wrench_env.agents import make_agent
from quad_wrench_env.agents.evaluate import evaluate
from quad_wrench_env.agents.sb3 import TrainingConfigError
from quad_wrench_env.agents.study import (
    StudyConfig,
    _priority,
    evaluate_all,
    figure,
    status,
    study,
    train_all,
)
from quad_wrench_env.config import build, load_yaml
from tests.conftest import FAN_TRACKING

pytest.importorskip("ray")

BASE = {
    "env_id": FAN_TRACKING,
    "env": {"episode_seconds": 2.0},
    "num_envs": 2,
    "total_steps": 64,
    "checkpoint_every_steps": 1024,
    "hyperparameters": {"n_steps": 32, "batch_size": 64, "n_epochs": 1},
    "evaluation": {"seeds": [900], "every_steps": 10000, "metric": "return"},
}
COMPARISON = {
    "env_id": FAN_TRACKING,
    "seeds": [2000, 2001],
    "agents": {"admittance (oracle)": {"agent": "admittance", "env": {"estimator": "oracle"}}},
    "cases": {"static": {"options": {"fan_motion": "static"}, "env": {"episode_seconds": 6.0}}},
}


def _config(**changes) -> StudyConfig:
    values = {
        "base": BASE,
        "arms": {"no wrench": {"env.observe_wrench": False}, "ukf, history 2": {"env.history": 2}},
        "seeds": [0, 1],
        "comparison": COMPARISON,
        **changes,
    }
    return build(StudyConfig, values)


def test_a_study_trains_every_arm_and_seed_scores_them_beside_the_classical_agent_and_continues(tmp_path):
    config = _config()
    rows = study(config, tmp_path)
    runs = sorted(p.name for p in (tmp_path / "runs").iterdir())
    assert runs == ["no-wrench-seed0", "no-wrench-seed1", "ukf-history-2-seed0", "ukf-history-2-seed1"]
    assert all(status(tmp_path / "runs" / run) == "done" for run in runs)
    arm = next(r for r in rows if r["agent"] == "ukf, history 2" and r["metric"] == "mean_abs_error_after_5s")
    assert arm["n"] == 2 and arm["kind"] == "arm"  # across the two training seeds
    per_run = [float(v) for v in arm["values"].split(";")]  # each run's mean, training seeds 0 and 1
    assert len(per_run) == 2 and sum(per_run) / 2 == pytest.approx(arm["mean"], rel=1e-5)
    classical = next(r for r in rows if r["agent"] == "admittance (oracle)")
    assert classical["n"] == 2 and classical["kind"] == "classical"  # across the two held-out seeds
    table = (tmp_path / "results.md").read_text()
    assert "| ukf, history 2 | static |" in table and "| admittance (oracle) | static |" in table
    with (tmp_path / "results.csv").open() as handle:
        assert len(list(csv.DictReader(handle))) == len(rows)
    assert train_all(config, tmp_path) == []  # a second call trains nothing: every run is done
    # the agents, evaluated in parallel Ray tasks, come back in the config's order with the numbers of
    # one agent flown on its own: the run with its training env (history 2) under the case's
    results = evaluate_all(config, tmp_path)
    agents = ["admittance (oracle)"] + [f"{arm} seed {k}" for arm in config.arms for k in (0, 1)]
    assert list(results) == [(agent, "static") for agent in agents]
    alone = evaluate(
        make_agent(str(tmp_path / "runs" / "ukf-history-2-seed1")),
        FAN_TRACKING,
        [2000, 2001],
        options={"fan_motion": "static"},
        episode_seconds=6.0,
        history=2,
    )
    assert results["ukf, history 2 seed 1", "static"].per_seed == alone.per_seed
    assert per_run[1] == pytest.approx(alone.mean["mean_abs_error_after_5s"], rel=1e-5)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"arms": {}}, "at least one arm"),
        ({"seeds": [0, 0]}, "distinct"),
        ({"comparison": {**COMPARISON, "seeds": [1]}}, r"comparison seeds \[1\] were trained on"),
        ({"comparison": {**COMPARISON, "seeds": [900]}}, r"comparison seeds \[900\]"),
        # vehicle i of a run trains on seed + i: the second vehicle of seed 10, and of an arm's wider run
        ({"seeds": [0, 10], "comparison": {**COMPARISON, "seeds": [11]}}, r"comparison seeds \[11\] were"),
        (
            {
                "arms": {"wide": {"num_envs": 4}},
                "seeds": [0, 10],
                "comparison": {**COMPARISON, "seeds": [13]},
            },
            r"comparison seeds \[13\] were",
        ),
        # selection seeds after an arm's own override
        (
            {"arms": {"plain": {}, "own": {"evaluation.seeds": [2001]}}, "comparison": COMPARISON},
            r"comparison seeds \[2001\] were",
        ),
        ({"arms": {"a b": {}, "a-b": {}}}, "the same folder name"),
        ({"common": {"env_processes": 2}}, r"env_processes=2 is more than cpus_per_run=1.0"),
        ({"common": [1]}, "common=.* must be a mapping"),
    ],
)
def test_a_bad_study_is_refused_by_name(changes, message):
    with pytest.raises(ValueError, match=message):
        _config(**changes)


def test_common_overrides_reach_every_arm_and_an_arm_overrides_them():
    config = _config(common={"total_steps": 96, "env.history": 3})
    assert config.run_config("no wrench", 1).total_steps == 96
    assert config.run_config("no wrench", 1).env["history"] == 3
    assert config.run_config("ukf, history 2", 0).env["history"] == 2


def test_a_run_meets_the_comparisons_world_with_its_estimator_and_its_arms_own_settings():
    """The base's training world (a short episode, a curriculum, a drawn heading) stays behind: in the
    comparison every agent meets the same episodes; the estimator trained on and the arm's (and
    ``common``'s) env overrides come along."""
    base = {
        **BASE,
        "env": {
            "episode_seconds": 2.0,
            "estimator": "ekf",
            "estimator_params": "paper",
            "fan": {"speed": 3.0},
        },
    }
    arms = {"oracle": {"env.estimator": "oracle"}, "ekf": {}}
    config = _config(base=base, common={"env.history": 3}, arms=arms)
    assert config.flying_env("ekf", 0) == {"estimator": "ekf", "estimator_params": "paper", "history": 3}
    assert config.flying_env("oracle", 1) == {
        "estimator": "oracle",
        "estimator_params": "paper",
        "history": 3,
    }
    sized = _config(base={**BASE, "env": {"fan_walks": True}}, arms={"ukf": {}})
    assert sized.flying_env("ukf", 0) == {"fan_walks": True}  # FanTracking's walks sized as trained


def test_an_arm_whose_env_the_task_refuses_stops_the_study_before_any_run(tmp_path):
    config = _config(arms={"bad": {"env.estimator": "kalman"}})
    with pytest.raises(TrainingConfigError, match=r"arms\['bad'\]: unknown estimator 'kalman'"):
        study(config, tmp_path)
    assert not (tmp_path / "runs").exists()


def test_a_learning_rate_sweep_trains_the_first_seed_at_each_rate_and_the_others_at_the_best(tmp_path):
    """The first seed at every rate, the later seeds at the rate whose kept model scored best on the
    run's own selection seeds (the return here: higher is better), the winner the first seed's run."""
    config = _config(arms={"ukf": {}}, learning_rates=[1e-3, 3e-4])
    lines = train_all(config, tmp_path)
    assert sorted(lines) == [
        "trained ukf, seed 0, learning rate 0.0003",
        "trained ukf, seed 0, learning rate 0.001",
        "trained ukf, seed 1",
    ]
    runs = tmp_path / "runs"
    assert sorted(p.name for p in runs.iterdir()) == ["ukf-lr0.0003-seed0", "ukf-lr0.001-seed0", "ukf-seed1"]
    scores = {
        rate: load_yaml(runs / f"ukf-lr{rate:g}-seed0" / "best" / "evaluation.yaml")["value"]
        for rate in (1e-3, 3e-4)
    }
    best = max(scores, key=scores.get)
    assert config.chosen_rate(tmp_path, "ukf") == best
    assert load_yaml(runs / "ukf-seed1" / "config.yaml")["hyperparameters"]["learning_rate"] == best
    assert config.run_path(tmp_path, "ukf", 0) == runs / f"ukf-lr{best:g}-seed0"
    assert train_all(config, tmp_path) == []


def _finished_run(path, value) -> None:
    (path / "final").mkdir(parents=True)
    (path / "final" / "model.zip").write_bytes(b"")
    (path / "best").mkdir()
    (path / "best" / "evaluation.yaml").write_text(f"value: {value}\n")


def test_the_sweep_chooses_by_the_selection_metrics_direction_never_a_nan_and_waits_for_every_rate(tmp_path):
    lower = {
        "evaluation": {**BASE["evaluation"], "metric": "mean_abs_error_after_5s", "lower_is_better": True}
    }
    config = _config(base={**BASE, **lower}, arms={"ukf": {}}, learning_rates=[1e-3, 3e-4, 1e-4])
    _finished_run(config.sweep_folder(tmp_path, "ukf", 1e-3), 0.5)
    _finished_run(config.sweep_folder(tmp_path, "ukf", 3e-4), ".nan")
    assert config.chosen_rate(tmp_path, "ukf") is None  # 1e-4 not done yet
    assert config.job(tmp_path, "ukf", 1, None) is None  # the second seed waits on it
    with pytest.raises(FileNotFoundError, match="its learning-rate sweep .* is not done"):
        config.run_path(tmp_path, "ukf", 0)
    _finished_run(config.sweep_folder(tmp_path, "ukf", 1e-4), 0.7)
    assert config.chosen_rate(tmp_path, "ukf") == 1e-3
    path, run = config.job(tmp_path, "ukf", 1, None)
    assert path == tmp_path / "runs" / "ukf-seed1" and run.hyperparameters["learning_rate"] == 1e-3


def test_an_arm_that_starts_from_a_swept_arm_starts_from_its_chosen_run_and_is_not_swept_at_zero_steps(
    tmp_path,
):
    arms = {"oracle": {"env.estimator": "oracle"}, "as shipped": {"init_from": "@oracle", "total_steps": 0}}
    config = _config(arms=arms, learning_rates=[1e-3, 3e-4])
    assert config.swept("oracle") and not config.swept("as shipped")
    sweep = [("oracle", 0, 1e-3), ("oracle", 0, 3e-4)]
    assert config.runs() == [*sweep, ("oracle", 1, None), ("as shipped", 0, None), ("as shipped", 1, None)]
    assert config.job(tmp_path, "as shipped", 0, None) is None  # the oracle's sweep is not done
    _finished_run(config.sweep_folder(tmp_path, "oracle", 1e-3), 10.0)
    _finished_run(config.sweep_folder(tmp_path, "oracle", 3e-4), 20.0)  # the return: higher is better
    run = config.job(tmp_path, "as shipped", 0, None)[1]
    assert run.init_from == str(tmp_path / "runs" / "oracle-lr0.0003-seed0")
    assert config.job(tmp_path, "as shipped", 1, None) is None  # the oracle's seed 1 is not trained


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"learning_rates": [1e-3, 1e-3]}, r"learning_rates=\[0.001, 0.001\] must be a list of distinct"),
        ({"learning_rates": [0.0]}, "numbers > 0"),
        ({"learning_rates": "1e-3"}, "must be a list"),
        (
            {"learning_rates": [1e-3], "arms": {"a": {"hyperparameters.learning_rate": 1e-4}}},
            r"arms\['a'\] sets hyperparameters.learning_rate beside learning_rates=\[0.001\]",
        ),
    ],
)
def test_a_bad_sweep_is_refused_by_name(changes, message):
    with pytest.raises(ValueError, match=message):
        _config(**changes)


@pytest.mark.parametrize(
    ("arm", "message"),
    [
        (
            {"algorithm": "sac", "privileged_critic": True},
            r"arms\['bad'\]: privileged_critic=true with algorithm='sac'",
        ),
        (
            {"algorithm": "dagger"},
            r"arms\['bad'\]: algorithm='dagger' with teacher=None: distillation needs a teacher",
        ),
        ({"env.privileged": True}, r"arms\['bad'\]: env.privileged=true without privileged_critic"),
    ],
)
def test_an_arm_whose_learner_cannot_do_what_it_asks_is_refused_before_any_run(tmp_path, arm, message):
    with pytest.raises(ValueError, match=message):
        study(_config(arms={"good": {}, "bad": arm}), tmp_path)
    assert not (tmp_path / "runs").exists()


def test_a_slow_learners_run_starts_first_then_an_arm_another_waits_on():
    arms = {
        "plain": {},
        "oracle": {"env.estimator": "oracle"},
        "lstm": {"algorithm": "recurrent_ppo"},
        "shipped as is": {"init_from": "@oracle", "total_steps": 0},
    }
    config = _config(arms=arms)
    order = sorted(arms, key=lambda label: _priority(config, label))
    assert order == ["lstm", "oracle", "plain", "shipped as is"]


def test_the_figure_gives_every_agent_its_own_colour_and_keeps_the_legend_off_the_bars():
    """Past ten agents tab10's colours repeat: with twelve every agent must still have its own, and
    the legend (twelve entries) must sit beside the axes, not on the bars."""
    agents = [f"agent {k}" for k in range(12)]
    rows = [
        {"agent": a, "case": c, "metric": "max_horizontal_deviation", "mean": 0.01 * (k + 1), "sd": 0.001}
        for k, a in enumerate(agents)
        for c in ("jet", "gusts")
    ]
    fig = figure(rows, "QuadWrench/DisturbanceRejection-v0")
    ax = fig.axes[0]
    bars = [c for c in ax.containers if hasattr(c, "patches")]
    colours = {tuple(bar.patches[0].get_facecolor()) for bar in bars}
    assert len(bars) == 12 and len(colours) == 12
    fig.canvas.draw()
    legend = ax.get_legend().get_window_extent()
    assert legend.x0 >= ax.get_window_extent().x1
