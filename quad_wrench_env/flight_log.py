"""Flight logs: what a wrench estimator sees in one flight, as CSV, one row per sample.

The file has one header line of column names (any order) and then one row per sample, comma-separated
numbers in SI units:

==============================  =======  ===========================================================
column                          unit     what
==============================  =======  ===========================================================
``t``                           s        time; increasing, each step within 0.5-1.5x the median step
``x``, ``y``, ``z``             m        measured position of the centre of mass (world frame, z up)
``qw``, ``qx``, ``qy``, ``qz``  1        measured attitude, unit quaternion body -> world (Hamilton)
or ``roll``, ``pitch``, ``yaw`` rad      the same attitude as ZYX Euler angles
``w1``, ``w2``, ``w3``, ``w4``  rad/s    motor speeds as the vehicle reports them (>= 0), in the
                                         project's motor order: hubs at body ``(x, y)`` = arm times
                                         ``(1, 1)``, ``(-1, 1)``, ``(-1, -1)``, ``(1, -1)``
                                         (:mod:`quad_wrench_env.vehicle`)
``vx``, ``vy``, ``vz``          m/s      optional: measured velocity (world frame)
``p``, ``q``, ``r``             rad/s    optional: measured body rates
``fx`` ... ``tz``               N, N·m   optional: ``fx, fy, fz, tx, ty, tz``, the true external
                                         wrench about the centre of mass (world frame), to compare with
==============================  =======  ===========================================================

The first row starts the estimator (at rest at that pose, with no external wrench); every later row is
one estimator step of the median time step: the pose measured at its end and the motor speeds over
it. An optional group comes whole or not at all; any other column is refused by name.

:func:`read_flight_log` refuses a bad log with a ``ValueError`` that names the column and the row (the
1-based data row and the file's line, the header being line 1): a missing column, a cell that is no
finite number, a time that is not after the row before (unsorted or duplicate), a gap or an uneven
step, and the units it can tell are wrong: times in milliseconds (a median step above 0.1 s), degrees
for Euler angles (beyond ±π roll, ±π/2 pitch, ±2π yaw), RPM for motor speeds (above twice the vehicle's
top speed), millimetres or mm/s (a position moving, or a velocity, faster than 50 m/s), deg/s for body
rates (beyond ±35 rad/s, 2000 °/s), and a quaternion that is not of unit norm (within 1e-3).

:class:`FlightRecorder` records the flight of a single env in this layout, at the physics rate, from
what its estimator is handed (``quad-wrench evaluate ... --log FILE.csv``), so that replaying the log
(``quad-wrench estimate``) gives the live run's estimates to rounding.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from quad_wrench_env.estimators.bank import EstimatorInputs
from quad_wrench_env.rotations import quat_from_euler_zyx
from quad_wrench_env.vehicle import VehicleParams

TIME = "t"
POSITION = ("x", "y", "z")
QUATERNION = ("qw", "qx", "qy", "qz")
EULER_ANGLES = ("roll", "pitch", "yaw")
MOTOR_SPEEDS = ("w1", "w2", "w3", "w4")
VELOCITY = ("vx", "vy", "vz")
BODY_RATES = ("p", "q", "r")
WRENCH = ("fx", "fy", "fz", "tx", "ty", "tz")
OPTIONAL = (VELOCITY, BODY_RATES, WRENCH)
"""The optional groups of columns, each whole or absent."""
COLUMNS = (TIME, *POSITION, *QUATERNION, *EULER_ANGLES, *MOTOR_SPEEDS, *VELOCITY, *BODY_RATES, *WRENCH)
"""Every column a log may have."""

MAX_PERIOD = 0.1
"""s: the longest median time step taken for seconds (a longer one reads as milliseconds)."""
STEP_RANGE = (0.5, 1.5)
"""Each time step as a multiple of the median step: outside, a gap (or an uneven step)."""
MAX_SPEED = 50.0
"""m/s: the fastest position change or velocity taken for metres (a faster one reads as mm)."""
MAX_BODY_RATE = 35.0
"""rad/s (2000 °/s, a gyroscope's range): faster reads as deg/s."""
EULER_LIMITS = {"roll": math.pi, "pitch": 0.5 * math.pi, "yaw": 2.0 * math.pi}
"""rad: the largest magnitude of each Euler angle (beyond: degrees)."""
RPM_FACTOR = 2.0
"""A motor speed above this times the vehicle's top speed reads as RPM."""
UNIT_NORM_TOLERANCE = 1e-3


@dataclass
class FlightLog:
    """One flight as an estimator sees it: arrays over ``n`` samples (SI units, see the module)."""

    time: np.ndarray
    """(n,) s"""
    position: np.ndarray
    """(n, 3) m, world frame"""
    quaternion: np.ndarray
    """(n, 4) ``[w, x, y, z]``, body -> world"""
    motor_speeds: np.ndarray
    """(n, 4) rad/s"""
    velocity: np.ndarray | None = None
    """(n, 3) m/s, world frame, where measured"""
    body_rates: np.ndarray | None = None
    """(n, 3) rad/s, where measured"""
    wrench: np.ndarray | None = None
    """(n, 6) the true ``[f, τ]`` (N, N·m, world frame), where known"""

    @property
    def period(self) -> float:
        """The estimator's time step (s): the median step, its rate rounded to 1e-6 Hz (so that a log
        written at 200 Hz gives exactly ``1 / 200``)."""
        return 1.0 / round(1.0 / float(np.median(np.diff(self.time))), 6)


# -- reading ---------------------------------------------------------------------------------------
def read_flight_log(path: str | Path, vehicle: VehicleParams) -> FlightLog:
    """The flight log at ``path``, checked (module docstring) against ``vehicle``'s motor speeds;
    ``ValueError`` naming the column and the row for a bad one."""
    path = Path(path)
    with path.open(newline="") as handle:
        reader = csv.reader(handle)
        header = [name.strip() for name in next(reader, [])]
        rows = [(reader.line_num, row) for row in reader if row]
    _check_header(path, header)
    if len(rows) < 2:
        raise ValueError(f"{path}: {len(rows)} data rows; a flight log needs at least 2 (module docs)")
    data = _numbers(path, header, rows)
    lines = [line for line, _ in rows]
    _check_units(path, data, lines, _check_time(path, data[TIME], lines))
    speeds = _block(data, MOTOR_SPEEDS)
    _check_motor_speeds(path, speeds, lines, vehicle)
    return FlightLog(
        data[TIME],
        _block(data, POSITION),
        _attitude(path, data, lines),
        speeds,
        *(_block(data, group) if group[0] in data else None for group in OPTIONAL),
    )


def _check_header(path: Path, header: list[str]) -> None:
    """Known columns, each once; the needed ones; optional groups whole."""
    where = f"{path}: header (line 1)"
    unknown = [name for name in header if name not in COLUMNS]
    if unknown:
        raise ValueError(f"{where}: unknown column {unknown[0]!r}; allowed: {', '.join(COLUMNS)}")
    repeated = [name for name in header if header.count(name) > 1]
    if repeated:
        raise ValueError(f"{where}: column {repeated[0]!r} appears more than once")
    columns = set(header)
    attitude = QUATERNION if QUATERNION[0] in columns or not columns & set(EULER_ANGLES) else EULER_ANGLES
    for name in (TIME, *POSITION, *attitude, *MOTOR_SPEEDS):
        if name not in columns:
            raise ValueError(
                f"{where}: missing column {name!r}; needed: t, x, y, z, the attitude (qw, qx, qy, qz or "
                "roll, pitch, yaw) and w1, w2, w3, w4"
            )
    if columns & set(QUATERNION) and columns & set(EULER_ANGLES):
        raise ValueError(f"{where}: give the attitude once, as qw, qx, qy, qz or as roll, pitch, yaw")
    for group in OPTIONAL:
        given = [name for name in group if name in columns]
        if given and len(given) < len(group):
            missing = next(name for name in group if name not in columns)
            raise ValueError(
                f"{where}: missing column {missing!r}; {', '.join(group)} come together or not at all"
            )


def _row(index: int, lines: list[int]) -> str:
    """Where data row ``index`` (0-based) is: its 1-based number and its line in the file."""
    return f"row {index + 1} (line {lines[index]})"


def _numbers(path: Path, header: list[str], rows: list[tuple[int, list[str]]]) -> dict[str, np.ndarray]:
    """Each column's finite numbers."""
    lines = [line for line, _ in rows]
    values = np.empty((len(rows), len(header)))
    for index, (_, cells) in enumerate(rows):
        if len(cells) != len(header):
            raise ValueError(
                f"{path}: {_row(index, lines)}: {len(cells)} cells, the header names {len(header)} columns"
            )
        for j, cell in enumerate(cells):
            try:
                value = float(cell)
            except ValueError:
                value = None
            if value is None or not math.isfinite(value):
                raise ValueError(
                    f"{path}: column {header[j]!r}, {_row(index, lines)}: {cell.strip()!r}; allowed: finite "
                    "numbers"
                )
            values[index, j] = value
    return {name: values[:, j] for j, name in enumerate(header)}


def _check_time(path: Path, t: np.ndarray, lines: list[int]) -> float:
    """Times in seconds, increasing at a steady rate; returns the median step."""
    steps = np.diff(t)
    for k in np.flatnonzero(steps <= 0.0)[:1]:
        now, before = float(t[k + 1]), float(t[k])
        what = (
            "a duplicate time" if now == before else f"earlier than the row before ({before!r} s): unsorted"
        )
        raise ValueError(
            f"{path}: column 't', {_row(k + 1, lines)}: {now!r} s is {what}; allowed: times increasing row "
            "by row"
        )
    median = float(np.median(steps))
    if median > MAX_PERIOD:
        k = int(np.argmax(steps > MAX_PERIOD))
        raise ValueError(
            f"{path}: column 't', {_row(k + 1, lines)}: a step of {steps[k]:.6g} from the row before "
            f"(median {median:.6g}); t must be in seconds, at most {MAX_PERIOD} s a step: milliseconds? "
            "(divide by 1000)"
        )
    low, high = STEP_RANGE
    for k in np.flatnonzero((steps < low * median) | (steps > high * median))[:1]:
        what = "a gap" if steps[k] > median else "an uneven step"
        raise ValueError(
            f"{path}: column 't', {_row(k + 1, lines)}: {what} of {steps[k]:.6g} s from the row before, "
            f"{steps[k] / median:.3g} times the median step {median:.6g} s; allowed: {low}-{high} times "
            "the median (an estimator steps at a fixed rate: split the log there)"
        )
    return median


def _check_units(path: Path, data: dict[str, np.ndarray], lines: list[int], period: float) -> None:
    """Positions and velocities in metres, body rates and Euler angles in radians (where it can tell)."""
    limits = [
        (POSITION, MAX_SPEED, "m/s between rows", "metres: millimetres? (divide by 1000)"),
        (VELOCITY, MAX_SPEED, "m/s", "m/s: mm/s? (divide by 1000)"),
        (BODY_RATES, MAX_BODY_RATE, "rad/s", "rad/s: deg/s? (rad/s = deg/s·π/180)"),
        *(((name,), limit, "rad", "rad: degrees? (rad = deg·π/180)") for name, limit in EULER_LIMITS.items()),
    ]
    for names, limit, unit, expected in limits:
        for name in (name for name in names if name in data):
            moving = name in POSITION  # a position's unit shows in how fast it changes
            values = np.diff(data[name]) / period if moving else data[name]
            for k in np.flatnonzero(np.abs(values) > limit)[:1]:
                raise ValueError(
                    f"{path}: column {name!r}, {_row(k + moving, lines)}: {values[k]:.6g} {unit} is beyond "
                    f"±{limit:.6g}; {name} must be in {expected}"
                )


def _check_motor_speeds(path: Path, speeds: np.ndarray, lines: list[int], vehicle: VehicleParams) -> None:
    top = vehicle.max_rotor_speed
    highest = RPM_FACTOR * top
    for k, i in np.argwhere((speeds < 0.0) | (speeds > highest))[:1]:
        value = speeds[k, i]
        what = (
            "below 0 (give speed magnitudes)"
            if value < 0
            else f"more than {RPM_FACTOR:g} times the {vehicle.name}'s top speed {top:.6g} rad/s: RPM? "
            "(rad/s = RPM·π/30)"
        )
        raise ValueError(
            f"{path}: column {MOTOR_SPEEDS[i]!r}, {_row(k, lines)}: {value:.6g} is {what}; allowed: motor "
            f"speeds in rad/s, 0 to {highest:.6g}"
        )


def _attitude(path: Path, data: dict[str, np.ndarray], lines: list[int]) -> np.ndarray:
    """(n, 4) unit quaternions ``[w, x, y, z]`` from the quaternion or the Euler-angle columns."""
    if EULER_ANGLES[0] in data:
        return quat_from_euler_zyx(*(data[name] for name in EULER_ANGLES))
    q = _block(data, QUATERNION)
    norm = np.linalg.norm(q, axis=1)
    for k in np.flatnonzero(np.abs(norm - 1.0) > UNIT_NORM_TOLERANCE)[:1]:
        raise ValueError(
            f"{path}: columns 'qw', 'qx', 'qy', 'qz', {_row(k, lines)}: norm {norm[k]:.6g}; allowed: a unit "
            f"quaternion [w, x, y, z] (norm within {UNIT_NORM_TOLERANCE:g} of 1)"
        )
    return q / norm[:, None]


def _block(data: dict[str, np.ndarray], names: tuple[str, ...]) -> np.ndarray:
    return np.column_stack([data[name] for name in names])


# -- writing ---------------------------------------------------------------------------------------
def write_flight_log(path: str | Path, log: FlightLog) -> None:
    """``log`` as CSV at ``path`` (its folder made where missing), the attitude as quaternions and every
    number as Python's ``repr`` writes it (read back to the same bits)."""
    parts = [((TIME,), log.time[:, None]), (POSITION, log.position), (QUATERNION, log.quaternion)]
    parts += [(MOTOR_SPEEDS, log.motor_speeds)]
    optional = zip(OPTIONAL, (log.velocity, log.body_rates, log.wrench), strict=True)
    parts += [(names, values) for names, values in optional if values is not None]
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    table = np.column_stack([values for _, values in parts])
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow([name for names, _ in parts for name in names])
        writer.writerows([repr(float(v)) for v in row] for row in table)


# -- recording -------------------------------------------------------------------------------------
class FlightRecorder:
    """Records a single env's flight as a :class:`FlightLog`: installed in place of the env's estimator
    bank, it hands every call on to it and keeps, at each reset and physics step, the time, the pose and
    the motor speeds the estimator is handed (the speeds as the vehicle reports them, from which the
    estimator's thrust and torque come), the measured velocity and body rates where the sensors make
    them, and the true wrench (the reset's once the env has computed it: pass :meth:`on_step` to
    :func:`~quad_wrench_env.agents.evaluate.run_episode`)."""

    def __init__(self, env: gym.Env) -> None:
        calibration = env.unwrapped.cfg.resolved_rotor_calibration()
        if calibration is not None:
            raise ValueError(
                f"rotor_calibration={calibration!r}: a log holds the reported motor speeds, which a replay "
                "turns into thrust and torque through the nominal mixer, not the calibrated one; record "
                "with rotor_calibration=None (crazyflie2 is calibrated by default)"
            )
        self._fleet = env.unwrapped.fleet
        self._inner = self._fleet.estimator
        self._fleet.estimator = self
        self._measures_motion = self._fleet.cfg.sensors.state_estimator
        self._rows: list[list[np.ndarray]] = []

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)

    def reset(self, index: int, position: np.ndarray, quaternion_wxyz: np.ndarray) -> None:
        """Reset the estimator; a new flight starts (at rest: velocity and body rates 0)."""
        self._inner.reset(index, position, quaternion_wxyz)
        self._rows = []
        rest = np.zeros(3) if self._measures_motion else None
        self._record(position, quaternion_wxyz, rest, rest, None)

    def step(self, inputs: EstimatorInputs) -> None:
        """Step the estimator and record the step's sensor data."""
        self._inner.step(inputs)
        motion = [None if v is None else v[0] for v in (inputs.velocities, inputs.body_rates)]
        self._record(inputs.positions[0], inputs.quaternions[0], *motion, self._fleet.wrench_true[0])

    def on_step(self, env: gym.Env, info: dict[str, Any]) -> None:
        """``run_episode``'s ``on_step``: after a reset, give its row the fleet's true wrench (computed
        after the estimator's reset)."""
        if self._rows and self._rows[0][-1] is None:
            self._rows[0][-1] = self._fleet.wrench_true[0].copy()

    def _record(self, position, quaternion, velocity, body_rates, wrench) -> None:
        fleet = self._fleet
        speeds = fleet.motor_sensor.measure(fleet.rotors.speeds[0])
        row = [np.array((fleet.time[0],)), position, quaternion, speeds, velocity, body_rates, wrench]
        self._rows.append([None if v is None else np.array(v, dtype=float) for v in row])

    def log(self) -> FlightLog:
        """The flight recorded since the last reset."""
        columns = [
            np.array(values) if values[0] is not None else None for values in zip(*self._rows, strict=True)
        ]
        time, position, quaternion, speeds, velocity, body_rates, wrench = columns
        return FlightLog(time[:, 0], position, quaternion, speeds, velocity, body_rates, wrench)
