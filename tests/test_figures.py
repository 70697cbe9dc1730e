"""Every figure the command line draws has labelled axes with units and a legend for every line.

The plotting code of each module (demo, compare agents, compare estimators, reproduce mckinnon, yuksel
and hentzen; ``reproduce tune-hentzen`` draws no figure) runs on tiny synthetic inputs: where a figure
is drawn inside the loop that flies the episodes, the flight (``_episode``, ``record``, ``fly``) is
replaced by a made-up trace, so no simulation runs. ``Figure.savefig`` is replaced by a check of the
figure: every Axes with data has an x label (its own or that of an Axes it shares x with), a y label
with a unit in brackets or parentheses (or "fraction"/"ratio" for a dimensionless one), every line,
scatter, band and bar series a label of its own (or the style of a labelled line: one legend entry for
several lines drawn alike), and a legend naming them where there is more than one. Lines on an Axes
whose x ticks name categories (the boxes of a box plot) are named by the ticks.
"""

from __future__ import annotations

import re
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
from matplotlib.collections import QuadMesh
from matplotlib.colors import to_rgba
from matplotlib.container import Container
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from quad_wrench_cli import (
    compare_agents,
    compare_estimators,
    demo,
    reproduce_hentzen,
    reproduce_mckinnon,
    reproduce_yuksel,
)
from quad_wrench_env.agents.evaluate import Episode, Evaluation, table_columns
from quad_wrench_env.agents.ida_pbc import IDAPBCPolicy
from quad_wrench_env.config import config_path, load_yaml
from quad_wrench_env.vehicle import make_vehicle

UNIT = re.compile(r"[\[(][^\])]+[\])]|fraction|ratio")


# -- the check ---------------------------------------------------------------------------------------
def _siblings_label(ax: Any, axis: str) -> str:
    """``ax``'s x or y label, else that of an Axes sharing that axis with it."""
    shared = ax.get_shared_x_axes() if axis == "x" else ax.get_shared_y_axes()
    for other in [ax, *shared.get_siblings(ax)]:
        label = other.get_xlabel() if axis == "x" else other.get_ylabel()
        if label.strip():
            return label
    return ""


def _members(container: Any) -> list[Any]:
    """The artists of a container (a bar container's error bars too), flattened."""
    out = []
    for item in [*container, getattr(container, "errorbar", None)]:
        if isinstance(item, (Container, tuple, list)):
            out += _members(item)
        elif item is not None:
            out.append(item)
    return out


def _style(line: Line2D) -> tuple:
    return to_rgba(line.get_color()), line.get_linestyle(), line.get_marker()


def _categorical(ax: Any) -> bool:
    """Whether the x ticks are named (categories, e.g. the controllers of a box plot)."""
    for tick in ax.get_xticklabels():
        text = tick.get_text().replace("\N{MINUS SIGN}", "-").strip()
        if text:
            try:
                float(text)
            except ValueError:
                return True
    return False


def problems(fig: Figure) -> list[str]:
    found = []
    for n, ax in enumerate(fig.axes):
        where = f"axes {n} ({ax.get_title() or ax.get_ylabel()!r})"
        if getattr(ax, "_colorbar", None) is not None:
            label = ax.get_ylabel() or ax.get_xlabel()
            if not UNIT.search(label):
                found.append(f"{where}: colour bar label {label!r} without a unit")
            continue
        if not (ax.lines or ax.collections or ax.patches or ax.images):
            continue
        if not _siblings_label(ax, "x"):
            found.append(f"{where}: no x label")
        ylabel = _siblings_label(ax, "y")
        if not UNIT.search(ylabel):
            found.append(f"{where}: y label {ylabel!r} without a unit")
        nested = {id(c.errorbar) for c in ax.containers if getattr(c, "errorbar", None) is not None}
        containers = [c for c in ax.containers if id(c) not in nested]
        in_containers = {id(a) for c in ax.containers for a in _members(c)}
        series = [*containers]
        series += [a for a in ax.lines if id(a) not in in_containers]
        series += [a for a in ax.collections if id(a) not in in_containers and not isinstance(a, QuadMesh)]
        labelled = [s for s in series if not s.get_label().startswith("_")]
        styles = {_style(s) for s in labelled if isinstance(s, Line2D)}
        for s in series:
            if not s.get_label().startswith("_"):
                continue
            if isinstance(s, Line2D) and (_style(s) in styles or _categorical(ax)):
                continue
            found.append(f"{where}: {type(s).__name__} without a label")
        if len(labelled) > 1 or (len(labelled) < len(series) and not _categorical(ax)):
            legend = ax.get_legend()
            texts = {t.get_text() for t in legend.get_texts()} if legend else set()
            texts |= {t.get_text() for lg in fig.legends for t in lg.get_texts()}
            if not texts:
                found.append(f"{where}: {len(series)} series and no legend")
            missing = sorted({s.get_label() for s in labelled} - texts)
            if texts and missing:
                found.append(f"{where}: not in the legend: {missing}")
    return found


@pytest.fixture
def saved(monkeypatch: pytest.MonkeyPatch) -> dict[str, list[str]]:
    """File name -> the problems of the figure saved under it (nothing is written)."""
    figures: dict[str, list[str]] = {}

    def check(self: Figure, fname: Any, *args: Any, **kwargs: Any) -> None:
        figures[Path(fname).name] = problems(self)

    monkeypatch.setattr(Figure, "savefig", check)
    return figures


def assert_clean(saved: dict[str, list[str]], expected: set[str]) -> None:
    assert set(saved) == expected
    bad = {name: found for name, found in saved.items() if found}
    assert not bad, bad


# -- made-up flights ---------------------------------------------------------------------------------
def _trace(seconds: float = 45.0, dt: float = 0.1, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds + dt / 2, dt)
    n = t.size
    wrench = np.outer(t > 5.0, (0.3, 0.0, -0.5, 0.01, -0.05, 0.02))
    reference = np.zeros((n, 3))
    reference[:, 0] = np.clip(2.5 + 0.1 * (t - 1.0), 2.5, 4.5)
    return {
        "time": t,
        "position": reference + 0.01 * rng.standard_normal((n, 3)),
        "reference_position": reference,
        "fan_position": np.outer(np.sin(0.1 * t), (0.0, 1.0, 0.0)),
        "jet_axis_y": np.sin(0.1 * t),
        "wrench_true": wrench,
        "wrench_est": wrench + 0.01 * rng.standard_normal((n, 6)),
    }


def _episode(seed: int = 0, **_: Any) -> Episode:
    trace = _trace(seed=seed)
    return Episode(seed, trace, 0.0, trace["time"].size, None)


def _shipped(name: str, seeds: list[int]) -> dict:
    config = load_yaml(config_path(name))
    config["seeds"] = seeds
    return config


# -- the figures -------------------------------------------------------------------------------------
def test_demo(saved: dict, tmp_path: Path) -> None:
    results = {
        (agent, case): Evaluation("QuadWrench/FanTracking-v1", [100], [{}], [_episode()])
        for agent in ("admittance + ukf", "ppo_fan_tracking + oracle")
        for case in ("randomised", "static_0.8m")
    }
    demo.plot(results, tmp_path / "tracking.png")
    assert_clean(saved, {"tracking.png"})


@pytest.mark.parametrize(
    "env_id",
    ["QuadWrench/FanTracking-v1", "QuadWrench/DisturbanceRejection-v0", "QuadWrench/ForceExertion-v0"],
)
def test_compare_agents(saved: dict, tmp_path: Path, env_id: str) -> None:
    metric, title, _ = table_columns(env_id)[0]  # what compare_agents.run plots
    results = {
        (agent, case): Evaluation(env_id, [1, 2], [{metric: 0.1}, {metric: 0.2}], [])
        for agent in ("a", "b")
        for case in ("c", "d")
    }
    compare_agents.plot(results, metric, title, tmp_path / "errors.png")
    assert compare_agents.plot_training(_shipped("compare_agents.yaml", [0]), tmp_path / "training.png")
    assert_clean(saved, {"errors.png", "training.png"})


def test_compare_estimators(saved: dict, tmp_path: Path) -> None:
    trace = _trace()
    traces = {name: trace["wrench_est"] for name in ("ukf", "ekf", "observer")}
    compare_estimators._plot(trace["time"], trace["wrench_true"], traces, tmp_path / "fig5.png", "title")
    assert_clean(saved, {"fig5.png"})  # fig5_<case>.png and fig4_yuksel.png are drawn by _plot


def test_reproduce_mckinnon(saved: dict, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(reproduce_mckinnon, "_episode", lambda config, policy, seed, *a, **k: _episode(seed))
    monkeypatch.setattr(
        reproduce_mckinnon,
        "episode_metrics",
        lambda env_id, ep: {
            "mean_abs_error_after_5s": 0.1,
            "fraction_within_0.15m": 0.5,
            "time_to_0.15m": 1.0,
        },
    )
    config = _shipped("reproduce_mckinnon.yaml", [0, 1])
    for part in reproduce_mckinnon.FIGURES.values():
        part(config, tmp_path)
    assert_clean(saved, {"fig3.png", "fig4.png", "fig6.png", "fig7.png"})


def _yuksel_record(env: Any, policy: Any, seed: int, options: dict) -> dict[str, np.ndarray]:
    trace = _trace(seed=seed)
    n = trace["time"].size
    contact = np.outer(trace["time"] > 1.0, (0.0, 0.0, -1.0))
    return {
        "t": trace["time"],
        "p": trace["position"],
        "v": 0.01 * trace["position"],
        "eta": np.zeros((n, 3)),
        "fne": -trace["wrench_true"][:, :3],
        "w": trace["wrench_true"],
        "w_hat": trace["wrench_est"],
        "contact": contact,
    }


class _FakeEnv:
    unwrapped = SimpleNamespace(cfg=SimpleNamespace(start_gap=0.1))

    def close(self) -> None:
        pass


def test_reproduce_yuksel(saved: dict, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(reproduce_yuksel, "record", _yuksel_record)
    monkeypatch.setattr(reproduce_yuksel, "free_air", lambda *a, **k: _FakeEnv())
    monkeypatch.setattr(reproduce_yuksel, "gym", SimpleNamespace(make=lambda *a, **k: _FakeEnv()))
    config = _shipped("reproduce_yuksel.yaml", [0, 1])
    config["fig6"]["torque_scales"] = [1.0]
    for name in ("fig4", "fig5", "fig6"):  # "wall" draws no figure
        reproduce_yuksel.PARTS[name](config, tmp_path)
    assert_clean(saved, {"fig4.png", "fig5.png", "fig6.png"})


def test_reproduce_hentzen(saved: dict, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(
        reproduce_hentzen, "fly", lambda config, label, estimator, seed, *a, **k: (_episode(seed), [1e-3] * 5)
    )
    monkeypatch.setattr(
        reproduce_hentzen,
        "episode_metrics",
        lambda env_id, ep: {"mean_tracking_error": 0.05 + 0.01 * ep.seed},
    )
    config = _shipped("reproduce_hentzen.yaml", [0, 1])
    for name in ("fig11", "fig9", "figure8"):  # "table1" draws no figure
        reproduce_hentzen.PARTS[name](config, tmp_path)
    expected = {f"fig11_{e}.png" for e in config["estimators"]} | {"fig9.png", "figure8.png"}
    assert_clean(saved, expected)


def test_the_check_finds_what_is_missing(saved: dict, tmp_path: Path) -> None:
    """The check itself: a figure without labels, units or legend is reported."""
    fig = Figure()
    ax = fig.add_subplot()
    ax.plot([0, 1], [0, 1])
    ax.plot([0, 1], [1, 0], label="b")
    ax.set_ylabel("f_z")
    fig.savefig(tmp_path / "bad.png")
    found = saved["bad.png"]
    assert any("no x label" in f for f in found)
    assert any("without a unit" in f for f in found)
    assert any("without a label" in f for f in found)
    assert any("no legend" in f for f in found)


def test_reproduce_yuksels_record_flies_a_short_episode() -> None:
    """``record`` itself (the figures' tests above replace it): 0.5 s of IDA-PBC hovering in free air
    under its own weight: the exerted force ``f_ne`` (the true rotors' thrust along body z minus the
    weight) is near zero at hover, and every column has a row per control step."""
    arena = {"x_min": -10.0, "x_max": 10.0, "y_half_width": 10.0, "z_max": 10.0}
    config = {"estimator": "observer", "free_air_height": 1.0, "free_air_seconds": 0.5}
    config["free_air_arena"] = arena
    env = reproduce_yuksel.free_air(config, [], drag=False)
    try:
        rows = reproduce_yuksel.record(env, IDAPBCPolicy(), 0, {"fan_motion": "static", "offset_y": 0.0})
    finally:
        env.close()
    assert {len(v) for v in rows.values()} == {25}
    weight = make_vehicle("yuksel1kg").mass * 9.81
    assert np.abs(rows["fne"]).max() < 0.05 * weight
