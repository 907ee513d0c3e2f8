"""The examples users copy are in canonical layout (``eacc fmt --check``) and the README shows
its example file exactly as it is on disk."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from grace_dsl.cli.eacc import main

ROOT = Path(__file__).parents[2]
EXAMPLES = sorted((ROOT / "docs" / "examples").glob("*.eac"))


def test_examples_pass_fmt_check(capsys: pytest.CaptureFixture[str]) -> None:
    assert EXAMPLES
    assert main(["fmt", "--check", *map(str, EXAMPLES)]) == 0, capsys.readouterr().out


def test_readme_listing_is_the_file() -> None:
    """The README names the file it lists (``A concept, from [`docs/examples/X.eac`]``) and
    its block is that file, byte for byte."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    m = re.search(
        r"A concept, from \[`(docs/examples/\w+\.eac)`\].*?```eac\n(.*?)```", readme, re.S
    )
    assert m is not None, "the README's example listing is gone"
    assert m.group(2) == (ROOT / m.group(1)).read_text(encoding="utf-8")
