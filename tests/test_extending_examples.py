"""docs/extending.md's examples run as written: each file of docs/examples/ appears on the page whole
(inside a python code block), and each ``*_run.py`` script passes its own checks when run from that
folder in a fresh interpreter (outside the package, its registrations its own)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "docs" / "examples"
PAGE = ROOT / "docs" / "extending.md"
FILES = sorted(p.name for p in EXAMPLES.glob("*.py"))
SCRIPTS = [name for name in FILES if name.endswith("_run.py")]


def test_every_kind_has_an_example_and_a_script():
    kinds = {
        "quasi_static.py",
        "thermal.py",
        "tether.py",
        "landing_pad.py",
        "hover_task.py",
        "compliant_hold.py",
    }
    assert kinds <= set(FILES)
    assert {name.removesuffix("_run.py") + ".py" for name in SCRIPTS} <= set(FILES)


@pytest.mark.parametrize("name", FILES)
def test_the_page_shows_the_example_file_as_written(name):
    blocks = re.findall(r"```python\n(.*?)```", PAGE.read_text(), flags=re.S)
    assert (EXAMPLES / name).read_text() in blocks, f"docs/extending.md lacks docs/examples/{name} as written"


@pytest.mark.parametrize("script", SCRIPTS)
def test_the_example_runs_as_written(script):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join((str(EXAMPLES), str(ROOT)))}
    run = subprocess.run(
        [sys.executable, script], cwd=EXAMPLES, env=env, capture_output=True, text=True, timeout=600
    )
    assert run.returncode == 0, f"{script} failed:\n{run.stdout}\n{run.stderr[-4000:]}"
