"""The estimator benchmark (quad_wrench_cli/estimator_benchmark.py): the step response's latency and
rise time against a first-order lag written here, and a user's estimator entering the table with one
line of config."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from quad_wrench_cli.estimator_benchmark import response, step_wrench
from quad_wrench_env import registry
from quad_wrench_env.vehicle import GRAVITY, make_vehicle

EXAMPLES = Path(__file__).resolve().parents[1] / "docs" / "examples"


def test_a_first_order_lag_has_the_latency_and_rise_of_its_time_constant():
    """``y = s·(1 - exp(-(t - t0)/τ))``: 10 % at ``τ·ln(10/9)`` after the step, 90 % at ``τ·ln 10``, so
    the 10-90 % rise is ``τ·ln 9``; read on a 1 ms grid (the tolerance), either sign of the step."""
    tau, start = 0.3, 2.0
    t = np.arange(0.0, 6.0, 1e-3)
    for size in (0.5, -0.02):
        y = np.where(t >= start, size * (1.0 - np.exp(-(t - start) / tau)), 0.0)
        latency, rise = response(t, y, start, size)
        assert latency == pytest.approx(tau * math.log(10 / 9), abs=2e-3)
        assert rise == pytest.approx(tau * math.log(9), abs=2e-3)
    assert all(math.isnan(v) for v in response(t, 0.05 * np.ones_like(t), start, 1.0))  # never at 90 %


def test_the_step_is_sized_by_the_vehicle():
    v = make_vehicle("crazyflie2")
    segment = step_wrench("crazyflie2", {"at": 3.0, "force": 0.1, "torque": 0.05}, 8.0)[0]
    assert segment[:2] == [3.0, 9.0]
    np.testing.assert_allclose(
        segment[2:], [0.1 * v.mass * GRAVITY, 0, 0, 0, 0, 0.05 * v.mass * GRAVITY * v.arm]
    )


def test_a_users_estimator_enters_the_benchmark_with_one_line(tmp_path, monkeypatch, capsys):
    from quad_wrench_cli.main import main

    monkeypatch.setitem(registry._ENTRIES, "estimator", dict(registry.registered("estimator")))
    monkeypatch.syspath_prepend(str(EXAMPLES))
    monkeypatch.delitem(sys.modules, "quasi_static", raising=False)  # registers again, in this registry
    config = tmp_path / "benchmark.yaml"
    config.write_text(
        "env_id: QuadWrench/FanTracking-v1\nseeds: [0]\n"
        f"output: {tmp_path / 'out'}\ncost: {{steps: 50, repeats: 1}}\n"
        "benchmark:\n"
        "  estimators: [ukf, 'quasi_static:quasi_static']\n"
        "  vehicles: [ardrone2]\n  first_seed: 0\n  runs: 2\n  settle: 1.0\n"
        "  step: {at: 1.5, force: 0.1, torque: 0.05}\n"
        "  flights:\n    step: {agent: hold, env: {episode_seconds: 3.0, fan: {enabled: false}}}\n"
    )
    assert main(["compare", "estimators", "--config", str(config), "--only", "benchmark"]) == 0
    rows = [line.split("|")[1:5] for line in capsys.readouterr().out.splitlines() if line.startswith("| ")]
    names = {cells[0].strip() for cells in rows}
    assert {"ukf", "quasi_static:quasi_static"} <= names
    ukf = next(cells for cells in rows if cells[0].strip() == "ukf" and cells[3].strip() == "step")
    assert ukf[1].strip() == "default" and ukf[2].strip() == "ardrone2"  # a filter's settings: the default
    assert next(cells for cells in rows if cells[0].strip() == "quasi_static:quasi_static")[1].strip() == "-"
