"""The package ships its type information (PEP 561): ``py.typed`` exists and is package data."""

from __future__ import annotations

from pathlib import Path

import grace_dsl

ROOT = Path(__file__).resolve().parent.parent


def test_py_typed_ships_with_the_package() -> None:
    package = Path(grace_dsl.__file__).parent
    assert (package / "py.typed").is_file()
    data = (ROOT / "pyproject.toml").read_text().split("[tool.setuptools.package-data]", 1)[1]
    assert '"py.typed"' in data.split("\n[", 1)[0]  # tomllib is 3.11+; the project runs on 3.10


def test_lint_type_checks_the_whole_package() -> None:
    lint = (ROOT / "Makefile").read_text().split("\nlint:", 1)[1].split("\n\n", 1)[0]
    assert "mypy grace_dsl\n" in lint + "\n"
