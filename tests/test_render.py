"""Pictures and videos: rgb_array frames of every task, the vehicle's size in them, force arrows, the
air's arrow, the reference and a task's own marks (DisturbanceRejection's scenario and path), the video
and still writers, and no rendering cost without a render mode."""

from __future__ import annotations

import sys

import imageio.v2 as imageio
import numpy as np
import pybullet as p
import pytest
from PIL import Image

from quad_wrench_env.agents import make_agent
from quad_wrench_env.agents.video import Still, record_video, save_stills
from quad_wrench_env.envs import render
from quad_wrench_env.envs.overlay import Camera, draw_panel, draw_reference
from quad_wrench_env.envs.render import FRAME_SIZE, REFERENCE, TRUE, WIND

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
        render_mode="rgb_array",
        estimator="oracle",
        fan={"enabled": False},
        external_wrench=[[0.1, 5.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0]],
    )
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


DISTURBANCE_REJECTION = "QuadWrench/DisturbanceRejection-v0"


def colour_pixels(image: np.ndarray, colour, centre=None, radius: float = 14.0) -> int:
    """How many pixels of ``image`` are exactly ``colour`` (within ``radius`` of ``centre`` if given)."""
    hits = np.all(image == colour, axis=2)
    if centre is not None:
        rows, columns = np.ogrid[: image.shape[0], : image.shape[1]]
        hits &= (columns - centre[0]) ** 2 + (rows - centre[1]) ** 2 <= radius**2
    return int(hits.sum())


def panels(monkeypatch) -> list[list[str]]:
    """Each draw_panel call's lines, recorded (and still drawn)."""
    calls = []

    def record(image, lines, legend, top=True):
        calls.append(list(lines) + [label for label, _ in legend])
        draw_panel(image, lines, legend, top)

    monkeypatch.setattr(render, "draw_panel", record)
    return calls


@pytest.mark.parametrize(
    ("options", "words"),
    [
        (
            {"scenario": "figure8", "wind_speed": 8.5},
            "scenario figure8: steady wind 8.5 m/s along (+0.00, +1.00)",
        ),
        (
            {"scenario": "jet_crossing", "jet_speed": 10.0},
            "scenario jet_crossing: jet 10.0 m/s across the path from -y",
        ),
    ],
)
def test_disturbance_rejection_frames_name_the_scenario(make_env, monkeypatch, options, words):
    env = make_env(DISTURBANCE_REJECTION, render_mode="rgb_array")
    env.reset(seed=0, options=options)
    calls = panels(monkeypatch)
    env.render()
    assert any(line.startswith(words) for line in calls[0]), calls[0]


def test_the_reference_point_is_drawn_where_it_projects(make_env):
    """Zero action in figure8's wind: after 0.8 s the vehicle has drifted 0.65 m from its reference;
    the reference's ring is at the reference's pixel, not at the vehicle's."""
    env = make_env(DISTURBANCE_REJECTION, render_mode="rgb_array")
    env.reset(seed=0, options={"scenario": "figure8", "wind_speed": 8.5})
    for _ in range(40):
        *_, info = env.step(np.zeros(4, dtype=np.float32))
    image = env.render()
    camera = env.unwrapped._renderer.camera
    (reference, vehicle), _ = camera.project(np.array((info["reference_position"], info["position"])))
    assert np.hypot(*(reference - vehicle)) > 50.0  # apart in the image
    assert colour_pixels(image, REFERENCE, reference) > 40
    assert colour_pixels(image, REFERENCE, vehicle) == 0


def test_a_reference_out_of_view_shows_as_a_pointer_on_the_edge():
    camera = Camera(np.array((0.0, -3.0, 1.0)), np.array((0.0, 0.0, 1.0)), WIDTH, HEIGHT)
    image = Image.new("RGB", (WIDTH, HEIGHT), (255, 255, 255))
    clear = np.zeros((HEIGHT, WIDTH), dtype=bool)
    draw_reference(image, camera, np.array((30.0, 0.0, 1.0)), None, np.zeros(3), REFERENCE, clear)
    pixels = np.asarray(image)
    assert colour_pixels(pixels[:, -40:], REFERENCE) > 30  # on the right edge, towards +x
    assert colour_pixels(pixels[:, :-80], REFERENCE) == 0


def test_the_air_at_the_vehicle_shows_as_an_arrow_pointing_at_it(make_env):
    """figure8's steady 8.5 m/s wind along +y: one arrow upwind of the vehicle, ending short of it; the
    calm table pass has none (the legend's swatch alone)."""
    windy = make_env(DISTURBANCE_REJECTION, render_mode="rgb_array")
    _, info = windy.reset(seed=0, options={"scenario": "figure8", "wind_speed": 8.5})
    windy.render()
    renderer = windy.unwrapped._renderer
    (arrow,) = renderer.wind_arrows(info)
    wind = np.asarray(info["wind_velocity"])
    assert arrow.colour == WIND and np.linalg.norm(wind) > 5.0
    assert np.allclose(arrow.vector, renderer.wind_scale * wind)
    gap = np.asarray(info["position"]) - (arrow.origin + arrow.vector)
    assert np.allclose(gap, 0.6 * renderer.span * wind / np.linalg.norm(wind))
    calm = make_env(DISTURBANCE_REJECTION, render_mode="rgb_array")
    _, calm_info = calm.reset(seed=0, options={"scenario": "table_pass"})
    counts = [colour_pixels(env.render(), WIND) for env in (windy, calm)]
    assert calm.unwrapped._renderer.wind_arrows(calm_info) == []
    assert counts[0] > counts[1] + 100, counts


def test_a_task_says_what_its_frames_show_through_render_marks(make_env, monkeypatch):
    """The hook: a task's ``render_marks(vehicle)`` gives the panel's label and the reference."""
    env = make_env(render_mode="rgb_array", fan={"enabled": False})
    _, info = env.reset(seed=0)
    point = np.add(info["position"], (0.0, 0.0, 0.25))
    monkeypatch.setattr(
        env.unwrapped.task,
        "render_marks",
        lambda vehicle: {"label": "the task's own line", "reference": point},
        raising=False,
    )
    calls = panels(monkeypatch)
    image = env.render()
    (pixel,), _ = env.unwrapped._renderer.camera.project(point[None])
    assert "the task's own line" in calls[0]
    assert colour_pixels(image, REFERENCE, pixel) > 40


def test_every_visible_wind_field_gives_a_well_formed_outlet(make_env):
    """The ``Visible`` seam's conformance: each wind field with an outlet (the fan, the fixed jet) gives
    unit axis and facing directions, a positive radius and spread, from the vehicle's own time and place."""
    from quad_wrench_env.disturbances.base import Outlet, Visible

    env = make_env(wind=[{"model": "jet", "position": [3, -2, 1], "direction": [0, 2, 0], "speed": 10}])
    env.reset(seed=0)
    visible = [w for w in env.unwrapped.fleet.components.winds if isinstance(w, Visible)]
    assert {type(w).__name__ for w in visible} == {"FanJet", "Jet"}
    for wind in visible:
        outlet = wind.outlet(0, 1.0, np.array((2.3, 0.2, 1.0)))
        assert isinstance(outlet, Outlet) and outlet.radius > 0 and outlet.spread > 0
        np.testing.assert_allclose([np.linalg.norm(outlet.axis), np.linalg.norm(outlet.facing)], 1.0)
    jet = next(w for w in visible if type(w).__name__ == "Jet")
    np.testing.assert_allclose(jet.outlet(0, 0.0, np.zeros(3)).axis, (0.0, 1.0, 0.0))


def test_a_users_wind_field_with_an_outlet_is_drawn_without_the_renderer_knowing_it(make_env, monkeypatch):
    """The renderer draws any ``Visible`` wind field: the thermal of docs/examples/ given an outlet of
    its own (a vent on the floor; no class the renderer knows) gets its outlet bodies, and an inactive
    outlet is hidden."""
    from pathlib import Path

    from quad_wrench_env import registry
    from quad_wrench_env.disturbances.base import Outlet

    monkeypatch.setitem(registry._ENTRIES, "wind", dict(registry.registered("wind")))
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[1] / "docs" / "examples"))
    monkeypatch.delitem(sys.modules, "thermal", raising=False)  # registers again, in this registry
    from thermal import Thermal

    @registry.register("wind", "vent")
    class Vent(Thermal):
        active = True

        def outlet(self, vehicle, time, position):
            x0, y0 = self.config.center
            up = np.array((0.0, 0.0, 1.0))
            return Outlet(np.array((x0, y0, 0.0)), up, up, self.config.radius, 0.1, self.active)

    env = make_env(fan={"enabled": False}, wind=[{"model": "vent"}], render_mode="rgb_array")
    env.reset(seed=0)
    before = bodies(env)
    env.render()
    renderer = env.unwrapped._renderer
    vent = env.unwrapped.fleet.components.winds[-1]
    assert isinstance(vent, Vent) and renderer.sources == [vent]
    assert len(renderer._drawn) == 1 and bodies(env) > before + 1
    assert renderer._active() == [True]
    vent.active = False
    assert renderer._active() == [False]
