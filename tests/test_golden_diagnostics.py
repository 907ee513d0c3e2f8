"""Golden tests: the exact rendered diagnostics for one small bad program per error code.

Each case is ``tests/golden/<code>_<name>.eac`` (or a directory ``tests/golden/<code>_<name>/``
of .eac files, for errors that need several files) with its expected output in
``tests/golden/<code>_<name>.expected``.  The test runs resolve and check on the case, renders
every diagnostic with ``render_all`` and compares the text, with file paths made relative to
``tests/golden`` (and the standard library shown as ``<stdlib>``) so it does not depend on the
machine.

After an intended change to a message, span or hint, rewrite the expected files with::

    UPDATE_GOLDEN=1 .venv/bin/python -m pytest tests/test_golden_diagnostics.py

and review the diff of ``tests/golden/*.expected`` before committing it.
"""

from __future__ import annotations

import difflib
import os
import re
from pathlib import Path

import pytest

from grace_dsl.compiler.check import check
from grace_dsl.compiler.resolve import resolve, stdlib_dir
from grace_dsl.lang.codes import CODES
from grace_dsl.lang.diagnostics import Diagnostic, render_all

GOLDEN = Path(__file__).resolve().parent / "golden"
UPDATE = os.environ.get("UPDATE_GOLDEN") == "1"


def _cases() -> list[Path]:
    """Every golden case: top-level .eac files and directories of .eac files."""
    return sorted(
        p
        for p in GOLDEN.iterdir()
        if (p.suffix == ".eac" and p.is_file()) or (p.is_dir() and any(p.rglob("*.eac")))
    )


def _normalise(text: str) -> str:
    """Make absolute paths relative to tests/golden and the standard library ``<stdlib>``."""
    for base, shown in ((GOLDEN, ""), (stdlib_dir(), "<stdlib>/")):
        text = text.replace(str(base) + os.sep, shown).replace(str(base), shown.rstrip("/") or ".")
    return text


def run_case(case: Path) -> tuple[list[Diagnostic], str]:
    """Resolve and check one case; its diagnostics and their normalised rendering."""
    prog, diags = resolve([case])
    _, more = check(prog)
    everything = diags + more
    return everything, _normalise(render_all(everything, prog.sources())) + "\n"


def _code_of(case: Path) -> str:
    match = re.match(r"(E\d{3})_\w+", case.stem if case.is_file() else case.name)
    assert match, f"golden case {case.name} must be named <code>_<name>"
    return match.group(1)


CASES = _cases()


def test_enough_codes_covered() -> None:
    covered = {_code_of(c) for c in CASES}
    assert len(covered) >= 30, sorted(covered)
    assert covered <= set(CODES), sorted(covered - set(CODES))


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_golden(case: Path) -> None:
    diags, rendered = run_case(case)
    code = _code_of(case)
    assert code in {d.code for d in diags}, f"{case.name} should report {code}:\n{rendered}"
    assert "Traceback" not in rendered
    expected_file = GOLDEN / f"{case.stem if case.is_file() else case.name}.expected"
    if UPDATE:
        expected_file.write_text(rendered, encoding="utf-8")
    assert expected_file.is_file(), f"missing {expected_file.name}; run with UPDATE_GOLDEN=1"
    expected = expected_file.read_text(encoding="utf-8")
    diff = "".join(
        difflib.unified_diff(
            expected.splitlines(True), rendered.splitlines(True), "expected", "actual"
        )
    )
    assert rendered == expected, f"{case.name} renders differently:\n{diff}"


def test_no_orphan_expected_files() -> None:
    names = {c.stem if c.is_file() else c.name for c in CASES}
    orphans = [p.name for p in GOLDEN.glob("*.expected") if p.stem not in names]
    assert not orphans, f"expected files without a case: {orphans}"
