"""Reproduce Yüksel et al.'s (2014) Figs. 4-6 with IDA-PBC (quad_wrench_env/agents/ida_pbc.py) on the
observer's estimate, and the wall-pressing check of ForceExertion-v0: PNG figures and a markdown report.

    quad-wrench reproduce yuksel [--config configs/reproduce_yuksel.yaml] [--only fig4 fig5 fig6 wall]

Figs. 4 and 6 fly ``yuksel1kg`` (Yüksel et al.'s (2014) m = 1 kg, J = diag(0.13, 0.13, 0.22)) in free air (the
FanTracking env with its fan off and a large arena) under the paper's scheduled wrench, drag-free as
in the paper and once with the default drag. Fig. 5 slides the tool's tip along a rough ceiling
(ForceExertion, ``surface="ceiling"``) with a compliant and a stiff parameter set. ``wall`` presses on
a wall with the configured vehicles and targets.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import matplotlib
import numpy as np
from tqdm import tqdm

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from quad_wrench_cli import reproduction
from quad_wrench_cli.common import save_figure
from quad_wrench_env.agents.evaluate import episode_metrics, run_episode
from quad_wrench_env.agents.ida_pbc import IDAPBCPolicy, euler_zyx, load_param_set
from quad_wrench_env.tasks.force_exertion import ForceExertion
from quad_wrench_env.vehicle import GRAVITY

DRAG_FREE = {"drag_area": 0.0, "rotor_drag_decel": 0.0}


def free_air(config: dict, profile: list, drag: bool) -> gym.Env:
    """yuksel1kg in free air with the scheduled wrench ``profile`` (the FanTracking env, fan off)."""
    return gym.make(
        "QuadWrench/FanTracking-v1",
        vehicle="yuksel1kg",
        action_type="wrench",
        estimator=config["estimator"],
        fan={"enabled": False, "height": config["free_air_height"]},
        kf_spread=0.0,
        vehicle_params={} if drag else DRAG_FREE,
        episode_seconds=config["free_air_seconds"],
        arena=config["free_air_arena"],
        external_wrench=profile,
    )


def record(env: gym.Env, policy: IDAPBCPolicy, seed: int, options: dict) -> dict[str, np.ndarray]:
    """One episode's time, position, velocity, Euler angles, exerted force ``f_ne`` (the rotors' thrust
    minus the weight), true and estimated external force and torque, and tip contact force."""
    obs, info = env.reset(seed=seed, options=options)
    policy.reset(env)
    base = env.unwrapped
    weight = base.vehicle.mass * GRAVITY * np.array((0.0, 0.0, 1.0))
    rows: dict[str, list] = {k: [] for k in ("t", "p", "v", "eta", "fne", "w", "w_hat", "contact")}
    while True:
        obs, _, terminated, truncated, info = env.step(policy.act(obs))
        fleet = base.fleet
        rotation = fleet.state.rotation[0]
        rows["t"].append(info["time"])
        rows["p"].append(info["position"])
        rows["v"].append(info["velocity"])
        rows["eta"].append(euler_zyx(rotation))
        thrust = fleet.step_buffer.fields["rotor_wrench"][0, 0]  # the true rotors' c_t
        rows["fne"].append(thrust * rotation[:, 2] - weight)
        rows["w"].append(info["wrench_true"])
        rows["w_hat"].append(info["wrench_est"])
        rows["contact"].append(fleet.contact_force[0].copy())
        if terminated or truncated:
            break
    return {k: np.asarray(v) for k, v in rows.items()}


def _plot_wrench(axes: Any, rec: dict, label: str) -> None:
    for i, name in enumerate(("f_x", "f_y", "f_z")):
        axes[i].plot(rec["t"], rec["w"][:, i], "k", linewidth=1, label=f"true {name}")
        axes[i].plot(rec["t"], rec["w_hat"][:, i], "r", linewidth=1, label=f"{label} {name}")
        axes[i].set_ylabel(f"{name} (N)")
        axes[i].legend(fontsize=7)


# -- Fig. 6: balancing a push while the wrench steps --------------------------------------------------------
def fig6(config: dict, out: Path) -> list[str]:
    setup = config["fig6"]
    lines = [
        f"## Fig. 6: balance mode ({setup['params']}), {config['estimator']}, seeds {config['seeds']}",
        "",
        "Per settled window: max |acceleration| (m/s²) and the largest per-axis error of f_ne against -f_e "
        "(N); pass: |a| < 0.05 and every axis within 10 % of the target (0.1 N).",
        "",
        "| torque scale | air | window (s) | max abs(a) | max f_ne error | passes |",
        "|---|---|---|---|---|---|",
    ]
    for scale, drag in ((s, d) for s in setup["torque_scales"] for d in (False, True)):
        profile = [[*row[:5], *(scale * np.array(row[5:]))] for row in setup["profile"]]
        records = []
        for seed in tqdm(config["seeds"], desc=f"Fig. 6 x{scale} drag={drag}", unit="episode", leave=False):
            policy = IDAPBCPolicy(replace(load_param_set(setup["params"]), mode="balance"))
            env = free_air(config, profile, drag)
            try:
                records.append(record(env, policy, seed, {"offset_y": 0.0, "fan_motion": "static"}))
            finally:
                env.close()
        for start, stop in setup["windows"]:
            worst_a, worst_f, passes = 0.0, 0.0, 0
            for rec in records:
                w = (rec["t"] > start) & (rec["t"] <= stop)
                k = np.flatnonzero(w)
                accel = (rec["v"][k[-1]] - rec["v"][k[0] - 1]) / (rec["t"][k[-1]] - rec["t"][k[0] - 1])
                error = np.max(np.abs(rec["fne"][w].mean(0) + rec["w"][w, :3].mean(0)))
                worst_a, worst_f = max(worst_a, float(np.linalg.norm(accel))), max(worst_f, float(error))
                passes += int(np.linalg.norm(accel) < 0.05 and error < 0.1)
            air = "default drag" if drag else "drag-free"
            scores = f"{worst_a:.3f} | {worst_f:.3f} | {passes}/{len(records)}"
            lines.append(f"| {scale:g} | {air} | {start}-{stop} | {scores} |")
        if not drag and scale == 1.0:
            rec = records[0]
            fig, axes = plt.subplots(3, 2, figsize=(11, 7), sharex=True)
            accel = np.gradient(rec["v"], rec["t"], axis=0)
            for i, name in enumerate("xyz"):
                axes[i, 0].plot(rec["t"], accel[:, i], label=f"a_{name} (m/s²)")
                axes[i, 0].plot(rec["t"], rec["fne"][:, i], label=f"f_ne,{name} (N)")
                axes[i, 0].plot(rec["t"], -rec["w"][:, i], "k--", linewidth=1, label=f"-f_e,{name} (N)")
                axes[i, 0].set_ylabel(f"{name} (m/s² or N)")
                axes[i, 0].legend(fontsize=7)
            _plot_wrench(axes[:, 1], rec, config["estimator"])
            for ax in axes[-1]:
                ax.set_xlabel("time (s)")
            fig.suptitle(
                f"Fig. 6: IDA-PBC balancing a 1 N push ({setup['params']}, seed {config['seeds'][0]})"
            )
            save_figure(fig, out / "fig6.png")
    return lines


# -- Fig. 4: free flight under the step profile -------------------------------------------------------------
def fig4(config: dict, out: Path) -> list[str]:
    setup = config["fig4"]
    lines = [
        f"## Fig. 4: IDA-PBC on the observer's estimate, drag-free, seed {config['seeds'][0]}",
        "",
        "| parameter set | max position excursion x, y, z (m) | max roll, pitch (deg) |",
        "|---|---|---|",
    ]
    fig, axes = plt.subplots(3, 2, figsize=(11, 7), sharex=True)
    for name in setup["params"]:
        env = free_air(config, setup["profile"], drag=False)
        try:
            rec = record(env, IDAPBCPolicy(load_param_set(name)), config["seeds"][0], {"offset_y": 0.0})
        finally:
            env.close()
        excursion = np.max(np.abs(rec["p"] - rec["p"][0]), axis=0)
        tilt = np.degrees(np.max(np.abs(rec["eta"][:, :2]), axis=0))
        lines.append(
            f"| {name} | {', '.join(f'{e:.2f}' for e in excursion)} | {tilt[0]:.1f}, {tilt[1]:.1f} |"
        )
        for i, axis in enumerate("xyz"):
            axes[i, 0].plot(rec["t"], rec["p"][:, i] - rec["p"][0, i], label=f"{name}: {axis} - {axis}(0)")
            axes[i, 0].set_ylabel(f"{axis} (m)")
            axes[i, 0].legend(fontsize=7)
        if name == setup["params"][0]:
            _plot_wrench(axes[:, 1], rec, config["estimator"])
            axes[0, 1].set_title(f"external force in the {name} flight", fontsize=9)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    fig.suptitle(
        "Fig. 4: 1 N along x (5-10 s), 1 N along -z (15-20 s), 1 N·m about x (25-30 s), all (35-40 s)"
    )
    save_figure(fig, out / "fig4.png")
    return lines


# -- Fig. 5: sliding along a rough ceiling ------------------------------------------------------------------
def fig5(config: dict, out: Path) -> list[str]:
    """Yüksel et al. 2014 Fig. 5 as they describe it: a constant high-level input, here IDA-PBC's position
    mode with its set-point ``press`` m beyond the ceiling (the reshaped spring ``K_x,z·press`` pushes the tip
    up) and moving along x at ``speed``, over ridges; the sets differ in inertia and damping along the
    thrust (QC1 compliant, QC2 stiff; the same ``K_x,z``)."""
    setup = config["fig5"]
    lines = [
        f"## Fig. 5: tip sliding along a rough ceiling (ridges up to {setup['roughness'] * 100:g} cm) at "
        f"{setup['speed']} m/s, set-point {setup['press']} m beyond it, seeds {config['seeds']}",
        "",
        "| parameter set | time in contact | longest loss (s) | mean force on the ceiling (N) "
        "| distance slid (m) |",
        "|---|---|---|---|---|",
    ]
    fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    for name, colour in zip(setup["params"], ("tab:blue", "tab:red"), strict=False):
        fractions, losses, forces, slid = [], [], [], []
        for seed in config["seeds"]:
            env = gym.make(
                "QuadWrench/ForceExertion-v0", roughness=setup["roughness"], episode_seconds=setup["seconds"]
            )
            gap = env.unwrapped.cfg.start_gap
            params = replace(
                load_param_set(name),
                mode="position",
                reference_offset=(0.0, 0.0, gap + setup["press"]),
                reference_velocity=(setup["speed"], 0.0, 0.0),
            )
            try:
                rec = record(env, IDAPBCPolicy(params), seed, {"surface": "ceiling"})
            finally:
                env.close()
            touching = np.linalg.norm(rec["contact"], axis=1) > 1e-3
            first = int(np.argmax(touching)) if touching.any() else len(touching)
            fractions.append(float(np.mean(touching[first:])) if touching.any() else 0.0)
            trace = {"time": rec["t"], "contact_force": rec["contact"], "target_force": rec["contact"] * 0}
            losses.append(ForceExertion.metrics(trace)["longest_contact_loss_s"])
            forces.append(float(np.mean(-rec["contact"][first:, 2])))
            slid.append(float(rec["p"][-1, 0] - rec["p"][0, 0]))
            if seed == config["seeds"][0]:
                axes[0].plot(
                    rec["t"], rec["p"][:, 2] - rec["p"][0, 2], color=colour, label=f"{name}: z - z(0)"
                )
                axes[1].plot(
                    rec["t"], -rec["contact"][:, 2], color=colour, label=f"{name}: exerted f_z (true)"
                )
                axes[2].plot(rec["t"], rec["w_hat"][:, 2], color=colour, label=f"{name}: observer's f_z")
                axes[2].plot(rec["t"], rec["w"][:, 2], color=colour, linestyle=":", label=f"{name}: true f_z")
        contact = f"{np.mean(fractions):.0%} ± {np.std(fractions):.0%}"
        loss = f"{np.mean(losses):.2f} ± {np.std(losses):.2f}"
        lines.append(f"| {name} | {contact} | {loss} | {np.mean(forces):.2f} | {np.mean(slid):.2f} |")
    axes[0].set_ylabel("height change (m)")
    axes[1].set_ylabel("force on the ceiling (N)")
    axes[2].set_ylabel("external f_z (N)")
    axes[2].set_xlabel("time (s)")
    for ax in axes:
        ax.legend(fontsize=7)
    fig.suptitle("Fig. 5: compliant vs stiff IDA-PBC sliding along a rough ceiling")
    save_figure(fig, out / "fig5.png")
    return lines


# -- wall pressing (ForceExertion acceptance) ---------------------------------------------------------------
def wall(config: dict, out: Path) -> list[str]:
    setup = config["wall"]
    lines = [
        f"## Wall pressing, IDA-PBC, {config['estimator']}, seeds {config['seeds']}",
        "",
        "| vehicle | parameter set | target (N) | mean force last 5 s (N) | within 10 % "
        "| longest loss after first touch (s) | ended early |",
        "|---|---|---|---|---|---|---|",
    ]
    reference_margin = None
    for vehicle in setup["vehicles"]:
        env = gym.make("QuadWrench/ForceExertion-v0", vehicle=vehicle)
        v = env.unwrapped.vehicle
        env.close()
        margin = 4.0 * v.kf * v.max_rotor_speed**2 - v.mass * GRAVITY
        reference_margin = reference_margin or margin
        for target in setup["targets"]:
            scaled = target * margin / reference_margin
            scores, early = [], 0
            for seed in tqdm(
                config["seeds"], desc=f"wall {vehicle} {scaled:.2f} N", unit="episode", leave=False
            ):
                env = gym.make("QuadWrench/ForceExertion-v0", vehicle=vehicle)
                try:
                    episode = run_episode(
                        IDAPBCPolicy(load_param_set(setup["params"][vehicle])),
                        env,
                        seed,
                        {"surface": "wall", "target_force": scaled},
                    )
                finally:
                    env.close()
                scores.append(episode_metrics("QuadWrench/ForceExertion-v0", episode))
                early += episode.termination_reason is not None
            force = [s["mean_contact_force_last_5s"] for s in scores]
            within = sum(abs(f - scaled) <= 0.1 * scaled for f in force)
            loss = max(s["longest_contact_loss_s"] for s in scores)
            lines.append(
                f"| {vehicle} | {setup['params'][vehicle]} | {scaled:.2f} | "
                f"{np.mean(force):.3f} ± {np.std(force):.3f} | "
                f"{within}/{len(force)} | {loss:.2f} | {early}/{len(force)} |"
            )
    return lines


PARTS = {"fig4": fig4, "fig5": fig5, "fig6": fig6, "wall": wall}


TITLE = "Yüksel et al. 2014"


CONFIG = "reproduce_yuksel.yaml"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    reproduction.add_arguments(parser, PARTS, CONFIG)


def run(args: argparse.Namespace) -> int:
    return reproduction.run_parts(args, PARTS, CONFIG, TITLE)
