"""The pages a user reads name no folder of the machine they were written on: commands in them run
from the repository's root on any machine."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
POLICIES = ROOT / "quad_wrench_env" / "agents" / "policies"
PAGES = sorted(
    [
        ROOT / "README.md",
        *(ROOT / "docs").rglob("*.md"),
        *(ROOT / "configs").glob("*.yaml"),
        *POLICIES.glob("*/*.md"),
    ]
)
MACHINE_PATH = re.compile(r"(?<![\w.~-])/(?:work|root|home|tmp|Users|mnt|scratch)/|\b[A-Z]:\\\\")
"""An absolute folder of a machine (``/work/runs/...``, ``/home/me/...``, ``C:\\...``)."""


def test_the_pattern_finds_a_machine_path_and_leaves_a_relative_one():
    assert MACHINE_PATH.search("quad-wrench evaluate /work/runs/oracle QuadWrench/FanTracking-v1")
    assert MACHINE_PATH.search("see /home/me/x.csv")
    assert not MACHINE_PATH.search("quad-wrench evaluate runs/oracle --json results/out.json")


@pytest.mark.parametrize("page", PAGES, ids=lambda page: str(page.relative_to(ROOT)))
def test_no_page_names_a_machine_path(page):
    found = [
        f"line {number}: {line.strip()}"
        for number, line in enumerate(page.read_text().splitlines(), 1)
        if MACHINE_PATH.search(line)
    ]
    assert not found, found
