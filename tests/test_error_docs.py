"""docs/errors.md documents every diagnostic code, and the compiler emits only known codes."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from grace_dsl.lang.codes import CODES

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "errors.md"
SECTION = re.compile(r"^##\s+(E\d{3})\b[:\s]*(.*)$", re.MULTILINE)
CODE_LITERAL = re.compile(r"""["'](E\d{3})["']""")


def _sections() -> dict[str, str]:
    """Code -> heading text of each ``## Ennn: title`` section."""
    return {m.group(1): m.group(2).strip() for m in SECTION.finditer(DOC.read_text("utf-8"))}


def _codes_in_source() -> dict[str, list[str]]:
    """Every ``"Ennn"`` literal in grace_dsl/*.py, with the files that use it."""
    found: dict[str, list[str]] = {}
    for path in sorted((ROOT / "grace_dsl").rglob("*.py")):
        if path.name == "codes.py":
            continue
        for code in set(CODE_LITERAL.findall(path.read_text("utf-8"))):
            found.setdefault(code, []).append(str(path.relative_to(ROOT)))
    return found


@pytest.mark.parametrize("code", sorted(CODES))
def test_every_code_is_documented(code: str) -> None:
    sections = _sections()
    assert code in sections, f"docs/errors.md has no `## {code}` section"
    assert CODES[code] in sections[code], (
        f"the heading of {code} should carry its title {CODES[code]!r}, not {sections[code]!r}"
    )


def test_no_documented_code_is_unknown() -> None:
    assert sorted(set(_sections()) - set(CODES)) == []


def test_sections_are_in_order_and_unique() -> None:
    codes = SECTION.findall(DOC.read_text("utf-8"))
    listed = [c for c, _ in codes]
    assert listed == sorted(set(listed))


def test_source_emits_only_known_codes() -> None:
    used = _codes_in_source()
    unknown = {c: files for c, files in used.items() if c not in CODES}
    assert not unknown, f"codes used in grace_dsl but missing from CODES: {unknown}"
    assert len(used) >= 30  # the scan finds the emitting code at all


GOLDEN = ROOT / "tests" / "golden"
EXAMPLE = re.compile(r"^`(E\d{3}_[A-Za-z0-9_]+)(?:\.eac|/[^`]+)`:$", re.MULTILINE)
TEXT_BLOCK = re.compile(r"```text\n(.*?)```", re.DOTALL)


def _doc_outputs(doc: str) -> list[tuple[str, re.Match[str]]]:
    """(golden case, the ```text block after its example) for every example in the doc."""
    found, seen = [], set()
    for m in EXAMPLE.finditer(doc):
        case = m.group(1)
        if case in seen:
            continue
        seen.add(case)
        block = TEXT_BLOCK.search(doc, m.end())
        if block is not None:
            found.append((case, block))
    return found


def test_examples_show_the_golden_output() -> None:
    """The rendered diagnostics in docs/errors.md are the golden outputs, byte for byte.

    ``UPDATE_GOLDEN=1`` rewrites them from tests/golden/*.expected.
    """
    import os

    doc = DOC.read_text("utf-8")
    stale = []
    for case, block in reversed(_doc_outputs(doc)):
        expected = (GOLDEN / f"{case}.expected").read_text("utf-8")
        if block.group(1) != expected:
            stale.append(case)
            doc = doc[: block.start(1)] + expected + doc[block.end(1) :]
    if stale and os.environ.get("UPDATE_GOLDEN"):
        DOC.write_text(doc, "utf-8")
        return
    assert stale == [], f"docs/errors.md shows stale output for {stale}; run with UPDATE_GOLDEN=1"
