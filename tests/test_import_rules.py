"""The import rules of docs/architecture.md, as import-linter contracts (``[tool.importlinter]`` in
pyproject.toml): the layers (agents over envs over tasks and control over the engine over disturbances,
scene and estimators over sensors over kernels), no import circle in any package (lazy imports inside
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


def test_no_module_name_stands_for_two_things():
    """A module's file name appears once under quad_wrench_env/ (``__init__.py`` and a subpackage's
    ``base.py`` aside; an estimator beside its kernel is ``<name>.py`` and ``<name>_kernel.py``), so
    that a name in a traceback or an import says which module it is."""
    names: dict[str, list[str]] = {}
    for path in sorted((ROOT / "quad_wrench_env").rglob("*.py")):
        if path.name not in ("__init__.py", "base.py"):
            names.setdefault(path.name, []).append(str(path.relative_to(ROOT)))
    twice = {name: paths for name, paths in names.items() if len(paths) > 1}
    assert not twice, twice
