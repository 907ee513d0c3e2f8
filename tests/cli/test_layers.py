"""Layers: the command line lives in ``grace_dsl/cli`` and nothing below it imports it."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).parents[2] / "grace_dsl"


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
    return names


def test_nothing_outside_cli_imports_cli() -> None:
    offenders = {
        str(p.relative_to(PACKAGE)): sorted(m for m in _imports(p) if m.startswith("grace_dsl.cli"))
        for p in PACKAGE.rglob("*.py")
        if "cli" not in p.relative_to(PACKAGE).parts
    }
    assert {k: v for k, v in offenders.items() if v} == {}


def test_no_command_modules_outside_cli() -> None:
    assert not (PACKAGE / "export" / "command.py").exists()
    assert not (PACKAGE / "render" / "command.py").exists()
    for p in PACKAGE.rglob("*.py"):
        if "cli" not in p.relative_to(PACKAGE).parts:
            assert "argparse" not in _imports(p), p
