"""Mutation check: small deliberate bugs, each run against the tests that should catch it.

    python scripts/mutation_check.py [--check] [--only NAME ...] [--jobs-timeout SECONDS]

Each mutation is one or more exact text edits (to the one implementation: the kernels run every
physics step; a few pieces, such as policy loading, are plain Python) applied to a copy of the
checkout's tracked files in a temporary folder; the listed test files then run there (``pytest -x``,
the copy's package first on the path, numba and composed-step caches of its own). A mutation whose
tests fail is killed (the first failing test is printed); one whose tests pass survived. ``--check``
only verifies that every edit's text occurs exactly once (fast). Not part of CI: it compiles mutated
kernels and takes minutes per mutation.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Mutation:
    name: str
    kind: str
    edits: tuple[tuple[str, str, str], ...]
    """``(file, text, replacement)``; each text must occur exactly once in its file."""
    tests: tuple[str, ...]


ENGINE = "quad_wrench_env/engine/kernels.py"
ACTIONS = "quad_wrench_env/engine/actions.py"
FAN = "quad_wrench_env/disturbances/fan.py"
JET = "quad_wrench_env/disturbances/jet_kernels.py"
REFERENCE = ("tests/test_reference_dynamics.py", "tests/test_reference_task.py")

MUTATIONS = (
    Mutation(
        "learned estimator: the body torque turned by Rᵀ instead of R",
        "estimator",
        (
            (
                "quad_wrench_env/estimators/learned_kernel.py",
                "r[3 * i] * torque[0] + r[3 * i + 1] * torque[1] + r[3 * i + 2] * torque[2]",
                "r[i] * torque[0] + r[3 + i] * torque[1] + r[6 + i] * torque[2]",
            ),
        ),
        ("tests/test_learned_estimator.py",),
    ),
    Mutation(
        "learned estimator: the window forces' tent one step late",
        "estimator",
        (
            (
                "quad_wrench_env/estimators/learned_kernel.py",
                "tent += (size - abs(back - (size - 1)))",
                "tent += (size - abs(back - size))",
            ),
        ),
        ("tests/test_learned_estimator.py",),
    ),
    Mutation(
        "learned estimator: the trackers' velocity corrected with the position's gain",
        "estimator",
        (
            (
                "quad_wrench_env/estimators/learned_kernel.py",
                "state[1] = velocity + gains[j, 1] * innovation",
                "state[1] = velocity + gains[j, 0] * innovation",
            ),
        ),
        ("tests/test_learned_estimator.py",),
    ),
    Mutation(
        "learned estimator: every axis's mixture weighed by the x axis's logits",
        "estimator",
        (
            (
                "quad_wrench_env/estimators/learned_kernel.py",
                "logits = read[OUTPUTS + i * SOURCES : OUTPUTS + (i + 1) * SOURCES]",
                "logits = read[OUTPUTS : OUTPUTS + SOURCES]",
            ),
        ),
        ("tests/test_learned_estimator.py",),
    ),
    Mutation(
        "residual: the correction not scaled",
        "controller",
        (
            (
                "quad_wrench_env/control/residual.py",
                "self.base.actions(observations) + self.scale * actions",
                "self.base.actions(observations) + actions",
            ),
        ),
        ("tests/test_residual.py",),
    ),
    Mutation(
        "residual: the acceleration-level correction never reaches the PID",
        "controller",
        (
            (
                "quad_wrench_env/control/pid_controller.py",
                "        if offsets is not None:\n            desired += offsets\n",
                "",
            ),
        ),
        ("tests/test_residual.py",),
    ),
    Mutation(
        "residual: the acceleration level's yaw-rate correction not scaled",
        "controller",
        (
            (
                "quad_wrench_env/control/residual.py",
                "flown[:, YAW_RATE] += self.scale * actions[:, 3]",
                "flown[:, YAW_RATE] += actions[:, 3]",
            ),
        ),
        ("tests/test_residual.py",),
    ),
    Mutation(
        "study: the sweep keeps the worst rate",
        "training",
        (
            (
                "quad_wrench_env/agents/study.py",
                "sign = 1.0 if lower_is_better else -1.0",
                "sign = -1.0 if lower_is_better else 1.0",
            ),
        ),
        ("tests/test_study.py",),
    ),
    Mutation(
        "motor spin signs flipped",
        "vehicle",
        (
            (
                "quad_wrench_env/vehicle.py",
                "MOTOR_SPIN = np.array((1.0, -1.0, 1.0, -1.0))",
                "MOTOR_SPIN = np.array((-1.0, 1.0, -1.0, 1.0))",
            ),
        ),
        ("tests/test_vehicle.py", *REFERENCE),
    ),
    Mutation(
        "hover speed from half the weight",
        "vehicle",
        (
            (
                "quad_wrench_env/vehicle.py",
                "return math.sqrt(self.mass * GRAVITY / (4.0 * self.kf))",
                "return math.sqrt(0.5 * self.mass * GRAVITY / (4.0 * self.kf))",
            ),
        ),
        ("tests/test_vehicle.py", "tests/test_autopilot.py"),
    ),
    Mutation(
        "motor lag up uses the down constant",
        "rotors",
        (
            (
                "quad_wrench_env/rotors.py",
                "self._alpha_up = 1.0 - math.exp(-dt / vehicle.motor_time_constant_up)",
                "self._alpha_up = 1.0 - math.exp(-dt / (2.0 * vehicle.motor_time_constant_up))",
            ),
        ),
        ("tests/test_physics.py", "tests/test_vehicle.py", *REFERENCE),
    ),
    Mutation(
        "rotor drag sign flipped",
        "rotors",
        (
            (
                "quad_wrench_env/rotors.py",
                "return -(self._drag_coefficient * self.speeds[index])[:, :, None] * in_plane",
                "return (self._drag_coefficient * self.speeds[index])[:, :, None] * in_plane",
            ),
            (
                ENGINE,
                "                k_d = rotor_drag * speeds[m, p]",
                "                k_d = -rotor_drag * speeds[m, p]",
            ),
        ),
        ("tests/test_physics.py", "tests/test_open_engine.py"),
    ),
    Mutation(
        "autopilot gyroscopic term dropped",
        "autopilot",
        (
            (
                ENGINE,
                "torque[0] + c0,\n                torque[1] + c1,\n                torque[2] + c2,",
                "torque[0],\n                torque[1],\n                torque[2],",
            ),
        ),
        ("tests/test_autopilot.py", *REFERENCE),
    ),
    Mutation(
        "attitude action's roll sign flipped",
        "actions",
        (
            (
                ENGINE,
                "roll, pitch, yaw_d = a[0] * scales[4], a[1] * scales[4]",
                "roll, pitch, yaw_d = -a[0] * scales[4], a[1] * scales[4]",
            ),
        ),
        REFERENCE,
    ),
    Mutation(
        "wrench action's yaw scaled by the roll coefficient",
        "actions",
        (
            (
                ENGINE,
                "                a[3] * scales[8],",
                "                a[3] * scales[6],",
            ),
        ),
        REFERENCE,
    ),
    Mutation(
        "velocity action's yaw rate ignored",
        "actions",
        ((ENGINE, "                yaw_rate = a[3] * scales[3]", "                yaw_rate = 0.0 * a[3]"),),
        REFERENCE,
    ),
    Mutation(
        "motor action maps to half speed",
        "actions",
        (
            (
                ENGINE,
                "command[i] = 0.5 * (a[i] + 1.0) * scales[9]",
                "command[i] = 0.25 * (a[i] + 1.0) * scales[9]",
            ),
        ),
        REFERENCE,
    ),
    Mutation(
        "fan transit delay ignores the core",
        "fan",
        (
            (JET, "        return x / u0", "        return 0.5 * x / u0"),
            (
                FAN,
                "return np.where(x <= core, x / u0, core / u0 + beyond)",
                "return np.where(x <= core, 0.5 * x / u0, core / u0 + beyond)",
            ),
        ),
        ("tests/test_fan.py", "tests/test_reference_dynamics.py"),
    ),
    Mutation(
        "fan transit delay beyond the core without asinh",
        "fan",
        (
            (
                JET,
                "integral = 0.5 * x * b + scale * (math.asinh(c * x / radius) - _CORE_INTEGRAL)",
                "integral = 0.5 * x * b",
            ),
            (
                FAN,
                "xi) + self._radius2 / (2.0 * c) * np.arcsinh(c * xi / radius)",
                "xi)",
            ),
        ),
        ("tests/test_fan.py", "tests/test_reference_dynamics.py"),
    ),
    Mutation(
        "jet profile Gaussian in r, not r²",
        "fan",
        (
            (
                JET,
                "speed = u_c * math.exp(-(dy * dy + dz * dz) / (b * b)) if x > 0.0 else 0.0",
                "speed = u_c * math.exp(-math.sqrt(dy * dy + dz * dz) / b) if x > 0.0 else 0.0",
            ),
            (
                FAN,
                "speed = np.where(x > 0.0, u_c * np.exp(-(dy * dy + dz * dz) / (b * b)), 0.0)",
                "speed = np.where(x > 0.0, u_c * np.exp(-np.sqrt(dy * dy + dz * dz) / b), 0.0)",
            ),
        ),
        ("tests/test_fan.py",),
    ),
    Mutation(
        "turbulence without sqrt(1 - a²)",
        "fan",
        (
            (
                JET,
                "noise[n, i] = decay * noise[n, i] + math.sqrt(1.0 - decay * decay) * normals[n, i]",
                "noise[n, i] = decay * noise[n, i] + normals[n, i]",
            ),
        ),
        ("tests/test_fan.py",),
    ),
    Mutation(
        "fan walks: quadratic drag's change along the jet not doubled",
        "fan",
        (
            (
                FAN,
                "QuadraticDrag(vehicle.drag_area, len(points)).coefficient * np.diag((2.0, 1.0, 1.0))",
                "QuadraticDrag(vehicle.drag_area, len(points)).coefficient * np.diag((1.0, 1.0, 1.0))",
            ),
        ),
        ("tests/test_fan_tracking_task.py",),
    ),
    Mutation(
        "matched walks: the forgetting's weights swapped",
        "estimator",
        (
            (
                "quad_wrench_env/estimators/walks.py",
                "value = forgetting * walks[block, i, j] + (1.0 - forgetting) * change_i * change_j",
                "value = (1.0 - forgetting) * walks[block, i, j] + forgetting * change_i * change_j",
            ),
        ),
        ("tests/test_adaptive_walks.py",),
    ),
    Mutation(
        "matched walks: the UKF on lanes adds no off-diagonal walk",
        "estimator",
        (
            (
                "quad_wrench_env/estimators/ukf_lanes_kernel.py",
                "for j in range(3):\n                    for row, block in ((12, 1), (15, 0)):",
                "for j in (i,):\n                    for row, block in ((12, 1), (15, 0)):",
            ),
        ),
        ("tests/test_lanes.py",),
    ),
    Mutation(
        "rotor calibration: the preset's ignored",
        "rotors",
        (
            (
                "quad_wrench_env/engine/env_config.py",
                "            return CALIBRATED_ROTORS.get(self.vehicle)",
                "            return None",
            ),
        ),
        ("tests/test_rotor_calibration_default.py",),
    ),
    Mutation(
        "fleet: the contact force survives a vehicle's restart",
        "reset",
        (("quad_wrench_env/engine/fleet.py", "        self.contact_force[index] = 0.0\n", "\n"),),
        ("tests/test_reset_equivalence.py",),
    ),
    Mutation(
        "pid: the integral survives reset",
        "reset",
        (
            (
                "quad_wrench_env/control/pid_controller.py",
                "        self._integral[:] = 0.0\n        self.reference.reset()",
                "        self.reference.reset()",
            ),
        ),
        ("tests/test_reset_equivalence.py",),
    ),
    Mutation(
        "mpc: the solver's warm start survives reset",
        "reset",
        (
            (
                "quad_wrench_env/control/mpc_controller.py",
                "        self.qps = [self._fresh() for _ in range(self.count)]",
                "        self.qps = self.qps or [self._fresh() for _ in range(self.count)]",
            ),
        ),
        ("tests/test_reset_equivalence.py",),
    ),
    Mutation(
        "mpc: a batch's restarted vehicle keeps its solver's warm start",
        "reset",
        (
            (
                "quad_wrench_env/control/mpc_controller.py",
                "            self.qps[vehicle] = self._fresh()\n",
                "            pass\n",
            ),
        ),
        ("tests/test_mpc.py", "tests/test_reset_equivalence.py"),
    ),
    Mutation(
        "mpc: a batch's restarted vehicle keeps its reference history",
        "reset",
        (("quad_wrench_env/control/mpc_controller.py", "        self.reference.restart(index)\n", ""),),
        ("tests/test_mpc.py",),
    ),
    Mutation(
        "flight log: the quaternion's scalar last, in the writer and the reader alike",
        "convention",
        (
            (
                "quad_wrench_env/flight_log.py",
                'QUATERNION = ("qw", "qx", "qy", "qz")',
                'QUATERNION = ("qx", "qy", "qz", "qw")',
            ),
        ),
        ("tests/test_flight_log.py",),
    ),
    Mutation(
        "sensors: body rates measured with the velocity's noise",
        "settings",
        (
            (
                ENGINE,
                "motion[m, 3 + i] = body_rates[m, i] + sensing[5] * draws[9 + i]",
                "motion[m, 3 + i] = body_rates[m, i] + sensing[4] * draws[9 + i]",
            ),
        ),
        ("tests/test_sensor_settings.py",),
    ),
    Mutation(
        "sensors: the motion capture one step less late than told",
        "settings",
        (
            (
                ENGINE,
                "            line[0] = (line[0] + 1.0) % latency",
                "            line[0] = (line[0] + 1.0) % max(latency - 1, 1)",
            ),
        ),
        ("tests/test_compiled_step.py",),
    ),
    Mutation(
        "study: only each run's base seed counted as trained on",
        "hygiene",
        (
            (
                "quad_wrench_env/agents/study.py",
                "used = {s + i for s in seeds for i in range(self._vehicles())}",
                "used = set(seeds)",
            ),
        ),
        ("tests/test_study.py",),
    ),
    Mutation(
        "study: the selection seeds of the first arm only",
        "hygiene",
        (
            (
                "quad_wrench_env/agents/study.py",
                "used |= {s for label in self.arms for s in self.run_config(label, seeds[0]).evaluation"
                ".seeds}",
                "used |= set(self.run_config(next(iter(self.arms)), seeds[0]).evaluation.seeds)",
            ),
        ),
        ("tests/test_study.py",),
    ),
    Mutation(
        "sensor block: the motor speeds over one level, not the top speed",
        "observation",
        (
            (
                ENGINE,
                "            row[i] = quantized_speed(speeds[m, i], levels, step) / top",
                "            row[i] = quantized_speed(speeds[m, i], levels, step) / step",
            ),
        ),
        ("tests/test_sensor_block.py",),
    ),
    Mutation(
        "sensor block: kept across a vehicle's restart",
        "observation",
        (("quad_wrench_env/engine/fleet.py", "        self.sensor_frames[index] = 0.0\n", "\n"),),
        ("tests/test_sensor_block.py",),
    ),
    Mutation(
        "pid: the thrust of the unclipped acceleration through the clipped tilt",
        "controller",
        (
            (
                "quad_wrench_env/control/pid_controller.py",
                "attitude_from_acceleration(desired[n], yaw, self._mass, self._max_tilt)",
                "attitude_from_acceleration(desired[n], yaw, self._mass)",
            ),
        ),
        ("tests/test_tilt_limit_height.py",),
    ),
    Mutation(
        "body drag linear in airspeed",
        "drag",
        (
            (
                "quad_wrench_env/disturbances/drag.py",
                "return (self.coefficient * speed)[..., None] * relative_air_velocity",
                "return self.coefficient * relative_air_velocity",
            ),
            (
                ENGINE,
                "            magnitude = math.sqrt(rel0 * rel0 + rel1 * rel1 + rel2 * rel2)",
                "            magnitude = 1.0",
            ),
        ),
        ("tests/test_physics.py", "tests/test_open_engine.py"),
    ),
    Mutation(
        "drag ignores the body's rotation",
        "drag",
        (
            (
                "quad_wrench_env/engine/fleet.py",
                "+ cross(state.angular_velocity[:, None, :], offsets)",
                "+ 0.0 * offsets",
            ),
            (
                ENGINE,
                "            rel1 = air[m, p, 1] - (velocity[m, 1] + w1)",
                "            rel1 = air[m, p, 1] - velocity[m, 1]",
            ),
        ),
        ("tests/test_physics.py", "tests/test_reference_dynamics.py"),
    ),
    Mutation(
        "motor speeds fed unquantized",
        "sensors",
        (
            (
                "quad_wrench_env/sensors.py",
                "return min(max(np.rint(speed / step), 0.0), levels) * step",
                "return min(max(speed / step, 0.0), levels) * step",
            ),
        ),
        ("tests/test_sensors_payload.py", "tests/test_reference_estimators.py"),
    ),
    Mutation(
        "motion capture noise twice its setting",
        "sensors",
        (
            (
                ENGINE,
                "measured_position[m, i] = pose[i] + position_noise * draws[i]",
                "measured_position[m, i] = pose[i] + 2.0 * position_noise * draws[i]",
            ),
        ),
        ("tests/test_sensors_payload.py", "tests/test_compiled_step.py"),
    ),
    Mutation(
        "UKF gyroscopic sign flipped",
        "ukf",
        (
            (
                "quad_wrench_env/estimators/ukf_kernel.py",
                "            torque[0] -= om1 * j2 - om2 * j1",
                "            torque[0] += om1 * j2 - om2 * j1",
            ),
            (
                "quad_wrench_env/estimators/ukf_lanes_kernel.py",
                "torque = torque + body_torque[i] - gyroscopic[i]",
                "torque = torque + body_torque[i] + gyroscopic[i]",
            ),
        ),
        ("tests/test_ukf.py", "tests/test_reference_estimators.py"),
    ),
    Mutation(
        "UKF force random walk 100x smaller",
        "ukf",
        (
            (
                "quad_wrench_env/estimators/noise.py",
                '    "force_walk": 4e-3,',
                '    "force_walk": 4e-5,',
            ),
        ),
        ("tests/test_ukf.py", "tests/test_reference_estimators.py"),
    ),
    Mutation(
        "filter noise not sized to the vehicle",
        "ukf",
        (
            (
                "quad_wrench_env/estimators/noise.py",
                "    return force_scale, torque_scale",
                "    return 1.0, 1.0",
            ),
        ),
        ("tests/test_ukf.py", "tests/test_wrench_covariance.py"),
    ),
    Mutation(
        "observer Coriolis term dropped",
        "observer",
        (
            (
                "quad_wrench_env/estimators/observer_kernel.py",
                "        inner[0] += om[1] * j2 - om[2] * j1",
                "",
            ),
            (
                "quad_wrench_env/estimators/observer_kernel.py",
                "        inner[1] += om[2] * j0 - om[0] * j2",
                "",
            ),
            (
                "quad_wrench_env/estimators/observer_kernel.py",
                "        inner[2] += om[0] * j1 - om[1] * j0",
                "",
            ),
        ),
        ("tests/test_ekf_observer.py", "tests/test_reference_estimators.py"),
    ),
    Mutation(
        "EKF ignores the onboard body rates",
        "ekf",
        (
            (
                "quad_wrench_env/estimators/ekf_kernel.py",
                "with_velocity, with_rates = velocities.shape[0] > 0, body_rates.shape[0] > 0",
                "with_velocity, with_rates = velocities.shape[0] > 0, False",
            ),
        ),
        ("tests/test_ekf_observer.py", "tests/test_reference_estimators.py"),
    ),
    Mutation(
        "tracking reward ignores the height error",
        "rewards",
        (
            (
                "quad_wrench_env/tasks/fan_tracking.py",
                "        out[n, 0] = math.sqrt(dy * dy + dz * dz)",
                "        out[n, 0] = abs(dy)",
            ),
        ),
        ("tests/test_fan_tracking_task.py", "tests/test_reference_task.py", "tests/test_task_records.py"),
    ),
    Mutation(
        "stand-off reward rewards distance",
        "rewards",
        (
            (
                "quad_wrench_env/tasks/fan_tracking.py",
                "        out[1, n] = terms.linear_cost(",
                "        out[1, n] = -terms.linear_cost(",
            ),
        ),
        ("tests/test_fan_tracking_task.py", "tests/test_reference_task.py"),
    ),
    Mutation(
        "flip detection off",
        "terminations",
        ((ENGINE, "        elif rotation[n, 2, 2] < limits[1]:", "        elif rotation[n, 2, 2] < -2.0:"),),
        ("tests/test_reference_task.py", "tests/test_env_api.py"),
    ),
    Mutation(
        "crash height ignored",
        "terminations",
        ((ENGINE, "        if z < limits[0]:", "        if z < -100.0:"),),
        ("tests/test_reference_task.py", "tests/test_env_api.py"),
    ),
    Mutation(
        "vector env masks every vehicle's final info",
        "vector env",
        (
            (
                "quad_wrench_env/envs/vector.py",
                "final_info=final_info, _final_info=done)",
                "final_info=final_info, _final_info=done | True)",
            ),
        ),
        ("tests/test_vector_env.py", "tests/test_reference_task.py"),
    ),
    Mutation(
        "vector env keeps the ended episode's observation",
        "vector env",
        (
            (
                "quad_wrench_env/envs/vector.py",
                "return next_observations, result.rewards, terminated, truncated, info",
                "return step_observations, result.rewards, terminated, truncated, info",
            ),
            (
                "quad_wrench_env/envs/vector.py",
                "            next_observations,\n            result.observations,",
                "            result.observations,\n            result.observations,",
            ),
        ),
        ("tests/test_vector_env.py", "tests/test_reference_task.py", "tests/test_sb3.py"),
    ),
    Mutation(
        "ground effect measured to z = 0 only",
        "ground effect",
        (
            (
                "quad_wrench_env/disturbances/ground_effect.py",
                "        height = np.where(under, np.maximum(height, top), height)",
                "        height = height",
            ),
            (
                "quad_wrench_env/disturbances/ground_effect.py",
                "                    surface = max(surface, t[4])",
                "                    surface = surface",
            ),
        ),
        ("tests/test_disturbances.py",),
    ),
    Mutation(
        "Dryden filter without sqrt(1 - a²)",
        "dryden",
        (
            (
                "quad_wrench_env/disturbances/dryden.py",
                "params[i] * math.sqrt(1.0 - decay * decay) * normals[n, i]",
                "params[i] * normals[n, i]",
            ),
        ),
        ("tests/test_disturbances.py",),
    ),
    Mutation(
        "motion capture latency hands out the current pose",
        "sensors",
        (
            (
                ENGINE,
                "                pose[i], line[slot + i] = line[slot + i], pose[i]",
                "                line[slot + i] = pose[i]",
            ),
        ),
        ("tests/test_compiled_step.py",),
    ),
    Mutation(
        "a calibrated vehicle's estimators keep the nominal mixer",
        "sensors",
        (
            (
                "quad_wrench_env/rotors.py",
                "            self.sensed_allocations[index] = calibrated.allocation",
                "            self.sensed_allocations[index] = Mixer(self.vehicle).allocation",
            ),
        ),
        ("tests/test_reference_estimators.py",),
    ),
    Mutation(
        "a component's velocity kernel and its episode-start form disagree",
        "dryden",
        (
            (
                "quad_wrench_env/disturbances/dryden.py",
                "                out[n, p, i] += weather[n, i] + weather[n, 3] * gust[n, i]",
                "                out[n, p, i] += weather[n, i] + weather[n, 3] * gust[n, 2 - i]",
            ),
        ),
        ("tests/test_component_conformance.py",),
    ),
    Mutation(
        "payload weight at the centre of mass",
        "point loads",
        (
            (
                "quad_wrench_env/disturbances/payload.py",
                "        offsets = body.rotation @ self._point",
                "        offsets = 0.0 * (body.rotation @ self._point)",
            ),
            (
                "quad_wrench_env/disturbances/payload.py",
                "            out[n, 3] += o1 * payload[4]",
                "            out[n, 3] += 0.0",
            ),
        ),
        ("tests/test_sensors_payload.py", "tests/test_compiled_step.py"),
    ),
    Mutation(
        "sensors read the wind's noise columns",
        "sensors",
        ((ENGINE, "        draws = normals[m, column:]", "        draws = normals[m, 0:]"),),
        ("tests/test_reference_estimators.py", "tests/test_compiled_step.py", "tests/test_fan.py"),
    ),
    # -- issue 33: the controllers, the newer tasks' rewards and metrics, the training pipeline ------
    # (ForceExertion's and DisturbanceRejection's rewards and metrics, the PID, the MPC and the
    # policy loading have a numpy form only: one edit each)
    Mutation(
        "ForceExertion reward's exerted force sign flipped",
        "rewards",
        (
            (
                "quad_wrench_env/tasks/force_exertion.py",
                "        exerted = -view.contact_force",
                "        exerted = view.contact_force",
            ),
        ),
        ("tests/test_reward_terms_by_hand.py",),
    ),
    Mutation(
        "ForceExertion approach shaping without the discount",
        "rewards",
        (
            (
                "quad_wrench_env/tasks/force_exertion.py",
                "approach = r.discount * potential - self.potential",
                "approach = potential - self.potential",
            ),
        ),
        ("tests/test_reward_terms_by_hand.py",),
    ),
    Mutation(
        "DisturbanceRejection tracking on the horizontal error only",
        "rewards",
        (
            (
                "quad_wrench_env/tasks/disturbance_rejection.py",
                "error = np.linalg.norm(offset, axis=1)",
                "error = np.linalg.norm(offset[:, :2], axis=1)",
            ),
        ),
        ("tests/test_reward_terms_by_hand.py",),
    ),
    Mutation(
        "the shared effort term summed, not averaged (every task)",
        "rewards",
        (
            (
                "quad_wrench_env/tasks/terms.py",
                "    return -weight * (total / action.shape[0])",
                "    return -weight * total",
            ),
        ),
        ("tests/test_reward_terms_by_hand.py",),
    ),
    Mutation(
        "DisturbanceRejection's action rate: the previous action carried across a reset",
        "rewards",
        (
            (
                "quad_wrench_env/tasks/disturbance_rejection.py",
                "        self.previous_action[index] = 0.0\n",
                "",
            ),
        ),
        ("tests/test_reward_terms_by_hand.py",),
    ),
    Mutation(
        "DisturbanceRejection's action rate: the action itself, not its change",
        "rewards",
        (
            (
                "quad_wrench_env/tasks/terms.py",
                "    cost = -weight * np.mean((actions - previous) ** 2, axis=1)",
                "    cost = -weight * np.mean(actions**2, axis=1)",
            ),
        ),
        ("tests/test_reward_terms_by_hand.py",),
    ),
    Mutation(
        "ForceExertion metrics' exerted force sign flipped",
        "metrics",
        (
            (
                "quad_wrench_env/tasks/force_exertion.py",
                'exerted = -np.asarray(trace["contact_force"])',
                'exerted = np.asarray(trace["contact_force"])',
            ),
        ),
        ("tests/test_contacts.py",),
    ),
    Mutation(
        "DisturbanceRejection horizontal deviation measured in 3-D",
        "metrics",
        (
            (
                "quad_wrench_env/tasks/disturbance_rejection.py",
                '"max_horizontal_deviation": float(np.max(_horizontal_distance(error))),',
                '"max_horizontal_deviation": float(np.max(np.linalg.norm(error, axis=1))),',
            ),
        ),
        ("tests/test_disturbance_rejection.py",),
    ),
    Mutation(
        "PID integral clamps the increment, not the integral",
        "pid",
        (
            (
                "quad_wrench_env/control/pid_controller.py",
                "self._integral = np.clip(self._k_i * error * self._dt + self._integral, -limit, limit)",
                "self._integral = self._integral + np.clip(self._k_i * error * self._dt, -limit, limit)",
            ),
        ),
        ("tests/test_pid_integral.py",),
    ),
    Mutation(
        "PID reference feed-forward subtracted",
        "pid",
        (
            (
                "quad_wrench_env/control/pid_controller.py",
                "            desired += acceleration",
                "            desired -= acceleration",
            ),
        ),
        ("tests/test_pid_integral.py",),
    ),
    Mutation(
        "PID bandwidth's integral gain λ³/5",
        "pid",
        (
            (
                "quad_wrench_env/control/pid_controller.py",
                "return bandwidth**2, 2.0 * bandwidth, 0.02 * bandwidth**3",
                "return bandwidth**2, 2.0 * bandwidth, 0.2 * bandwidth**3",
            ),
        ),
        ("tests/test_pid_integral.py",),
    ),
    Mutation(
        "PID bandwidth not capped by the attitude loop",
        "pid",
        (
            (
                "quad_wrench_env/control/pid_controller.py",
                "self.bandwidth = min(self.gains.bandwidth, attitude_p / 3.0)",
                "self.bandwidth = self.gains.bandwidth",
            ),
        ),
        ("tests/test_pid_integral.py",),
    ),
    Mutation(
        "MPC derived slack weight 10x smaller",
        "mpc",
        (
            (
                "quad_wrench_env/control/mpc_controller.py",
                "linear = 2.0 * max(g.position_weight[:2]) * g.cross_track_limit * g.terminal_weight",
                "linear = 0.2 * max(g.position_weight[:2]) * g.cross_track_limit * g.terminal_weight",
            ),
        ),
        ("tests/test_mpc_exact_penalty.py",),
    ),
    Mutation(
        "MPC: the soft problem's slack kept where the hard problem solves",
        "mpc",
        (
            (
                "quad_wrench_env/control/mpc_controller.py",
                "if self.gains.slack and flag != 1:",
                "if self.gains.slack:",
            ),
        ),
        ("tests/test_mpc_exact_penalty.py",),
    ),
    Mutation(
        "MPC: the band on x and y alone, the height free (it climbs at the tilt limit)",
        "mpc",
        (
            (
                "quad_wrench_env/control/mpc_controller.py",
                "limits = (g.cross_track_limit,) * 2 + (() if g.height_limit is None else (g.height_limit,))",
                "limits = (g.cross_track_limit,) * 2",
            ),
        ),
        ("tests/test_tilt_limit_height.py",),
    ),
    Mutation(
        "MPC: the second pass linearised about the current attitude again",
        "mpc",
        (("quad_wrench_env/control/mpc_controller.py", "points[:, 6:8] = attitudes", "pass"),),
        ("tests/test_mpc.py",),
    ),
    Mutation(
        "MPC: a batch's second pass reads each vehicle's row of the whole batch",
        "mpc",
        (
            (
                "quad_wrench_env/control/mpc_controller.py",
                "commands[v] = qps[v].solve_prepared(data, row, again=True)",
                "commands[v] = qps[v].solve_prepared(data, min(v, len(again) - 1), again=True)",
            ),
        ),
        ("tests/test_mpc.py",),
    ),
    Mutation(
        "MPC: the second pass about the attitude one step ahead",
        "mpc",
        (
            (
                "quad_wrench_env/control/mpc_controller.py",
                "self.predicted_states[round(ahead / self.step), 6:8]",
                "self.predicted_states[1, 6:8]",
            ),
        ),
        ("tests/test_mpc.py",),
    ),
    Mutation(
        "MPC: the input reference's thrust unclipped beyond the tilt limit",
        "mpc",
        (
            (
                "quad_wrench_env/control/mpc_controller.py",
                "attitude_from_acceleration(acceleration - force / self.mass, yaw, self.mass, self.tilt)",
                "attitude_from_acceleration(acceleration - force / self.mass, yaw, self.mass)",
            ),
        ),
        ("tests/test_mpc.py",),
    ),
    Mutation(
        "DisturbanceRejection: the path ahead relative to the reference now, not the vehicle",
        "observation",
        (
            (
                "quad_wrench_env/tasks/disturbance_rejection.py",
                "out[:, column + 3 * k : column + 3 * k + 3] = ahead - estimated[:, :3]",
                "out[:, column + 3 * k : column + 3 * k + 3] = ahead - position",
            ),
        ),
        ("tests/test_disturbance_rejection.py",),
    ),
    Mutation(
        "observation scaling loaded with mean and variance swapped",
        "training",
        (
            (
                "quad_wrench_env/agents/sb3_policy.py",
                'return cls(data["mean"], data["var"], float(data["clip"]), float(data["epsilon"]))',
                'return cls(data["var"], data["mean"], float(data["clip"]), float(data["epsilon"]))',
            ),
        ),
        ("tests/test_observation_scaling.py",),
    ),
    Mutation(
        "a run folder loads its final model before its kept best",
        "training",
        (
            (
                "quad_wrench_env/agents/sb3_policy.py",
                '    for name in ("best", "final"):',
                '    for name in ("final", "best"):',
            ),
        ),
        ("tests/test_observation_scaling.py",),
    ),
    Mutation(
        "the kept model is the worst evaluated, not the best",
        "training",
        (
            (
                "quad_wrench_env/agents/sb3.py",
                "if (value < self.best) if e.lower_is_better else (value > self.best):",
                "if (value > self.best) if e.lower_is_better else (value < self.best):",
            ),
        ),
        ("tests/test_sb3.py",),
    ),
    Mutation(
        "force exertion: the tip's gap measured from the centre of mass",
        "task",
        (
            (
                "quad_wrench_env/tasks/force_exertion.py",
                'tips = state.position + np.einsum("nij,j->ni", state.rotation, self._tip_offset())',
                "tips = state.position",
            ),
        ),
        ("tests/test_task_records.py",),
    ),
    Mutation(
        "bench: the env's own Python counts the info's time again",
        "engine",
        (
            (
                "quad_wrench_env/bench.py",
                '    parts[ENV_OWN] = whole - simulation - parts.get("policy: info", 0.0)',
                "    parts[ENV_OWN] = whole - simulation",
            ),
        ),
        ("tests/test_bench.py",),
    ),
    Mutation(
        "step buffer: the air region laid out before the drag points",
        "engine",
        (
            (
                "quad_wrench_env/engine/step_buffer.py",
                '            ("points", 3 * p),\n            ("air", 3 * p),',
                '            ("air", 3 * p),\n            ("points", 3 * p),',
            ),
        ),
        ("tests/test_step_buffer.py",),
    ),
    Mutation(
        "step buffer: a part handed its region without its numbers",
        "engine",
        (
            (
                "quad_wrench_env/engine/step_buffer.py",
                "        view[...] = held\n",
                "",
            ),
        ),
        ("tests/test_step_buffer.py",),
    ),
    Mutation(
        "fleet view: the estimates not read again after a step",
        "engine",
        (
            (
                "quad_wrench_env/engine/fleet.py",
                "        self._read_estimates()\n        return self._view",
                "        return self._view",
            ),
        ),
        (
            "tests/test_task_records.py",
            "tests/test_env_api.py",
            "tests/test_ukf.py",
            "tests/test_determinism.py",
        ),
    ),
    Mutation(
        "residual: the base reads the policy's observation, without the hidden wrench",
        "actions",
        (
            (
                "quad_wrench_env/envs/simulation.py",
                "        if not self._wrench_hidden:\n            return self.observations",
                "        if True:\n            return self.observations",
            ),
        ),
        ("tests/test_residual.py",),
    ),
    Mutation(
        "step outcome: an episode that ended early also counted as truncated",
        "terminations",
        (
            (
                "quad_wrench_env/envs/simulation.py",
                "        truncated[n] = code == 0 and steps[n] >= max_steps",
                "        truncated[n] = steps[n] >= max_steps",
            ),
        ),
        ("tests/test_task_records.py", "tests/test_env_api.py"),
    ),
    Mutation(
        "UKF's reported covariance: the torque's rows where the force's belong",
        "ukf",
        (
            (
                "quad_wrench_env/estimators/ukf_kernel.py",
                "            a = 15 + i if i < 3 else 9 + i",
                "            a = 12 + i",
            ),
        ),
        ("tests/test_wrench_covariance.py", "tests/test_ukf.py"),
    ),
)


def _copy(destination: Path) -> None:
    files = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    for name in files.splitlines():
        source = ROOT / name
        if source.is_file():
            target = destination / name
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, target)


def _apply(root: Path, mutation: Mutation) -> list[str]:
    """Apply the edits; return the problems (a text missing or not unique, a listed test file not in the
    copy: untracked, or gone)."""
    problems = [f"{name}: no such tracked test file" for name in mutation.tests if not (root / name).exists()]
    for name, text, replacement in mutation.edits:
        path = root / name
        source = path.read_text()
        count = source.count(text)
        if count != 1:
            problems.append(f"{name}: text found {count} times: {text[:60]!r}")
            continue
        path.write_text(source.replace(text, replacement))
    return problems


def _restore(root: Path, mutation: Mutation) -> None:
    for name, _, _ in mutation.edits:
        shutil.copy2(ROOT / name, root / name)


def _run(root: Path, mutation: Mutation, timeout: float) -> tuple[str, str, float]:
    env = {**os.environ, "PYTHONPATH": str(root), "QUAD_WRENCH_CACHE_DIR": str(root / ".compositions")}
    start = time.perf_counter()
    try:
        done = subprocess.run(
            [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *mutation.tests],
            cwd=root,
            env=env,
            capture_output=True,
            text=True,
            timeout=timeout,
        )
    except subprocess.TimeoutExpired:
        return "timeout", "", time.perf_counter() - start
    seconds = time.perf_counter() - start
    failed = re.findall(r"^FAILED (\S+)", done.stdout, re.MULTILINE)
    if done.returncode == 0:
        return "survived", "", seconds
    return "killed", failed[0] if failed else f"pytest exit {done.returncode}", seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="only check that every edit applies")
    parser.add_argument("--only", nargs="+", metavar="NAME", help="mutations whose name contains NAME")
    parser.add_argument("--timeout", type=float, default=900.0, help="seconds per mutation's tests")
    args = parser.parse_args()
    chosen = [m for m in MUTATIONS if not args.only or any(part in m.name for part in args.only)]
    if not chosen:
        parser.error(f"--only {args.only} matches no mutation; names: {[m.name for m in MUTATIONS]}")
    with tempfile.TemporaryDirectory(prefix="mutation-check-") as folder:
        root = Path(folder)
        _copy(root)
        rows, killed = [], 0
        for mutation in chosen:
            problems = _apply(root, mutation)
            if problems:
                verdict, by, seconds = "broken", "; ".join(problems), 0.0
            elif args.check:
                verdict, by, seconds = "applies", "", 0.0
            else:
                verdict, by, seconds = _run(root, mutation, args.timeout)
            _restore(root, mutation)
            killed += verdict == "killed"
            rows.append(f"| {mutation.kind} | {mutation.name} | {verdict} | {by} | {seconds:.0f} |")
            print(rows[-1], flush=True)
    print("\n| kind | mutation | verdict | first failing test | s |\n|---|---|---|---|---|")
    print("\n".join(rows))
    if not args.check:
        print(f"\nkilled {killed} of {len(chosen)} ({killed / len(chosen):.0%})")
    if any("| broken |" in row for row in rows):
        sys.exit(1)


if __name__ == "__main__":
    main()
