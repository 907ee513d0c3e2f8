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
