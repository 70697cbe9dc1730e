"""Evaluate one agent on one env id over seeds: each seed's metrics and their mean.

    quad-wrench evaluate admittance QuadWrench/FanTracking-v1 --seeds 0 1 2
    quad-wrench evaluate pid QuadWrench/DisturbanceRejection-v0 --seeds 0 1 --env estimator=ekf \\
        --agent-param bandwidth=3.5 --options '{"scenario": "jet_crossing"}' --json out.json
    quad-wrench evaluate runs/NAME QuadWrench/FanTracking-v1 --seeds 100 101 --csv out.csv --video out.mp4
    quad-wrench evaluate hold QuadWrench/FanTracking-v1 --seeds 0 --log flight.csv   # then: estimate

AGENT is a classical agent, a shipped learned policy (``quad-wrench list`` names both) or a training run
folder. The episodes run through the one harness (:func:`quad_wrench_env.agents.evaluate.evaluate`); the
table shows each seed's metrics and their mean ± standard deviation; ``--json`` and ``--csv`` write them for
tools (JSON: null where a metric is undefined or never reached). ``--log`` writes the first seed's flight
as its estimator saw it, at the physics rate, in the flight-log layout that ``quad-wrench estimate`` reads
(:mod:`quad_wrench_env.flight_log`).
"""

from __future__ import annotations

import argparse

import gymnasium as gym
from tqdm import tqdm

from quad_wrench_cli.common import (
    UsageError,
    add_key_value_argument,
    env_id,
    json_object,
    seed,
    show,
    usage_errors,
    write_csv,
    write_json,
)
from quad_wrench_env.agents import make_agent
from quad_wrench_env.agents.base import Policy
from quad_wrench_env.agents.evaluate import (
    Evaluation,
    episode_metrics,
    evaluate,
    flying_settings,
    metrics_table,
    run_episode,
)
from quad_wrench_env.config import apply_overrides
from quad_wrench_env.flight_log import FlightRecorder, write_flight_log


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "agent",
        metavar="AGENT",
        help="a classical agent or shipped policy (quad-wrench list), or a run folder",
    )
    parser.add_argument(
        "env_id", metavar="ENV_ID", type=env_id, help="an env id, e.g. QuadWrench/FanTracking-v1"
    )
    parser.add_argument(
        "--seeds", nargs="+", type=seed, required=True, metavar="SEED", help="one episode each"
    )
    add_key_value_argument(
        parser,
        "--env",
        "a gym.make argument (repeatable; the value is read as YAML; dots reach into sections)",
    )
    add_key_value_argument(
        parser,
        "--agent-param",
        "an agent parameter, e.g. bandwidth=3.5 (repeatable; a learned policy takes none)",
    )
    parser.add_argument(
        "--options",
        type=json_object,
        default={},
        metavar="JSON",
        help='reset options of every episode, e.g. \'{"fan_motion": "static", "offset_y": 0.8}\'',
    )
    parser.add_argument("--json", metavar="PATH", help="write the metrics as JSON to PATH")
    parser.add_argument(
        "--csv", metavar="PATH", help="write the metrics as CSV to PATH (one row per seed, then the mean)"
    )
    parser.add_argument(
        "--video",
        metavar="PATH",
        type=_video_path,
        help="record the first seed's episode to PATH (.mp4 or .gif), with a progress bar; a frame takes "
        "about 0.05 s (a 15 s episode at 50 Hz: about 40 s as .mp4)",
    )
    parser.add_argument(
        "--video-every",
        metavar="N",
        type=_video_every,
        help="with --video: record every N-th policy step (N >= 1; default: every step for .mp4, "
        "12.5 frames per second for .gif); N = 2 records about twice as fast",
    )
    parser.add_argument(
        "--log",
        metavar="PATH",
        type=_log_path,
        help="write the first seed's flight to PATH (.csv): what its estimator saw at each physics step "
        "and the true wrench, for quad-wrench estimate (docs/estimators.md, Flight logs)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def _video_path(text: str) -> str:
    """argparse type: a video file name that :func:`quad_wrench_env.agents.video.record_video` writes."""
    if not text.lower().endswith((".mp4", ".gif")):
        raise argparse.ArgumentTypeError(f"{text!r} must end in .mp4 or .gif")
    return text


def _log_path(text: str) -> str:
    """argparse type: a flight log's file name (CSV)."""
    if not text.lower().endswith(".csv"):
        raise argparse.ArgumentTypeError(f"{text!r} must end in .csv (a flight log)")
    return text


def _video_every(text: str) -> int:
    """argparse type: steps per video frame, an integer >= 1."""
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"{text!r} must be an integer >= 1 (record every N-th policy step)")
    return int(text)


def run(args: argparse.Namespace) -> int:
    if args.video_every is not None and not args.video:
        raise UsageError(f"--video-every {args.video_every} applies to a video: add --video PATH")
    with usage_errors():
        env_kwargs, agent_params = apply_overrides({}, args.env), apply_overrides({}, args.agent_param)
        policy = make_agent(args.agent, **agent_params)
        env_kwargs = flying_settings(policy, env_kwargs, args.env_id)  # a learned policy: its training env
        env = gym.make(args.env_id, **env_kwargs)  # bad settings and reset options, before any episode
        try:
            env.reset(seed=args.seeds[0], options=args.options)
            policy.reset(env)  # the agent's own refusal of this env (its action type, its observation)
        finally:
            env.close()
    seeds = tqdm(args.seeds, desc=f"{args.agent} on {args.env_id}", unit="episode", disable=args.no_progress)
    runs = [
        _logged(policy, args, s, env_kwargs)
        if args.log and not i
        else evaluate(policy, args.env_id, [s], options=args.options, **env_kwargs)
        for i, s in enumerate(seeds)
    ]
    result = Evaluation(
        args.env_id, args.seeds, [m for r in runs for m in r.per_seed], [e for r in runs for e in r.episodes]
    )
    columns = tuple((key, key, "{:.4g}") for key in result.per_seed[0])
    rows = {(args.agent, f"seed {r.seeds[0]}"): r for r in runs} | {(args.agent, "mean ± sd"): result}
    title = f"{args.agent} on {args.env_id}, env {env_kwargs}, options {args.options}, seeds {args.seeds}"
    show("\n".join([title, "", *metrics_table(rows, columns)]))
    per_seed = [{"seed": s, **m} for s, m in zip(result.seeds, result.per_seed, strict=True)]
    if args.json:
        write_json(
            args.json,
            {
                "agent": args.agent,
                "agent_params": agent_params,
                "env_id": args.env_id,
                "env": env_kwargs,
                "options": args.options,
                "seeds": result.seeds,
                "per_seed": per_seed,
                "mean": result.mean,
            },
        )
    if args.csv:
        write_csv(args.csv, [*per_seed, {"seed": "mean", **result.mean}])
    if args.video:
        from quad_wrench_env.agents.video import (
            record_video,  # imageio and the renderer: loaded only to record
        )

        record_video(
            policy,
            args.env_id,
            args.video,
            args.seeds[0],
            args.options,
            args.video_every,
            progress=not args.no_progress,
            **env_kwargs,
        )
    written = [path for path in (args.json, args.csv, args.video, args.log) if path]
    if written:
        print("wrote " + ", ".join(written))
    return 0


def _logged(policy: Policy, args: argparse.Namespace, seed: int, env_kwargs: dict) -> Evaluation:
    """The evaluation of ``seed`` (as :func:`~quad_wrench_env.agents.evaluate.evaluate` runs it), its
    flight written to ``args.log``."""
    env = gym.make(args.env_id, **env_kwargs)
    try:
        recorder = FlightRecorder(env)
        episode = run_episode(policy, env, seed, args.options, on_step=recorder.on_step)
    finally:
        env.close()
    write_flight_log(args.log, recorder.log())
    return Evaluation(args.env_id, [seed], [episode_metrics(args.env_id, episode)], [episode])
