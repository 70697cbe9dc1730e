"""Pictures and videos: rgb_array frames of every task, the vehicle's size in them, force arrows, the
video and still writers, and no rendering cost without a render mode."""

from __future__ import annotations

import imageio.v2 as imageio
import numpy as np
import pybullet as p
import pytest
from PIL import Image

from agents import make_agent
from agents.video import Still, record_video, save_stills
from quad_wrench_env.envs.render import FRAME_SIZE, TRUE

TASKS = ("QuadWrench/FanTracking-v1", "QuadWrench/DisturbanceRejection-v0", "QuadWrench/ForceExertion-v0")
WIDTH, HEIGHT = FRAME_SIZE


def bodies(env) -> int:
    return p.getNumBodies(physicsClientId=env.unwrapped.world.client)


@pytest.mark.parametrize("env_id", TASKS)
def test_each_task_renders_an_rgb_image(make_env, env_id):
    env = make_env(env_id, render_mode="rgb_array")
    env.reset(seed=0)
    env.step(np.zeros(4, dtype=np.float32))
    image = env.render()
    assert image.shape == (HEIGHT, WIDTH, 3) and image.dtype == np.uint8
    assert image.std() > 10  # not a blank frame


@pytest.mark.parametrize("vehicle", ["crazyflie2", "yuksel1kg"])
def test_the_vehicle_fills_a_sizable_share_of_the_frame(make_env, vehicle):
    """The camera's distance follows the vehicle's size: a 13 cm crazyflie2 and a 1 m yuksel1kg cover
    alike shares of the frame (the pixels that change when the vehicle's look is hidden)."""
    env = make_env(render_mode="rgb_array", vehicle=vehicle)
    env.reset(seed=0, options={"offset_y": 0.3, "fan_motion": "static"})
    shown = env.render().astype(int)
    unwrapped = env.unwrapped
    hidden = (0.0, 0.0, 0.0, 0.0)
    p.changeVisualShape(
        unwrapped._renderer._vehicle, -1, rgbaColor=hidden, physicsClientId=unwrapped.world.client
    )
    share = np.mean(np.any(np.abs(shown - env.render()) > 8, axis=2))
    assert 0.01 < share < 0.25, share


def test_a_force_arrow_appears_with_a_true_external_force_and_not_without(make_env):
    """Oracle estimator, no fan: at rest after the reset there is no external force and no arrow; a push
    of 1 N along x draws the true force's arrow (its colour appears beyond the legend's swatch)."""
    env = make_env(
        render_mode="rgb_array", estimator="oracle", fan={"enabled": False},
        external_wrench=[[0.1, 5.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0]],
    )  # fmt: skip
    _, info = env.reset(seed=0)
    still = env.render()
    renderer = env.unwrapped._renderer
    assert not np.any(info["wrench_true"]) and renderer.arrows(info) == []
    for _ in range(10):
        _, _, _, _, info = env.step(np.zeros(4, dtype=np.float32))
    pushed = env.render()
    assert [a.colour for a in renderer.arrows(info)][:1] == [TRUE]
    true_pixels = [int(np.all(image == TRUE, axis=2).sum()) for image in (still, pushed)]
    assert true_pixels[1] > true_pixels[0] + 100, true_pixels


def test_the_video_has_a_frame_for_the_reset_and_each_step(tmp_path):
    path = tmp_path / "episode.mp4"
    env_id = "quad_wrench_env:QuadWrench/FanTracking-v1"
    episode = record_video(make_agent("hold"), env_id, path, seed=1, episode_seconds=0.3)
    reader = imageio.get_reader(path)
    try:
        frames = [frame for frame in reader]
        fps = reader.get_meta_data()["fps"]
    finally:
        reader.close()
    assert episode.length == 15 and len(frames) == 16 and fps == 50.0
    assert frames[0].shape == (HEIGHT, WIDTH, 3)


def test_a_gif_keeps_every_nth_frame(tmp_path):
    path = tmp_path / "episode.gif"
    env_id = "quad_wrench_env:QuadWrench/FanTracking-v1"
    record_video(make_agent("hold"), env_id, path, every=5, episode_seconds=0.2)
    assert len(imageio.mimread(path)) == 3  # the reset's frame and steps 5 and 10 of 10


def test_stills_are_written_as_png(tmp_path):
    still = Still("hover", "quad_wrench_env:QuadWrench/ForceExertion-v0", "ida_pbc", 0.1, {"surface": "wall"})
    (path,) = save_stills(tmp_path, [still])
    with Image.open(path) as image:
        assert path.name == "hover.png" and image.size == (WIDTH, HEIGHT)


@pytest.mark.parametrize("env_id", TASKS)
def test_without_a_render_mode_nothing_is_drawn(make_env, env_id):
    """No render mode: no visual bodies, ever; with one, they come at the first render() only."""
    plain = make_env(env_id)
    plain.reset(seed=0)
    plain.step(np.zeros(4, dtype=np.float32))
    drawn = make_env(env_id, render_mode="rgb_array")
    drawn.reset(seed=0)
    assert bodies(plain) == bodies(drawn)
    drawn.render()
    assert bodies(drawn) > bodies(plain)
