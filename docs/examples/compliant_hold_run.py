"""Fly the compliant hover (run from this folder: python compliant_hold_run.py)."""

import pytest
from compliant_hold import CompliantHoldPolicy  # registers "compliant_hold"

from quad_wrench_env.agents import make_agent
from quad_wrench_env.agents.base import Policy
from quad_wrench_env.agents.evaluate import evaluate

policy = make_agent("compliant_hold", k=1.0, admittance=0.3)
assert isinstance(policy, Policy) and isinstance(policy, CompliantHoldPolicy)
result = evaluate(
    policy,
    "QuadWrench/FanTracking-v1",
    seeds=[0, 1],
    options={"fan_motion": "static", "offset_y": 0.5},
    estimator="ukf",
    episode_seconds=10.0,
)
# it gives way downstream and does not seek the jet's axis
assert result.mean["mean_abs_error_after_5s"] == pytest.approx(0.46, abs=0.02)
assert result.mean["mean_abs_standoff_error_after_5s"] == pytest.approx(0.23, abs=0.02)
assert result.mean["terminated_early"] == 0.0

with pytest.raises(ValueError, match=r"unknown config key\(s\) 'compliant_hold.gain'"):
    make_agent("compliant_hold", gain=2.0)
refused = "CompliantHoldPolicy needs action_type='velocity', the env has 'attitude'"
with pytest.raises(ValueError, match=refused):
    evaluate(policy, "QuadWrench/DisturbanceRejection-v0", seeds=[0])
