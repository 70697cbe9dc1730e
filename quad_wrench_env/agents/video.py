"""Videos and pictures of episodes: a policy flown on an env with ``render_mode="rgb_array"`` (the frames
of :mod:`quad_wrench_env.envs.render`), through the one harness loop
(:func:`quad_wrench_env.agents.evaluate.run_episode`).

:func:`record_video` writes one episode as ``.mp4`` (H.264 through imageio's ffmpeg binary, no system
ffmpeg needed; every step's frame by default) or ``.gif`` (every 4th at 50 Hz by default,
:data:`GIF_FPS`, all on one palette of the first frame's colours and the overlay's, no dithering: a
15 s episode in about 2 MB), with a progress bar of the frames; a frame takes about 0.05 s to draw, so
recording costs about 2.5 s per second of episode at 50 Hz (``every=2`` halves it).
:func:`save_stills` writes one PNG per task (:data:`STILLS`: a classical agent flown a few seconds,
the frame of the last step). From the shell::

    python -m quad_wrench_env.agents.video stills docs/frames
    python -m quad_wrench_env.agents.video video out.mp4 --env quad_wrench_env:QuadWrench/FanTracking-v1 \\
        --agent admittance --option fan_motion=sine --seed 0
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
from tqdm import tqdm

from quad_wrench_env.agents import make_agent
from quad_wrench_env.agents.base import Policy
from quad_wrench_env.agents.evaluate import Episode, run_episode
from quad_wrench_env.envs.overlay import JET_COLOUR
from quad_wrench_env.envs.render import ESTIMATE, EXERTED, REFERENCE, TARGET, TRUE, WIND

GIF_FPS = 12.5
"""A GIF's frame rate when ``every`` is not given: every ``round(render_fps / GIF_FPS)``-th step."""
GIF_COLOURS = (TRUE, ESTIMATE, EXERTED, TARGET, REFERENCE, WIND, JET_COLOUR, (245, 245, 245), (25, 25, 30))
"""Colours every GIF's palette holds exactly (arrows, reference, jet, text, outlines), besides those of
its first frame."""


def default_every(path: str | Path, render_fps: float) -> int:
    """Steps per frame when ``every`` is not given: 1 for ``.mp4``, about :data:`GIF_FPS` frames per
    second for ``.gif``."""
    if Path(path).suffix.lower() == ".gif":
        return max(1, round(render_fps / GIF_FPS))
    return 1


def record_video(
    policy: Policy,
    env_id: str,
    path: str | Path,
    seed: int = 0,
    options: Mapping[str, Any] | None = None,
    every: int | None = None,
    progress: bool = True,
    **env_kwargs: Any,
) -> Episode:
    """Run ``policy`` on ``gym.make(env_id, render_mode="rgb_array", **env_kwargs)`` for one episode
    from ``reset(seed=seed, options=options)`` and write its frames (the reset's and every ``every``-th
    step's; by default :func:`default_every`) to ``path`` (``.mp4`` or ``.gif``) at ``render_fps /
    every`` frames per second, with a progress bar of the frames on stderr unless ``progress`` is
    false; returns the episode as :func:`~quad_wrench_env.agents.evaluate.run_episode` does."""
    path = Path(path)
    if path.suffix.lower() not in (".mp4", ".gif"):
        raise ValueError(f"video path {str(path)!r} must end in .mp4 or .gif")
    if every is not None and not (isinstance(every, int) and not isinstance(every, bool) and every >= 1):
        raise ValueError(f"every={every!r} must be an integer >= 1 (steps per frame)")
    env = gym.make(env_id, render_mode="rgb_array", **env_kwargs)
    fps = env.metadata["render_fps"]
    every = default_every(path, fps) if every is None else every
    steps = getattr(env.unwrapped, "max_steps", None)
    bar = tqdm(
        total=None if steps is None else steps // every + 1,
        desc=f"recording {path.name}",
        unit="frame",
        disable=not progress,
    )
    with contextlib.closing(env), _writer(path, fps / every) as writer, bar:
        count = itertools.count()

        def frame(env: gym.Env, info: dict[str, Any]) -> None:
            if next(count) % every == 0:
                writer.append_data(env.render())
                bar.update()

        episode = run_episode(policy, env, seed, options, on_step=frame)
        bar.total = bar.n  # an episode that ended early has fewer frames
        return episode


def _writer(path: Path, fps: float) -> Any:
    """A writer of frames to ``path``: H.264 (yuv420p, plays everywhere) or an endless GIF."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix.lower() == ".gif":
        return _GifWriter(path, fps)
    return imageio.get_writer(
        path, fps=fps, codec="libx264", quality=7, macro_block_size=16, ffmpeg_log_level="error"
    )


class _GifWriter:
    """An endless GIF at ``fps``, every frame on the one palette of the first frame's colours (Pillow's
    fast octree) and :data:`GIF_COLOURS`, without dithering: what stands still between frames stays
    the same bytes, and Pillow writes only the rectangle that changed. The frames are kept, one byte a
    pixel, and written at :meth:`close`."""

    def __init__(self, path: Path, fps: float) -> None:
        self.path = path
        self.duration = 1000.0 / fps
        self.frames: list[Image.Image] = []
        self.palette: Image.Image | None = None

    def __enter__(self) -> _GifWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def append_data(self, frame: Any) -> None:
        image = Image.fromarray(frame)
        if self.palette is None:
            first = image.quantize(256 - len(GIF_COLOURS), method=Image.Quantize.FASTOCTREE)
            self.palette = Image.new("P", (1, 1))
            colours = first.getpalette()[: 3 * (256 - len(GIF_COLOURS))]
            self.palette.putpalette(colours + [c for colour in GIF_COLOURS for c in colour])
        self.frames.append(image.quantize(palette=self.palette, dither=Image.Dither.NONE))

    def close(self) -> None:
        if self.frames:
            first, *rest = self.frames
            first.save(self.path, save_all=True, append_images=rest, duration=self.duration, loop=0)
            self.frames = []


@dataclass(frozen=True)
class Still:
    """One task's picture: ``agent`` (a name of :func:`quad_wrench_env.agents.make_agent`, with
    ``agent_params``) flown from ``reset(seed, options)`` for ``seconds``; the frame of the last step."""

    name: str
    env_id: str
    agent: str
    seconds: float
    options: dict[str, Any] = field(default_factory=dict)
    agent_params: dict[str, Any] = field(default_factory=dict)
    env_kwargs: dict[str, Any] = field(default_factory=dict)


STILLS = (
    Still(
        "fan_tracking",
        "quad_wrench_env:QuadWrench/FanTracking-v1",
        "admittance",
        3.0,
        {"offset_y": 0.6, "fan_motion": "static"},
    ),
    Still(  # 3 s: the descent crosses the jet's axis (1.4 m high), where the jet pushes hardest
        "disturbance_rejection",
        "quad_wrench_env:QuadWrench/DisturbanceRejection-v0",
        "pid",
        3.0,
        {"scenario": "jet_crossing", "jet_speed": 10.0},
        {"bandwidth": 3.5, "compensation": True},
        {"estimator": "ekf"},
    ),
    Still(
        "force_exertion", "quad_wrench_env:QuadWrench/ForceExertion-v0", "ida_pbc", 5.0, {"surface": "wall"}
    ),
)
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
        prog="python -m quad_wrench_env.agents.video",
        description="Record an episode as .mp4 or .gif, or one PNG per task.",
    )
    commands = parser.add_subparsers(dest="command", required=True)
    stills = commands.add_parser("stills", help="one PNG per task into a folder")
    stills.add_argument("folder", type=Path)
    video = commands.add_parser("video", help="one episode as .mp4 or .gif")
    video.add_argument("path", type=Path)
    video.add_argument("--env", required=True, help="env id, e.g. quad_wrench_env:QuadWrench/FanTracking-v1")
    video.add_argument(
        "--agent", required=True, help="agent name (quad_wrench_env.agents.make_agent) or a run folder"
    )
    video.add_argument("--seed", type=int, default=0)
    video.add_argument("--every", type=int, help="record every n-th step (default: 1; .gif: 12.5 frames/s)")
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
