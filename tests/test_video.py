"""Recording videos: the progress bar's count, small GIFs, and ``quad-wrench evaluate --video-every``."""

from __future__ import annotations

import imageio.v2 as imageio
import numpy as np
import pytest

from quad_wrench_cli.main import main
from quad_wrench_env.agents import make_agent
from quad_wrench_env.agents import video as video_module
from quad_wrench_env.agents.video import record_video
from tests.conftest import FAN_TRACKING, assert_usage_error

FAN = f"quad_wrench_env:{FAN_TRACKING}"


def frames(path) -> int:
    return len(imageio.mimread(path, memtest=False))


class Zero:
    """No action: in figure8's 8.5 m/s wind the vehicle leaves the arena after 100 steps."""

    def reset(self, env) -> None:
        pass

    def act(self, observation):
        return np.zeros(4, dtype=np.float32)


@pytest.fixture
def bars(monkeypatch) -> list:
    """Each progress bar of quad_wrench_env.agents.video, with the total it expected at the start
    (``expected``)."""
    made = []

    class Bar(video_module.tqdm):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self.expected = self.total
            made.append(self)

    monkeypatch.setattr(video_module, "tqdm", Bar)
    return made


def test_the_progress_bar_counts_the_frames(tmp_path, bars):
    """0.3 s at 50 Hz, every 2nd step: the reset's frame and 7 more; the bar expects 8 and shows 8."""
    path = tmp_path / "episode.mp4"
    record_video(make_agent("hold"), FAN, path, seed=1, every=2, episode_seconds=0.3)
    (bar,) = bars
    assert bar.expected == bar.total == bar.n == frames(path) == 8


def test_an_episode_that_ends_early_ends_its_bar_at_its_frames(tmp_path, bars):
    path = tmp_path / "episode.mp4"
    episode = record_video(
        Zero(),
        "quad_wrench_env:QuadWrench/DisturbanceRejection-v0",
        path,
        every=10,
        options={"scenario": "figure8", "wind_speed": 8.5},
    )
    (bar,) = bars
    assert episode.length == 100 and bar.expected == 76  # 750 steps
    assert bar.total == bar.n == frames(path) == 11


def test_a_gif_of_a_short_episode_stays_small(tmp_path):
    """1 s of DisturbanceRejection's jet crossing as a GIF: 12.5 frames per second by default, one
    palette, under 200 kB (each frame on its own palette, every step: about 1.5 MB)."""
    path = tmp_path / "episode.gif"
    record_video(
        make_agent("pid", bandwidth=3.5),
        "quad_wrench_env:QuadWrench/DisturbanceRejection-v0",
        path,
        options={"scenario": "jet_crossing", "jet_speed": 10.0},
        progress=False,
        episode_seconds=1.0,
    )
    assert frames(path) == 13  # the reset's and every 4th of 50 steps
    assert path.stat().st_size < 200_000, path.stat().st_size


@pytest.mark.parametrize("value", ["0", "-1", "1.5", "x"])
def test_a_bad_video_every_exits_with_code_2_and_a_message(value, tmp_path, capsys):
    argv = ["evaluate", "hold", FAN_TRACKING, "--seeds", "0", "--video", str(tmp_path / "out.mp4")]
    assert_usage_error(
        [*argv, f"--video-every={value}"],
        f"argument --video-every: {value!r} must be an integer >= 1",
        capsys,
    )
    assert not (tmp_path / "out.mp4").exists()


def test_video_every_without_a_video_exits_with_code_2(capsys):
    assert_usage_error(
        ["evaluate", "hold", FAN_TRACKING, "--seeds", "0", "--video-every", "2"], "add --video PATH", capsys
    )


def test_evaluate_records_every_nth_step(tmp_path, capsys):
    path = tmp_path / "out.gif"
    argv = ["evaluate", "hold", FAN_TRACKING, "--seeds", "0", "--env", "episode_seconds=0.2", "--no-progress"]
    assert main([*argv, "--video", str(path), "--video-every", "3"]) == 0
    assert frames(path) == 4  # the reset's and steps 3, 6 and 9 of 10 (a GIF's default: 3 frames)
    assert f"wrote {path}" in capsys.readouterr().out
