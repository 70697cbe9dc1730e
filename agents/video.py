"""Videos and pictures of episodes: a policy flown on an env with ``render_mode="rgb_array"`` (the frames
of :mod:`quad_wrench_env.envs.render`), through the one harness loop (:func:`agents.evaluate.run_episode`).

:func:`record_video` writes one episode as ``.mp4`` (H.264 through imageio's ffmpeg binary, no system
ffmpeg needed) or ``.gif``, at the env's ``render_fps``; :func:`save_stills` writes one PNG per task
(:data:`STILLS`: a classical agent flown a few seconds, the frame of the last step). From the shell::

    python -m agents.video stills docs/frames
    python -m agents.video video out.mp4 --env quad_wrench_env:QuadWrench/FanTracking-v1 --agent admittance \\
        --option fan_motion=sine --seed 0
"""

from __future__ import annotations

import argparse
import contextlib
import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import imageio.v2 as imageio
import yaml
from PIL import Image

from agents import make_agent
from agents.base import Policy
from agents.evaluate import Episode, run_episode


def record_video(
    policy: Policy,
    env_id: str,
    path: str | Path,
    seed: int = 0,
    options: Mapping[str, Any] | None = None,
    every: int = 1,
    **env_kwargs: Any,
) -> Episode:
    """Run ``policy`` on ``gym.make(env_id, render_mode="rgb_array", **env_kwargs)`` for one episode
    from ``reset(seed=seed, options=options)`` and write its frames (the reset's and every ``every``-th
    step's) to ``path`` (``.mp4`` or ``.gif``) at ``render_fps / every`` frames per second; returns the
    episode as :func:`~agents.evaluate.run_episode` does."""
    path = Path(path)
    if path.suffix.lower() not in (".mp4", ".gif"):
        raise ValueError(f"video path {str(path)!r} must end in .mp4 or .gif")
    if not (isinstance(every, int) and every >= 1):
        raise ValueError(f"every={every!r} must be an integer >= 1 (steps per frame)")
    env = gym.make(env_id, render_mode="rgb_array", **env_kwargs)
    with contextlib.closing(env), _writer(path, env.metadata["render_fps"] / every) as writer:
        steps = itertools.count()

        def frame(env: gym.Env, info: dict[str, Any]) -> None:
            if next(steps) % every == 0:
                writer.append_data(env.render())

        return run_episode(policy, env, seed, options, on_step=frame)


def _writer(path: Path, fps: float) -> Any:
    """An imageio writer for ``path``: H.264 (yuv420p, plays everywhere) or an endless GIF."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix.lower() == ".gif":
        return imageio.get_writer(path, duration=1000.0 / fps, loop=0)
    return imageio.get_writer(
        path, fps=fps, codec="libx264", quality=7, macro_block_size=16, ffmpeg_log_level="error"
    )


@dataclass(frozen=True)
class Still:
    """One task's picture: ``agent`` (a name of :func:`agents.make_agent`, with ``agent_params``) flown
    from ``reset(seed, options)`` for ``seconds``; the frame of the last step."""

    name: str
    env_id: str
    agent: str
    seconds: float
    options: dict[str, Any] = field(default_factory=dict)
    agent_params: dict[str, Any] = field(default_factory=dict)
    env_kwargs: dict[str, Any] = field(default_factory=dict)


STILLS = (
    Still(
        "fan_tracking", "quad_wrench_env:QuadWrench/FanTracking-v1", "admittance", 3.0,
        {"offset_y": 0.6, "fan_motion": "static"},
    ),
    Still(  # 3 s: the descent crosses the jet's axis (1.4 m high), where the jet pushes hardest
        "disturbance_rejection", "quad_wrench_env:QuadWrench/DisturbanceRejection-v0", "pid", 3.0,
        {"scenario": "jet_crossing", "jet_speed": 10.0}, {"bandwidth": 3.5, "compensation": True},
        {"estimator": "ekf"},
    ),
    Still(
        "force_exertion", "quad_wrench_env:QuadWrench/ForceExertion-v0", "ida_pbc", 5.0, {"surface": "wall"}
    ),
)  # fmt: skip
"""The pictures of ``docs/frames/``: each task with a classical agent of its paper."""


def save_stills(folder: str | Path, stills: Sequence[Still] = STILLS, seed: int = 0) -> list[Path]:
    """Write ``<name>.png`` of each of ``stills`` into ``folder``; returns their paths."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for still in stills:
        env = gym.make(
            still.env_id, render_mode="rgb_array", episode_seconds=still.seconds, **still.env_kwargs
        )
        with contextlib.closing(env):
            run_episode(make_agent(still.agent, **still.agent_params), env, seed, still.options)
            paths.append(folder / f"{still.name}.png")
            Image.fromarray(env.render()).save(paths[-1])
    return paths


def _pairs(items: list[str]) -> dict[str, Any]:
    """``key=value`` arguments as a mapping, each value read as YAML (numbers, lists, strings)."""
    pairs = {}
    for item in items:
        key, separator, value = item.partition("=")
        if not separator:
            raise SystemExit(f"expected key=value, got {item!r}")
        pairs[key] = yaml.safe_load(value)
    return pairs


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m agents.video", description="Record an episode as .mp4 or .gif, or one PNG per task."
    )
    commands = parser.add_subparsers(dest="command", required=True)
    stills = commands.add_parser("stills", help="one PNG per task into a folder")
    stills.add_argument("folder", type=Path)
    video = commands.add_parser("video", help="one episode as .mp4 or .gif")
    video.add_argument("path", type=Path)
    video.add_argument("--env", required=True, help="env id, e.g. quad_wrench_env:QuadWrench/FanTracking-v1")
    video.add_argument("--agent", required=True, help="agent name (agents.make_agent) or a run folder")
    video.add_argument("--seed", type=int, default=0)
    video.add_argument("--every", type=int, default=1, help="record every n-th step")
    video.add_argument("--option", action="append", default=[], help="reset option key=value")
    video.add_argument("--param", action="append", default=[], help="agent parameter key=value")
    video.add_argument("--env-arg", action="append", default=[], help="gym.make argument key=value")
    args = parser.parse_args(argv)
    if args.command == "stills":
        for path in save_stills(args.folder):
            print(path)
        return
    policy = make_agent(args.agent, **_pairs(args.param))
    episode = record_video(
        policy, args.env, args.path, args.seed, _pairs(args.option), args.every, **_pairs(args.env_arg)
    )
    print(f"{args.path}: {episode.length} steps, return {episode.total_reward:.2f}")


if __name__ == "__main__":
    main()
