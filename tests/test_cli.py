"""The ``quad-wrench`` command line: every command's help, bad arguments (exit code 2, a message, no
traceback), ``list --json``, a short ``evaluate`` with its JSON and CSV, ``python -m quad_wrench_env``."""

from __future__ import annotations

import argparse
import csv
import json
import math
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from quad_wrench_cli import peers
from quad_wrench_cli.common import load_config
from quad_wrench_cli.main import build_parser, main
from quad_wrench_env.agents import make_agent
from quad_wrench_env.agents.evaluate import evaluate
from quad_wrench_env.tasks import TASKS
from tests.conftest import FAN_TRACKING, assert_usage_error


def _commands(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()) -> Iterator[tuple]:
    """``(path, parser)`` of the command line and of every command under it, groups included."""
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _commands(sub, (*path, name))


COMMANDS = dict(_commands(build_parser()))


def test_every_command_of_the_issue_is_there():
    top = {path[0] for path in COMMANDS if path}
    assert top == {
        "demo",
        "train",
        "evaluate",
        "estimate",
        "fit-estimator",
        "compare",
        "reproduce",
        "bench",
        "sweep",
        "study",
        "list",
    }
    assert {("reproduce", p) for p in ("mckinnon", "yuksel", "hentzen")} <= set(COMMANDS)
    assert {("compare", "agents"), ("compare", "estimators")} <= set(COMMANDS)


@pytest.mark.parametrize("path", list(COMMANDS), ids=lambda path: " ".join(path) or "quad-wrench")
def test_the_help_of_every_command_names_each_option_and_explains_it(path, capsys):
    with pytest.raises(SystemExit) as exit_:
        main([*path, "--help"])
    assert exit_.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: quad-wrench")
    for action in COMMANDS[path]._actions:
        assert action.help, f"{' '.join(path)}: {action.option_strings or action.dest} has no help text"
        names = action.option_strings or [action.metavar or action.dest]
        assert all(name in out for name in names), names


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["nobody"], "invalid choice: 'nobody'"),
        (["reproduce", "nobody"], "invalid choice: 'nobody'"),
        (["compare"], "required"),
        (["evaluate", "nobody", FAN_TRACKING, "--seeds", "0"], "unknown agent 'nobody'"),
        (["evaluate", "hold", "QuadWrench/Nope-v0", "--seeds", "0"], "unknown env id 'QuadWrench/Nope-v0'"),
        (["evaluate", "hold", FAN_TRACKING, "--seeds", "x"], "seed 'x' must be an integer >= 0"),
        (["evaluate", "hold", FAN_TRACKING, "--seeds", "0", "--env", "nonsense=1"], "'nonsense'"),
        (
            ["evaluate", "hold", FAN_TRACKING, "--seeds", "0", "--env", "episode_seconds"],
            "must read KEY=VALUE",
        ),
        (["evaluate", "hold", FAN_TRACKING, "--seeds", "0", "--agent-param", "k_xy=fast"], "k_xy"),
        (["evaluate", "hold", FAN_TRACKING, "--seeds", "0", "--options", '{"bogus": 1}'], "'bogus'"),
        (["evaluate", "hold", FAN_TRACKING, "--seeds", "0", "--options", "[1]"], "JSON object"),
        (["evaluate", "hold", FAN_TRACKING, "--seeds", "0", "--video", "out.avi"], ".mp4 or .gif"),
        (["demo", "--seeds", "x"], "seed 'x'"),
        (["demo", "--config", "missing.yaml"], "'missing.yaml' does not exist"),
        (["reproduce", "mckinnon", "--config", "missing.yaml"], "'missing.yaml' does not exist"),
        (["reproduce", "yuksel", "--only", "fig9"], "invalid choice: 'fig9'"),
        (["train", "missing.yaml"], "'missing.yaml' does not exist"),
        (["train"], "give a config"),
        (["sweep", "missing.yaml"], "'missing.yaml' does not exist"),
        (["bench", "--soak-minutes", "5"], "at least 20"),
        (["bench", "--gym-pybullet-drones", "."], "add --peers"),
        (["bench", "--steps", "0"], "integer >= 1"),
    ],
)
def test_bad_arguments_exit_with_code_2_and_a_message(argv, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # missing.yaml is missing; nothing is written where the tests run
    assert_usage_error(argv, message, capsys)


def test_list_json_holds_the_vehicle_presets_and_the_env_ids(capsys):
    assert main(["list", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert set(data["vehicles"]) == {"ardrone2", "crazyflie2", "hummingbird", "yuksel1kg"}
    assert data["vehicles"]["yuksel1kg"]["mass_kg"] == 1.0
    assert data["env_ids"] == list(TASKS)
    assert {"hold", "admittance", "pid", "mpc", "ida_pbc"} <= set(data["agents"])
    assert "ppo_fan_tracking" in data["policies"] and "QC1" in data["ida_pbc_sets"]
    assert "jet_crossing" in data["scenarios"] and "wall" in data["surfaces"]
    assert data["ida_pbc_task_defaults"] == {"QuadWrench/ForceExertion-v0": "QC4"}  # what ida_pbc flies there
    assert main(["list"]) == 0
    assert "default; QC4 on QuadWrench/ForceExertion-v0" in capsys.readouterr().out


def test_evaluate_writes_each_seeds_metrics_as_json_and_csv(tmp_path, capsys):
    """The harness's own numbers, seed by seed (NaN, a window the short episode never reached: null)."""
    out = tmp_path / "out"
    argv = ["evaluate", "hold", FAN_TRACKING, "--seeds", "0", "1", "--env", "episode_seconds=2"]
    assert main([*argv, "--no-progress", "--json", str(out / "m.json"), "--csv", str(out / "m.csv")]) == 0
    assert "mean ± sd" in capsys.readouterr().out
    expected = evaluate(make_agent("hold"), FAN_TRACKING, [0, 1], episode_seconds=2)
    data = json.loads((out / "m.json").read_text())
    assert data["seeds"] == [0, 1] and data["env"] == {"episode_seconds": 2}
    for seed, row, metrics in zip((0, 1), data["per_seed"], expected.per_seed, strict=True):
        assert row == {"seed": seed, **{k: v if math.isfinite(v) else None for k, v in metrics.items()}}
    with (out / "m.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert [r["seed"] for r in rows] == ["0", "1", "mean"]
    assert float(rows[2]["return"]) == pytest.approx(expected.mean["return"])


def test_bench_has_nothing_to_download_once_the_peers_are_installed(tmp_path):
    """Only peers not yet installed are resolved with pip (their download size said before installing)."""
    chosen = peers.jobs(argparse.Namespace(gym_pybullet_drones=None))
    assert set(peers.missing(chosen, tmp_path)) == {"pyflyt", "rotorpy"}
    for requirements, _, name in chosen.values():
        stamp = peers._stamp(tmp_path, name, requirements)
        stamp.parent.mkdir(parents=True, exist_ok=True)
        stamp.touch()
    assert peers.missing(chosen, tmp_path) == {}
    assert "nothing to download" in peers.download_summary({})


def test_a_default_config_is_the_shipped_one_from_any_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    config, label = load_config(None, "reproduce_mckinnon.yaml")
    assert label == "configs/reproduce_mckinnon.yaml" and config["env_id"] == FAN_TRACKING.split(":")[-1]


def test_python_m_quad_wrench_env_runs_the_command_line():
    root = Path(__file__).resolve().parent.parent
    done = subprocess.run(
        [sys.executable, "-m", "quad_wrench_env", "--help"],
        cwd=root,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("usage: python -m quad_wrench_env") and "reproduce" in done.stdout


TRAIN_CONFIG = str(Path(__file__).resolve().parent.parent / "configs" / "train_fan_tracking.yaml")


@pytest.mark.parametrize(
    ("argv", "files", "message"),
    [
        (["--set", "env.estimator=kalman"], {}, "unknown estimator 'kalman'"),
        (["--set", "env.foo=1"], {}, "'foo'"),
        (["--set", "evaluation.env.foo=2"], {}, "'foo'"),
        (["--set", "hyperparameters.n_step=32"], {}, "hyperparameters ['n_step'] are not PPO's"),
        (["--set", "hyperparameters.n_steps=abc"], {}, "'n_steps': 'abc'"),
        (["--set", "env_id=QuadWrench/FanTracking-v9"], {}, "env_id='QuadWrench/FanTracking-v9'"),
        (["--set", "evaluation.metric=nope"], {}, "evaluation.metric='nope'; allowed"),
        (["v.yaml"], {"v.yaml": "env: {vehicle: ardrone3}\n"}, "unknown vehicle preset 'ardrone3'"),
        (["bad.yaml"], {"bad.yaml": "env_id: [a\n  b: c\n"}, "is not valid YAML at line 2"),
        ([], {"run/kept.txt": ""}, "run folder 'run' is not empty"),
    ],
)
def test_train_refuses_bad_input_before_anything_runs(argv, files, message, capsys, tmp_path, monkeypatch):
    """Exit code 2 and one line naming the value, no traceback, and no run folder left behind: the
    env settings, the hyperparameters and the evaluation are checked before the run starts."""
    monkeypatch.chdir(tmp_path)
    for name, text in files.items():
        Path(name).parent.mkdir(parents=True, exist_ok=True)
        Path(name).write_text(text)
    config = [] if argv and argv[0].endswith(".yaml") else [TRAIN_CONFIG]
    assert_usage_error(["train", *config, *argv, "--run-dir", "run", "--no-progress"], message, capsys)
    expected = ["kept.txt"] if "run/kept.txt" in files else []  # a refused run writes nothing
    assert sorted(p.name for p in Path("run").glob("*")) == expected


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["evaluate", "admittance", "QuadWrench/DisturbanceRejection-v0", "--seeds", "0"],
            "action_type='velocity'",
        ),
        (
            ["evaluate", "ppo_fan_tracking", "QuadWrench/ForceExertion-v0", "--seeds", "0"],
            "trained on observations of shape (25,), the env has (28,)",
        ),
        (
            [
                "evaluate",
                "ppo_fan_tracking",
                "QuadWrench/ForceExertion-v0",
                "--seeds",
                "0",
                "--env",
                "action_type=wrench",
            ],
            "trained with action_type='velocity', the env has action_type='wrench'",
        ),
        (["demo", "--config", "bad.yaml"], "is not valid YAML"),
        (["sweep", "sweep.yaml", "--address", "auto", "--folder", "sweep"], "address='auto'"),
    ],
)
def test_an_agent_the_env_refuses_and_a_missing_cluster_exit_with_code_2(
    argv, message, capsys, tmp_path, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    services = pytest.importorskip("ray._private.services")

    def no_ray_running() -> list[str]:  # what Ray finds of other processes' clusters: none
        return []

    no_ray_running.cache_clear = lambda: None  # Ray's own is cached
    monkeypatch.setattr(services, "find_gcs_addresses", no_ray_running)
    Path("bad.yaml").write_text("cases: [a\n  b: c\n")
    Path("sweep.yaml").write_text(f"base: {TRAIN_CONFIG}\nspace: {{seed: {{grid: [0, 1]}}}}\nsearch: grid\n")
    assert_usage_error(argv, message, capsys)
    assert not Path("sweep").exists()


def test_everything_the_package_installs_lives_under_the_projects_names():
    """No top-level module named ``agents`` (it would shadow other packages of that name): the agents
    are ``quad_wrench_env.agents``, with their shipped policies as package data."""
    import importlib.util

    tomllib = pytest.importorskip("tomllib")  # Python 3.11+
    root = Path(__file__).resolve().parent.parent
    packages = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]
    assert {name.split(".")[0] for name in packages} == {"quad_wrench_env", "quad_wrench_cli"}
    assert "quad_wrench_env.agents" in packages and not (root / "agents").exists()
    spec = importlib.util.find_spec("agents")
    assert spec is None or root not in Path(spec.origin or "/").parents
    assert make_agent("ppo_fan_tracking") is not None  # a shipped policy, found in the package
