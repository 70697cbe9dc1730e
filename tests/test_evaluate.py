"""The harness's metrics on episodes with known answers, and its contract."""

from __future__ import annotations

import math

import numpy as np
import pytest

from quad_wrench_cli.compare_estimators import record
from quad_wrench_env.agents.evaluate import Episode, episode_metrics, evaluate
from quad_wrench_env.config import config_path, load_yaml
from tests.conftest import FAN_TRACKING


def _episode(error: np.ndarray, standoff: np.ndarray | None = None, dt: float = 0.02) -> Episode:
    t = np.arange(len(error)) * dt
    trace = {
        "time": t,
        "axis_error": error,
        "standoff_error": np.zeros_like(error) if standoff is None else standoff,
    }
    return Episode(0, trace, total_reward=1.0, length=len(error) - 1, termination_reason=None)


def test_fan_tracking_metrics_on_a_known_trace():
    # 10 s: 0.8 m for the first 2 s, then -0.1 m
    error = np.where(np.arange(501) * 0.02 < 2.0, 0.8, -0.1)
    standoff = np.where(np.arange(501) * 0.02 < 7.5, -0.5, 0.2)  # 2.5 s at 0.5 m after 5 s, then 2.5 s at 0.2
    m = episode_metrics(FAN_TRACKING, _episode(error, standoff))
    assert m["mean_abs_standoff_error_after_5s"] == pytest.approx((125 * 0.5 + 126 * 0.2) / 251)
    assert m["time_to_0.15m"] == pytest.approx(2.0)
    assert m["mean_abs_error_after_5s"] == pytest.approx(0.1)
    assert m["fraction_within_0.15m"] == pytest.approx(401 / 501)


def test_never_reaching_the_band_is_infinite():
    assert math.isinf(episode_metrics(FAN_TRACKING, _episode(np.full(100, 0.5)))["time_to_0.15m"])


class _Hover:
    def reset(self, env):
        self.calls = 0

    def act(self, observation):
        self.calls += 1
        return np.zeros(4, dtype=np.float32)


def test_evaluate_runs_every_seed_and_is_reproducible():
    policy = _Hover()
    kwargs = {"options": {"fan_motion": "static"}, "episode_seconds": 2.0}
    a = evaluate(policy, FAN_TRACKING, [3, 4], **kwargs)
    b = evaluate(policy, FAN_TRACKING, [3, 4], **kwargs)
    assert a.seeds == [3, 4] and len(a.per_seed) == 2
    assert a.per_seed == b.per_seed
    assert a.per_seed[0] != a.per_seed[1]  # the seed draws the start offset
    assert policy.calls == 100 and len(a.episodes[0].trace["time"]) == 101
    with pytest.raises(ValueError, match="seed"):
        evaluate(policy, FAN_TRACKING, [])


def test_the_estimator_comparison_records_a_short_flight():
    """quad-wrench compare estimators swaps a recording bank into the env: a short flight records
    one sensor sample and one true wrench per physics step."""
    stream = record(load_yaml(config_path("compare_estimators.yaml")), 0, episode_seconds=0.2)
    assert len(stream.inputs) == len(stream.truth) == round(0.2 / stream.dt)
    thrust, torque, position, quaternion = stream.inputs[-1]
    assert math.isfinite(thrust) and torque.shape == position.shape == (3,) and quaternion.shape == (4,)
