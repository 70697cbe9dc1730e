"""What the subcommands share: config files, argument types, errors of the user's making (reported as
argparse reports its own: the usage, a message, exit code 2) and output (markdown shown on the
terminal, JSON and CSV files for tools)."""

from __future__ import annotations

import argparse
import csv
import json
import math
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np
from rich.console import Console
from rich.markdown import Markdown

from quad_wrench_env.config import config_path, load_yaml

if TYPE_CHECKING:
    from matplotlib.figure import Figure

ENV_NAMESPACE = "QuadWrench/"


class UsageError(Exception):
    """A bad value on the command line or in a file it names: the subcommand's usage, the message and
    exit code 2, no traceback."""


@contextmanager
def usage_errors() -> Iterator[None]:
    """Turns the project's refusals of a bad value raised inside (``ValueError``, ``FileNotFoundError``,
    the ``KeyError`` of a missing config key) into :class:`UsageError`. Wrap only the reading and
    checking of inputs, so that a bug in a long run still shows its traceback."""
    try:
        yield
    except KeyError as error:
        raise UsageError(f"missing config key {error.args[0]!r}") from None
    except (ValueError, FileNotFoundError) as error:
        raise UsageError(str(error)) from None


def seed(text: str) -> int:
    """argparse type: a seed, an integer >= 0."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"seed {text!r} must be an integer >= 0")
    return value


def key_value(text: str) -> str:
    """argparse type: ``KEY=VALUE`` (the form checked here; :func:`quad_wrench_env.config.apply_overrides`
    reads the value as YAML and lets dots reach into sections)."""
    key, separator, _ = text.partition("=")
    if not (separator and key):
        raise argparse.ArgumentTypeError(f"{text!r} must read KEY=VALUE")
    return text


def add_key_value_argument(parser: argparse.ArgumentParser, flag: str, help: str) -> None:
    """A repeatable ``flag KEY=VALUE`` option (collected as a list of strings, each checked by
    :func:`key_value`)."""
    parser.add_argument(flag, action="append", default=[], type=key_value, metavar="KEY=VALUE", help=help)


def json_object(text: str) -> dict[str, Any]:
    """argparse type: a JSON object, e.g. ``'{"fan_motion": "static", "offset_y": 0.8}'``."""
    try:
        value = json.loads(text)
    except json.JSONDecodeError as error:
        raise argparse.ArgumentTypeError(f"{text!r} is not JSON: {error}") from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(f"{text!r} must be a JSON object ({{...}})")
    return value


def env_ids() -> list[str]:
    """The registered env ids of this project's tasks (``import quad_wrench_env`` registers them)."""
    return [name for name in gym.registry if name.startswith(ENV_NAMESPACE)]


def env_id(text: str) -> str:
    """argparse type: a registered env id of this project, with or without ``quad_wrench_env:``."""
    if text.split(":", 1)[-1] not in env_ids():
        raise argparse.ArgumentTypeError(f"unknown env id {text!r}; allowed: {env_ids()}")
    return text


def add_config_argument(parser: argparse.ArgumentParser, name: str) -> None:
    """``--config YAML``, by default the shipped ``configs/<name>``."""
    parser.add_argument(
        "--config",
        metavar="YAML",
        help=f"the config file, used as given (default: the shipped configs/{name}; see quad-wrench list)",
    )


def load_config(given: str | None, name: str) -> tuple[dict[str, Any], str]:
    """The config file ``given`` (a path, used as it is) or else the shipped ``configs/<name>`` (found
    wherever the package is installed), and the label that reports name it by."""
    with usage_errors():
        if given is None:
            return load_yaml(config_path(name)), f"configs/{name}"
        return load_yaml(given), given


def markdown_table(header: list[str], rows: list[list[str]]) -> str:
    """A markdown table of ``header`` and ``rows`` (cells already formatted)."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return "\n".join(lines + ["| " + " | ".join(row) + " |" for row in rows])


def show(markdown: str) -> None:
    """Print ``markdown``: rendered by rich on a terminal (tables as tables), as it is to a pipe or a
    file."""
    console = Console()
    if console.is_terminal:
        console.print(Markdown(markdown))
    else:
        print(markdown, flush=True)


def to_json(data: Any) -> str:
    """``data`` as JSON that any reader takes: numpy numbers as numbers, NaN and infinities (a metric
    undefined or never reached) as null."""
    return json.dumps(_plain(data), indent=2)


def _plain(value: Any) -> Any:
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def write_json(path: str | Path, data: Any) -> None:
    """:func:`to_json` of ``data`` into ``path`` (its folder made where missing)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(to_json(data) + "\n")


def write_csv(path: str | Path, rows: Sequence[Mapping[str, Any]]) -> None:
    """``rows`` (mappings with the same keys, in order) as CSV with a header into ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def save_figure(fig: Figure, path: str | Path, dpi: int = 120) -> None:
    """Lay ``fig`` out, write it to ``path`` and close it (every job's figures end this way)."""
    import matplotlib.pyplot as plt  # not at import: --help stays quick

    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
