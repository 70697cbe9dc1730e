"""The learned wrench estimator: its features against kinematics written here, its network against
PyTorch's GRU, the shipped models against pushes of known size, and what it refuses."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
import torch

import quad_wrench_env  # noqa: F401  (registers the envs)
from quad_wrench_env.estimators import make_estimator, make_estimator_bank
from quad_wrench_env.estimators.fitting import Network
from quad_wrench_env.estimators.learned import LearnedModel, shipped_models
from quad_wrench_env.estimators.learned_kernel import FEATURES, gru_step, stream_features
from quad_wrench_env.vehicle import GRAVITY, PRESETS, make_vehicle

DT = 0.005


def axis_angle_quaternion(axis: np.ndarray, angle: float) -> np.ndarray:
    """``[w, x, y, z]`` of a rotation by ``angle`` about unit ``axis``."""
    return np.concatenate(([math.cos(angle / 2)], math.sin(angle / 2) * axis))


def hamilton(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    aw, av, bw, bv = a[0], a[1:], b[0], b[1:]
    return np.concatenate(([aw * bw - av @ bv], aw * bv + bw * av + np.cross(av, bv)))


def matrix_of(q: np.ndarray) -> np.ndarray:
    """Body -> world rotation: the quaternion's action on the basis vectors (v -> q v q*)."""
    columns = []
    for e in np.eye(3):
        rotated = hamilton(hamilton(q, np.concatenate(([0.0], e))), q * np.array((1, -1, -1, -1)))
        columns.append(rotated[1:])
    return np.array(columns).T


def test_the_features_are_the_kinematics_of_the_measured_stream():
    """A vehicle moving at constant velocity and turning at a constant body rate: the features give
    that velocity and that rate (exact for a constant rate), the thrust along the body's z axis and
    the motor torque, step by step."""
    velocity, rate, thrust, torque = (
        np.array((0.3, -0.2, 0.1)),
        np.array((0.4, -1.1, 2.5)),
        7.1,
        np.array((1e-3, -2e-3, 5e-4)),
    )
    start = np.array((1.0, 0.5, 1.5))
    q0 = axis_angle_quaternion(np.array((0.0, 0.6, 0.8)), 0.7)
    steps = 50
    axis, speed = rate / np.linalg.norm(rate), np.linalg.norm(rate)
    quaternions = np.array(
        [hamilton(q0, axis_angle_quaternion(axis, speed * DT * (k + 1))) for k in range(steps)]
    )
    positions = np.array([start + velocity * DT * (k + 1) for k in range(steps)])
    mass = 0.7
    features = stream_features(
        np.full(steps, thrust),
        np.tile(torque, (steps, 1)),
        positions,
        quaternions,
        np.empty((0, 3)),
        np.empty((0, 3)),
        np.concatenate((start, q0)),
        DT,
        mass,
    )
    assert features.shape == (steps, FEATURES)
    for k in (0, 17, steps - 1):
        r = matrix_of(quaternions[k])
        np.testing.assert_allclose(features[k, 0:3], velocity, atol=1e-9)
        np.testing.assert_allclose(features[k, 3:6], r[:, 2] * thrust / mass, atol=1e-12)
        np.testing.assert_allclose(features[k, 6:15], r.ravel(), atol=1e-12)
        np.testing.assert_allclose(features[k, 15:18], rate, atol=1e-9)
        np.testing.assert_allclose(features[k, 18:21], torque, atol=0)


def test_the_kernels_network_is_pytorchs_gru():
    """The kernel's recurrent unit and head, step by step, against ``torch.nn.GRU`` and ``Linear`` in
    float64 on the same random weights and inputs (PyTorch's equations, not ours)."""
    torch.manual_seed(3)
    network = Network(FEATURES, 16).double()
    with torch.no_grad():
        for parameter in network.parameters():
            parameter.normal_(0.0, 0.4)
    inputs = torch.randn(1, 40, FEATURES, dtype=torch.float64)
    expected = network(inputs)[0].detach().numpy()
    arrays = network.arrays()
    hidden, out = np.zeros(16), np.zeros(18)
    for k in range(40):
        gru_step(
            inputs[0, k].numpy(),
            hidden,
            out,
            arrays["weights_in"],
            arrays["weights_hidden"],
            arrays["bias_in"],
            arrays["bias_hidden"],
            arrays["head"],
            arrays["head_bias"],
        )
        np.testing.assert_allclose(out, expected[k], rtol=0, atol=1e-12)


def test_every_preset_has_a_shipped_model_that_knows_where_it_came_from():
    assert shipped_models() == sorted(PRESETS)
    for name in shipped_models():
        bank = make_estimator_bank("learned", make_vehicle(name), DT, 1)
        provenance = bank.model.provenance
        assert bank.model.fitted_for.vehicle == name
        assert {"config", "commit", "kept_epoch", "held_out_loss"} <= set(provenance)


@pytest.mark.parametrize("vehicle", sorted(PRESETS))
def test_the_shipped_model_weighs_a_steady_push_along_x(vehicle):
    """Hovering under a steady push of 0.15 of the weight along x (the fitting mix's jets and fan push
    along x) from 1 s: after 2.5 s the estimate holds every force component within 0.04 of the weight,
    and each error lies within 3 of the model's sds. (A push along y or z, which the mix lacks, is
    underestimated by half or more: docs/estimators.md, "learned".)"""
    weight = PRESETS[vehicle].mass * GRAVITY
    push = np.array((0.15, 0.0, 0.0)) * weight
    env = gym.make(
        "QuadWrench/FanTracking-v1",
        vehicle=vehicle,
        estimator="learned",
        fan={"enabled": False},
        episode_seconds=5.0,
        external_wrench=[[1.0, 10.0, *push, 0.0, 0.0, 0.0]],
    )
    env.reset(seed=0)
    errors = []
    for _ in range(240):
        _, _, terminated, _, info = env.step(np.zeros(4, dtype=np.float32))
        assert not terminated
        if info["time"] >= 3.5:
            error = info["wrench_est"][:3] - info["wrench_true"][:3]
            errors.append(error)
            sd = np.sqrt(np.diag(info["wrench_cov"])[:3])
            assert np.all(np.abs(error) <= 3.0 * sd), (error, sd)
    env.close()
    np.testing.assert_allclose(info["wrench_true"][:3], push, atol=0.02 * weight)
    assert np.max(np.abs(np.mean(errors, axis=0))) <= 0.04 * weight


def test_a_model_refuses_another_vehicle_time_step_or_sensor_set():
    hummingbird = make_vehicle("hummingbird")
    with pytest.raises(ValueError, match="fitted for vehicle='ardrone2', asked for 'hummingbird'"):
        make_estimator("learned", hummingbird, DT, model=_shipped_path("ardrone2"))
    with pytest.raises(ValueError, match="fitted for dt=0.005, asked for 0.0025"):
        make_estimator("learned", hummingbird, 0.0025)
    estimator = make_estimator("learned", hummingbird, DT)
    with pytest.raises(ValueError, match="fitted for measured_motion=False, asked for True"):
        estimator.step(7.0, np.zeros(3), np.zeros(3), np.array((1.0, 0, 0, 0)), np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match="fitted for measured_motion=False"):
        gym.make("QuadWrench/FanTracking-v1", estimator="learned", sensors={"state_estimator": True}).reset(
            seed=0
        )
    with pytest.raises(ValueError, match="estimator_params.model='nowhere.npz' is not a file"):
        make_estimator("learned", hummingbird, DT, model="nowhere.npz")
    with pytest.raises(ValueError, match="'estimator_params.walk'"):
        make_estimator("learned", hummingbird, DT, walk=1.0)


def test_a_damaged_model_is_refused_by_name(tmp_path):
    model = LearnedModel.load(_shipped_path("hummingbird"))
    model.arrays["head"] = model.arrays["head"][:, :5]
    with pytest.raises(ValueError, match="head has shape"):
        LearnedModel(model.fitted_for, model.arrays, model.provenance)
    nan = LearnedModel.load(_shipped_path("hummingbird"))
    nan.arrays["bias_in"][0] = np.nan
    with pytest.raises(ValueError, match="bias_in"):
        LearnedModel(nan.fitted_for, nan.arrays, nan.provenance)


def _shipped_path(name: str) -> str:
    from importlib import resources

    from quad_wrench_env.estimators.learned import MODELS

    with resources.as_file(MODELS / f"{name}.npz") as path:
        return str(path)


TINY_FIT = [
    "--set",
    "vehicles=[hummingbird]",
    "--set",
    "runs=2",
    "--set",
    "held_out_runs=1",
    "--set",
    "flights={hover: {agent: hold, env: {episode_seconds: 1.0, fan: {enabled: false}}}}",
    "--set",
    "training={hidden: 8, epochs: 2, window_seconds: 0.5, batch: 2, settle_seconds: 0.5}",
    "--no-progress",
]


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("speed=fast", "'speed'"),
        ("training.epochz=3", "'training.epochz'"),
        ("vehicles=[blimp]", "unknown ['blimp']"),
        ("runs=0", "runs=0"),
        ("flights={hover: {agent: hold, wind: 3}}", "flights.hover"),
    ],
)
def test_a_bad_fitting_config_exits_before_any_work(override, message, capsys, tmp_path, monkeypatch):
    from quad_wrench_env.config import config_path
    from tests.conftest import assert_usage_error

    monkeypatch.chdir(tmp_path)
    config = str(config_path("fit_estimator.yaml"))
    argv = ["fit-estimator", config, *TINY_FIT, "--set", override, "--run-dir", "run"]
    assert_usage_error(argv, message, capsys)
    assert not (tmp_path / "run").exists()


def test_fit_estimator_makes_a_model_that_flies(tmp_path, capsys):
    """A tiny fit end to end: its model names its vehicle and config, and an env flies on it."""
    from quad_wrench_cli.main import main
    from quad_wrench_env.config import config_path

    run = tmp_path / "run"
    assert (
        main(["fit-estimator", str(config_path("fit_estimator.yaml")), *TINY_FIT, "--run-dir", str(run)]) == 0
    )
    model = LearnedModel.load(run / "hummingbird.npz")
    assert model.fitted_for.vehicle == "hummingbird" and model.hidden_size == 8
    assert model.provenance["config"]["training"]["epochs"] == 2
    assert (run / "config.yaml").is_file() and (run / "hummingbird_curve.csv").is_file()
    env = gym.make(
        "QuadWrench/DisturbanceRejection-v0",
        estimator="learned",
        estimator_params={"model": str(run / "hummingbird.npz")},
    )
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.zeros(4, dtype=np.float32))
    assert np.all(np.isfinite(info["wrench_est"])) and np.all(np.linalg.eigvalsh(info["wrench_cov"]) > 0)
    env.close()


def test_the_head_is_read_in_the_world_frame_through_the_measured_attitude():
    """The head's body-frame torque and its variances reach ``wrenches`` and ``wrench_covariances``
    turned by the measured attitude (``R τ``, ``R Σ Rᵀ``), the force and its variances as they are,
    each scaled by the model's target scale and variance scale; velocity and rates in ``states``."""
    bank = make_estimator_bank("learned", make_vehicle("hummingbird"), DT, 2)
    q = axis_angle_quaternion(np.array((0.6, 0.0, 0.8)), 1.1)
    bank.reset(1, np.array((1.0, 2.0, 3.0)), q)
    rng = np.random.default_rng(0)
    bank.outputs[1] = rng.normal(0.0, 1.0, 18)
    head, scale = bank.outputs[1], bank.model.arrays["target_scale"]
    variance_scale = bank.model.arrays["variance_scale"]
    r = matrix_of(q)
    states, wrenches = bank.estimates()
    np.testing.assert_allclose(wrenches[1, :3], head[:3] * scale[:3], rtol=1e-12)
    np.testing.assert_allclose(wrenches[1, 3:], r @ (head[3:6] * scale[3:6]), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(states[1, :3], (1.0, 2.0, 3.0))
    np.testing.assert_allclose(states[1, 3:6], head[12:15] * scale[6:9], rtol=1e-12)
    np.testing.assert_allclose(states[1, 6:10], q)
    np.testing.assert_allclose(states[1, 10:13], head[15:18] * scale[9:12], rtol=1e-12)
    covariance = bank.wrench_covariances()[1]
    force = np.diag(np.exp(head[6:9]) * scale[:3] ** 2 * variance_scale[0])
    torque = r @ np.diag(np.exp(head[9:12]) * scale[3:6] ** 2 * variance_scale[1]) @ r.T
    np.testing.assert_allclose(covariance[:3, :3], force, rtol=1e-12)
    np.testing.assert_allclose(covariance[3:, 3:], torque, rtol=1e-10, atol=1e-30)
    np.testing.assert_array_equal(covariance[:3, 3:], 0.0)
