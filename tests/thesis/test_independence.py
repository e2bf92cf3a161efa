"""The thesis oracle (humanoid_sim.thesis) stays independent of the simulator it checks."""

from __future__ import annotations

import ast
from pathlib import Path

from tests.conftest import ROOT

PKG = ROOT / "humanoid_sim"


def _imports(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
        elif isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
    return names


def test_oracle_package_imports_nothing_of_the_simulator():
    """An independent check must not share code with what it checks: the oracle imports only itself and the
    package's root modules (errors, paths)."""
    allowed = ("humanoid_sim.thesis", "humanoid_sim.errors", "humanoid_sim.paths")
    files = sorted((PKG / "thesis").rglob("*.py"))
    assert files
    for f in files:
        bad = [m for m in _imports(f) if m.split(".")[0] == "humanoid_sim" and not m.startswith(allowed)]
        assert not bad, (f.name, bad)
