"""The import rules of docs/architecture.md, as import-linter contracts (``[tool.importlinter]`` in
pyproject.toml): the layers (agents over envs over tasks over the engine over disturbances, scene and
estimators over sensors over kernels), no import circle in any package (lazy imports inside
functions included; annotations under ``TYPE_CHECKING`` never run and are left out), and the package
importing no command line."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from importlinter.cli import lint_imports

ROOT = Path(__file__).resolve().parent.parent


def test_every_import_rule_is_kept(monkeypatch, capsys):
    monkeypatch.chdir(ROOT)
    monkeypatch.syspath_prepend(str(ROOT))
    assert str(ROOT) in sys.path and os.getcwd() == str(ROOT)
    code = lint_imports(config_filename=str(ROOT / "pyproject.toml"), no_cache=True, no_logo=True)
    assert code == 0, capsys.readouterr().out
