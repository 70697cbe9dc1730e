"""Flight logs (:mod:`quad_wrench_env.flight_log`): ``quad-wrench evaluate --log`` then ``quad-wrench
estimate`` gives the live run's wrench estimates, and every kind of bad log is refused with a message that
names the column and the row."""

from __future__ import annotations

import csv
import math
from collections.abc import Callable
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from quad_wrench_cli.main import main
from quad_wrench_env.agents import make_agent
from quad_wrench_env.agents.evaluate import run_episode
from quad_wrench_env.flight_log import FlightRecorder, read_flight_log
from quad_wrench_env.rotations import quat_from_euler_zyx
from quad_wrench_env.vehicle import make_vehicle
from tests.conftest import FAN_TRACKING, assert_usage_error

SUBSTEPS = 4
"""Physics steps per policy step in FanTracking-v1 (200 Hz, 50 Hz)."""


def _read_csv(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as handle:
        return list(csv.DictReader(handle))


@pytest.mark.parametrize(
    ("estimator", "state_estimator"),
    [("ukf", False), ("ekf", True), ("observer", False), ("oracle", False)],  # ekf: velocity, body rates
)
def test_a_logged_flight_read_back_gives_the_live_runs_estimates(
    tmp_path, capsys, estimator, state_estimator
):
    log, out = tmp_path / "flight.csv", tmp_path / "out"
    settings = {"estimator": estimator, "episode_seconds": 0.5, "sensors.state_estimator": state_estimator}
    env_args = [a for key, value in settings.items() for a in ("--env", f"{key}={str(value).lower()}")]
    argv = ["evaluate", "hold", FAN_TRACKING, "--seeds", "3", "--no-progress", "--log", str(log), *env_args]
    assert main(argv) == 0
    assert main(["estimate", str(log), "--estimator", estimator, "--output", str(out)]) == 0
    assert "wrote" in capsys.readouterr().out and (out / f"flight_{estimator}.png").stat().st_size > 0
    rows = _read_csv(out / f"flight_{estimator}.csv")
    labels = ("f_x", "f_y", "f_z", "tau_x", "tau_y", "tau_z")
    estimated = np.array([[float(row[label]) for label in labels] for row in rows])

    sensors = {"state_estimator": state_estimator}
    live_env = gym.make(FAN_TRACKING, estimator=estimator, episode_seconds=0.5, sensors=sensors)
    try:
        live = run_episode(make_agent("hold"), live_env, 3).trace
    finally:
        live_env.close()
    assert len(rows) == SUBSTEPS * (len(live["time"]) - 1) + 1  # every physics step and the reset
    np.testing.assert_allclose(estimated[::SUBSTEPS], live["wrench_est"], rtol=1e-9, atol=1e-12)
    assert np.abs(live["wrench_est"][1:]).max() > 0.1  # a flight with a wrench to estimate
    flight = read_flight_log(log, make_vehicle("ardrone2"))
    np.testing.assert_array_equal(flight.time[::SUBSTEPS], live["time"])
    np.testing.assert_array_equal(flight.wrench[::SUBSTEPS], live["wrench_true"])
    assert (flight.velocity is not None) == state_estimator == (flight.body_rates is not None)
    bands = {row[f"{label}_band"] for row in rows for label in labels}
    if estimator in ("ukf", "ekf"):
        assert all(float(b) > 0 for b in bands)
    else:  # no covariance: no band, not an invented one
        assert bands == {""}


# -- bad logs --------------------------------------------------------------------------------------
VEHICLE = make_vehicle("ardrone2")
Columns = dict[str, list]


def _good(rows: int = 20) -> Columns:
    """A hover moving at 0.5 m/s along x, at 200 Hz, in the layout's units."""
    t = 0.005 * np.arange(rows)
    columns = {"t": t, "x": 0.5 * t, "y": 0.0 * t, "z": 1.0 + 0.0 * t, "qw": 1.0 + 0.0 * t}
    columns |= {name: 0.0 * t for name in ("qx", "qy", "qz")}
    columns |= {f"w{i}": VEHICLE.hover_rotor_speed + 0.0 * t for i in range(1, 5)}
    return {name: values.tolist() for name, values in columns.items()}


def _write(path: Path, columns: Columns) -> Path:
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(columns)
        writer.writerows(zip(*columns.values(), strict=True))
    return path


def _set(name: str, row: int, value: float | str) -> Callable[[Columns], None]:
    """Set data row ``row`` (1-based) of column ``name``."""

    def edit(columns: Columns) -> None:
        columns[name][row - 1] = value

    return edit


def _scale(names: str, factor: float) -> Callable[[Columns], None]:
    def edit(columns: Columns) -> None:
        for name in names.split():
            columns[name] = [factor * v for v in columns[name]]

    return edit


def _add(names: str, value: float = 0.0) -> Callable[[Columns], None]:
    def edit(columns: Columns) -> None:
        for name in names.split():
            columns[name] = [value] * len(columns["t"])

    return edit


def _both(*edits: Callable[[Columns], None]) -> Callable[[Columns], None]:
    def edit(columns: Columns) -> None:
        for one in edits:
            one(columns)

    return edit


def _drop_rows(start: int, stop: int) -> Callable[[Columns], None]:
    """Drop data rows ``start`` to ``stop`` (1-based, inclusive)."""

    def edit(columns: Columns) -> None:
        for values in columns.values():
            del values[start - 1 : stop]

    return edit


def _euler(columns: Columns) -> None:
    for name in ("qw", "qx", "qy", "qz"):
        del columns[name]
    _add("roll pitch yaw")(columns)


BAD_LOGS = {
    "missing column": (lambda c: c.pop("qw"), "header (line 1): missing column 'qw'"),
    "partial optional group": (_add("vx vz"), "header (line 1): missing column 'vy'"),
    "unknown column": (_add("rpm1"), "header (line 1): unknown column 'rpm1'"),
    "unsorted times": (
        _set("t", 7, 0.02),
        "column 't', row 7 (line 8): 0.02 s is earlier than the row before (0.025 s)",
    ),
    "duplicate times": (_set("t", 7, 0.025), "column 't', row 7 (line 8): 0.025 s is a duplicate time"),
    "gap": (
        _drop_rows(10, 11),
        "column 't', row 10 (line 11): a gap of 0.015 s from the row before, 3 times",
    ),
    "uneven step": (_set("t", 7, 0.0265), "column 't', row 7 (line 8): an uneven step of 0.0015 s"),
    "NaN": (_set("z", 5, "nan"), "column 'z', row 5 (line 6): 'nan'; allowed: finite numbers"),
    "infinity": (_set("qx", 2, "inf"), "column 'qx', row 2 (line 3): 'inf'; allowed: finite numbers"),
    "no number": (_set("w2", 3, "fast"), "column 'w2', row 3 (line 4): 'fast'; allowed: finite numbers"),
    "empty cell": (_set("x", 4, ""), "column 'x', row 4 (line 5): ''; allowed: finite numbers"),
    "milliseconds": (_scale("t", 1000.0), "column 't', row 2 (line 3): a step of 5 from the row before"),
    "RPM": (
        _scale("w1 w2 w3 w4", 30 / np.pi),
        "column 'w1', row 1 (line 2): 3144.41 is more than 2 times the ardrone2's top speed 550 rad/s: RPM?",
    ),
    "negative motor speed": (
        _set("w3", 8, -300.0),
        "column 'w3', row 8 (line 9): -300 is below 0",
    ),
    "degrees": (
        _both(_euler, _set("pitch", 4, -10.0)),
        "column 'pitch', row 4 (line 5): -10 rad is beyond ±1.5708; pitch must be in rad: degrees?",
    ),
    "quaternion not unit": (_set("qw", 6, 2.0), "columns 'qw', 'qx', 'qy', 'qz', row 6 (line 7): norm 2;"),
    "millimetres": (
        _scale("x y z", 1000.0),
        "column 'x', row 2 (line 3): 500 m/s between rows is beyond ±50",
    ),
    "mm/s": (_add("vx vy vz", 500.0), "column 'vx', row 1 (line 2): 500 m/s is beyond ±50"),
    "deg/s": (
        _both(_add("p q r"), _set("r", 9, 90.0)),
        "column 'r', row 9 (line 10): 90 rad/s is beyond ±35",
    ),
}


@pytest.mark.parametrize("case", list(BAD_LOGS))
def test_a_bad_log_is_refused_naming_the_column_and_the_row(tmp_path, capsys, case):
    edit, message = BAD_LOGS[case]
    columns = _good()
    edit(columns)
    log = _write(tmp_path / "bad.csv", columns)
    assert_usage_error(["estimate", str(log), "--output", str(tmp_path / "out")], message, capsys)
    assert not (tmp_path / "out").exists()


def test_a_row_of_the_wrong_length_and_a_log_too_short_are_refused(tmp_path, capsys):
    log = _write(tmp_path / "short.csv", _good(1))
    assert_usage_error(["estimate", str(log)], "1 data rows; a flight log needs at least 2", capsys)
    log.write_text(log.read_text() + "0.005,0,0,1\n")
    assert_usage_error(["estimate", str(log)], "row 2 (line 3): 4 cells, the header names 12 columns", capsys)


def test_the_oracle_needs_the_true_wrench_and_evaluate_a_csv_name(tmp_path, capsys):
    log = _write(tmp_path / "flight.csv", _good())
    message = "the oracle returns the true wrench: it needs the log's columns fx, fy, fz, tx, ty, tz"
    assert_usage_error(["estimate", str(log), "--estimator", "oracle"], message, capsys)
    argv = ["evaluate", "hold", FAN_TRACKING, "--seeds", "0", "--log", "flight.txt"]
    assert_usage_error(argv, "'flight.txt' must end in .csv", capsys)


def test_euler_angles_read_as_the_quaternions_they_are(tmp_path):
    columns = _good()
    _euler(columns)
    columns["roll"], columns["yaw"] = [0.1] * 20, [3.0] * 20
    flight = read_flight_log(_write(tmp_path / "euler.csv", columns), VEHICLE)
    np.testing.assert_allclose(flight.quaternion, np.tile(quat_from_euler_zyx(0.1, 0.0, 3.0), (20, 1)))
    assert flight.period == 0.005 and flight.velocity is None and flight.wrench is None


def test_a_calibrated_vehicles_flight_is_not_recorded():
    """A log holds the reported speeds and a replay uses the nominal mixer: a calibrated vehicle's
    flight (``rotor_calibration``) would not replay as it flew, so recording it is refused by name."""
    env = gym.make("QuadWrench/FanTracking-v1", rotor_calibration=0.002)
    try:
        with pytest.raises(ValueError, match="rotor_calibration=0.002"):
            FlightRecorder(env)
    finally:
        env.close()


def _hand_written(path, columns: dict[str, list[float]]):
    """A CSV written here by hand, as a user's logger would: the header, then comma-separated numbers."""
    names = list(columns)
    lines = [",".join(names)] + [
        ",".join(f"{columns[n][k]:.12g}" for n in names) for k in range(len(columns["t"]))
    ]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_a_hand_written_logs_optional_columns_read_each_to_its_own_place(tmp_path):
    """Velocity (world, m/s), body rates (body, rad/s) and the true wrench (world, N and N·m), each column
    a value of its own, come back where their names say."""
    n = 20
    columns = {"t": [0.005 * k for k in range(n)], "x": [0.0] * n, "y": [0.0] * n, "z": [1.0] * n}
    columns |= {"qw": [1.0] * n, "qx": [0.0] * n, "qy": [0.0] * n, "qz": [0.0] * n}
    columns |= {f"w{i}": [200.0 + i] * n for i in range(1, 5)}
    names = ["vx", "vy", "vz", "p", "q", "r", "fx", "fy", "fz", "tx", "ty", "tz"]
    values = dict(zip(names, np.arange(1, 13) / 100.0, strict=True))
    columns |= {name: [float(value)] * n for name, value in values.items()}
    flight = read_flight_log(_hand_written(tmp_path / "optional.csv", columns), VEHICLE)
    np.testing.assert_array_equal(flight.motor_speeds, [[201.0, 202.0, 203.0, 204.0]] * n)
    np.testing.assert_allclose(flight.velocity, [[0.01, 0.02, 0.03]] * n)
    np.testing.assert_allclose(flight.body_rates, [[0.04, 0.05, 0.06]] * n)
    np.testing.assert_allclose(flight.wrench, [[0.07, 0.08, 0.09, 0.10, 0.11, 0.12]] * n)


@pytest.mark.parametrize("attitude", ["quaternion", "euler"])
def test_a_hand_written_log_of_a_rolled_vehicle_reads_to_its_attitude_and_force(tmp_path, attitude):
    """Conventions against a log written apart from the project's writer: a vehicle at rest, rolled 0.1
    rad about body x, its four rotors at one speed whose thrust carries its weight (4 k ω² cos φ = m g).
    Rolling right-handed about x turns the body's z axis to (0, -sin φ, cos φ), so the thrust pushes
    towards -y by m g tan φ, and whatever holds the vehicle at rest pushes +y by as much: with the
    scalar first ``qw = cos(φ/2), qx = sin(φ/2)`` (or ``roll`` φ), the reader gives that quaternion, and the
    UKF replaying the log settles at ``f = (0, m g tan φ, 0)`` (0.41 N on ardrone2) within its noise; the
    scalar-last misreading gives about -0.02 N."""
    from quad_wrench_cli.estimate import replay
    from quad_wrench_env.estimators import make_estimator
    from quad_wrench_env.vehicle import GRAVITY

    roll, n, dt = 0.1, 800, 0.005
    speed = math.sqrt(VEHICLE.mass * GRAVITY / (4.0 * VEHICLE.kf * math.cos(roll)))
    columns = {"t": [k * dt for k in range(n)], "x": [0.0] * n, "y": [0.0] * n, "z": [1.0] * n}
    if attitude == "quaternion":
        columns |= {
            "qw": [math.cos(roll / 2)] * n,
            "qx": [math.sin(roll / 2)] * n,
            "qy": [0.0] * n,
            "qz": [0.0] * n,
        }
    else:
        columns |= {"roll": [roll] * n, "pitch": [0.0] * n, "yaw": [0.0] * n}
    columns |= {f"w{i}": [speed] * n for i in range(1, 5)}
    optional = {"vx": 0.0, "vy": 0.0, "vz": 0.0, "p": 0.0, "q": 0.0, "r": 0.0}  # at rest
    optional |= {
        "fx": 0.0,
        "fy": VEHICLE.mass * GRAVITY * math.tan(roll),
        "fz": 0.0,
        "tx": 0.0,
        "ty": 0.0,
        "tz": 0.0,
    }
    columns |= {name: [value] * n for name, value in optional.items()}
    flight = read_flight_log(_hand_written(tmp_path / "rolled.csv", columns), VEHICLE)
    for field, names in (("velocity", "vx vy vz"), ("body_rates", "p q r"), ("wrench", "fx fy fz tx ty tz")):
        np.testing.assert_allclose(
            getattr(flight, field), [[optional[k] for k in names.split()]] * n, rtol=1e-11
        )
    np.testing.assert_allclose(
        flight.quaternion, [[math.cos(roll / 2), math.sin(roll / 2), 0.0, 0.0]] * n, atol=1e-12
    )
    np.testing.assert_array_equal(flight.motor_speeds, np.full((n, 4), float(f"{speed:.12g}")))
    assert flight.period == pytest.approx(dt)
    wrenches, _ = replay(flight, make_estimator("ukf", VEHICLE, flight.period), VEHICLE)
    settled = wrenches[-200:].mean(axis=0)
    holding = VEHICLE.mass * GRAVITY * math.tan(roll)
    np.testing.assert_allclose(settled[:3], (0.0, holding, 0.0), atol=0.05 * holding)
    np.testing.assert_allclose(settled[3:], 0.0, atol=1e-3)
