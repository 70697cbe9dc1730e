"""Sweeps on Ray Tune: a 2-trial grid on a local Ray (needs the ``tune`` extra), and the sweep
config's checks (without Ray)."""

from __future__ import annotations

import csv
import math
import sys

import pytest

from quad_wrench_env.agents.sb3 import TrainConfig
from quad_wrench_env.agents.sweep import SweepConfig, load_sweep_config, sweep
from quad_wrench_env.config import build, config_path, load_yaml

TINY = {  # two vehicles, two PPO updates, one 6 s evaluation episode
    "env": {"estimator": "oracle", "episode_seconds": 6.0},
    "num_envs": 2,
    "total_steps": 256,
    "checkpoint_every_steps": 100_000,
    "hyperparameters": {"n_steps": 64, "batch_size": 64, "n_epochs": 1},
    "evaluation": {
        "seeds": [1],
        "every_steps": 100_000,
        "metric": "mean_abs_error_after_5s",
        "lower_is_better": True,
    },
}
METRIC = "mean_abs_error_after_5s"


@pytest.fixture
def local_ray():
    """A local Ray on two CPUs, shut down after the test."""
    ray = pytest.importorskip("ray", reason='sweeps need the tune extra: pip install "quad-wrench-env[tune]"')
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


def test_a_grid_sweep_runs_each_trial_and_writes_the_table_and_the_best_config(tmp_path, local_ray):
    space = {"hyperparameters.learning_rate": {"grid": [1.0e-4, 1.0e-3]}}
    result = sweep(build(SweepConfig, {"base": TINY, "space": space}), tmp_path / "sweep", progress=False)
    assert local_ray.is_initialized()  # a Ray it did not start is left running
    with (tmp_path / "sweep" / "results.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 2 and all(math.isfinite(float(r[METRIC])) for r in rows)
    assert sorted(float(r["hyperparameters.learning_rate"]) for r in rows) == [1.0e-4, 1.0e-3]
    assert all(int(r["steps"]) >= 256 and not r["error"] for r in rows)
    for row in rows:
        assert (tmp_path / "sweep" / "runs" / row["trial"] / "final" / "model.zip").is_file()
        assert row["run"] == str(tmp_path / "sweep" / "runs" / row["trial"])
    best = min(rows, key=lambda r: float(r[METRIC]))
    assert result.best["trial"] == best["trial"] == rows[0]["trial"]  # best first
    config = build(TrainConfig, load_yaml(tmp_path / "sweep" / "best_config.yaml"))  # as quad-wrench train
    assert config.hyperparameters["learning_rate"] == float(best["hyperparameters.learning_rate"])
    assert config == result.config and config.num_envs == 2
    assert len((tmp_path / "sweep" / "results.md").read_text().splitlines()) == 2 + 2


def test_the_example_sweep_loads_with_its_base_beside_it():
    config = load_sweep_config(config_path("sweep_fan_tracking.yaml"), ["num_samples=2", "search=optuna"])
    assert config.num_samples == 2 and config.search == "optuna"
    assert build(TrainConfig, config.base_values()).evaluation.metric == METRIC
    quick = load_sweep_config(config_path("sweep_quick.yaml"))  # the README's 2-trial try
    assert quick.search == "grid" and len(quick.space["hyperparameters.learning_rate"]["grid"]) == 2


@pytest.mark.parametrize(
    ("values", "match"),
    [
        ({"search": "bayes"}, r"search='bayes'; allowed: \['grid', 'random', 'optuna'\]"),
        (
            {"search": "optuna", "space": {"seed": {"grid": [0, 1]}}},
            r"space\['seed'\]: grid needs search: grid",
        ),
        ({"samples": 4}, r"unknown config key\(s\) 'samples'"),
        (
            {"space": {"hyperparameter.gamma": {"choice": [0.9]}}},
            r"space\['hyperparameter.gamma'\].*'hyperparameter'",
        ),
        ({"space": {"seed": {"choice": [0.5]}}}, r"space\['seed'\]: seed=0.5 must be an integer"),
        (
            {"space": {"seed": {"between": [0, 9]}}},
            r"space\['seed'\]=\{'between': \[0, 9\]\} must be a mapping of one",
        ),
        (
            {"space": {"hyperparameters.learning_rate": {"loguniform": [0, 1]}}},
            r"must be \[low, high\], positive",
        ),
        ({"space": {"seed": {"randint": [5, 5]}}}, r"randint=\[5, 5\] must be \[low, high\], integers"),
        ({"space": {"evaluation.seeds": {"choice": [[1]]}}}, r"evaluation section"),
        ({"space": {}}, r"space=\{\} must name at least one"),
        ({"num_samples": 0}, r"num_samples=0 must be an integer >= 1"),
        ({"cpus_per_trial": 0}, r"sweep.cpus_per_trial=0 must be a finite number > 0"),
    ],
)
def test_bad_sweep_configs_name_the_value_and_what_is_allowed(values, match):
    with pytest.raises(ValueError, match=match):
        build(SweepConfig, {"base": TINY, "space": {"seed": {"grid": [0, 1]}}, **values})


def test_without_ray_the_error_says_how_to_install_it(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray raises ImportError
    config = build(SweepConfig, {"base": TINY, "space": {"seed": {"grid": [0, 1]}}})
    with pytest.raises(ImportError, match=r'pip install "quad-wrench-env\[tune\]"'):
        sweep(config, tmp_path)
