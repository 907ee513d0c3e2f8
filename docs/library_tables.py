"""The generated tables of docs/library.md: every concept of the standard library with its
picture, category, parameters and units, grasps and modes, actions and synopsis.

    python docs/library_tables.py            # rewrite the tables between the markers
    python docs/library_tables.py PAGE.md    # another page with the same markers

tests/test_library.py keeps the committed page equal to what this script writes.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from grace_dsl.agent.catalog import _cell, _para
from grace_dsl.runtime.library import Concept, Library

# Source file -> category, in the order of the tables; part concepts (mounted on objects by
# `part`) first. Files not listed are object concepts named after the file.
PART_FILES = {
    "handles.eac": "handle",
    "knobs.eac": "knob / dial",
    "switches.eac": "button / switch",
}
OBJECT_FILES = {
    "cabinets.eac": "cabinet",
    "doors.eac": "door",
    "appliances.eac": "appliance",
    "windows.eac": "window",
    "containers.eac": "container",
    "fixtures.eac": "fixture",
}
LIBRARY_TABLE_BEGIN = (
    "<!-- Generated from the library by docs/library_tables.py: after changing a concept, run\n"
    "`python docs/library_tables.py`. -->"
)
LIBRARY_TABLE_END = "<!-- End of the generated tables. -->"
_HEADER = (
    "| concept | picture | category (file) | parameters (unit) | grasps (mode) "
    "| actions (verb, sense; grasps used) | synopsis |"
)


def library_table(lib: Library) -> str:
    """The markdown tables of every concept of ``lib`` that is not a primitive: its category,
    picture (``gallery/NAME.png``), parameters with their units, grasps with their modes, actions
    with verb, sense and the grasps they use, and synopsis; part concepts, then object concepts,
    in the order of ``PART_FILES`` and ``OBJECT_FILES`` (other files last, by name)."""
    files = {**PART_FILES, **OBJECT_FILES}
    order = list(files)
    rows: dict[str, list[str]] = {}
    for name in lib:
        c = lib[name]
        if c.entry["kind"] == "primitive":
            continue
        rows.setdefault(c.entry["file"], []).append(_table_row(c, files))
    ranked = sorted(rows, key=lambda f: (order.index(f) if f in order else len(order), f))
    parts = [r for f in ranked if f in PART_FILES for r in rows[f]]
    objects = [r for f in ranked if f not in PART_FILES for r in rows[f]]
    out = [f"## Part concepts ({len(parts)})", "", _HEADER, "|---" * 7 + "|", *parts]
    out += ["", f"## Object concepts ({len(objects)})", "", _HEADER, "|---" * 7 + "|", *objects]
    return "\n".join(out) + "\n"


def _table_row(c: Concept, files: Mapping[str, str]) -> str:
    file = c.entry["file"]
    category = files.get(file, Path(file).stem.replace("_", " "))
    picture = f'<img src="gallery/{c.name}.png" width="160" alt="{c.name}">'
    params = ", ".join(f"`{p.name}` ({_unit(p)})" for p in c.params) or "-"
    grasps = _joined(f"`{g}` ({_grasp_how(e)})" for g, e in c.grasps.items())
    actions = _joined(_action_cell(a) for a in c.actions.values())
    cells = [c.name, picture, f"{category} (`{file}`)", params, grasps, actions, _para(c.doc)]
    return "| " + " | ".join(_cell(x) for x in cells) + " |"


def _joined(cells: Iterable[str]) -> str:
    """Cells once each after naming repeated copies by index letters (``drawer[0][1].open`` and
    ``drawer[2][0].open`` are both ``drawer[i][j].open``): a loop's copies are one row entry."""
    seen = dict.fromkeys(_generic(c) for c in cells)
    return ", ".join(seen) or "-"


def _generic(text: str) -> str:
    """Each index of a name replaced by a letter for its position: the first i, the second j."""

    def letter(m: re.Match[str]) -> str:
        depth = text[: m.start()].rsplit("`", 1)[-1].count("[")
        return "[" + "ijklmn"[depth] + "]"

    return re.sub(r"\[\d+\]", letter, text)


def _unit(p: Any) -> str:
    if p.kind == "choice":
        return "/".join(p.choices or ())
    if p.kind in ("bool", "int"):
        return p.kind
    unit = {"length": "m", "angle": "rad"}.get(p.dim or "", "-")
    return f"vec{p.size}, {unit}" if p.kind == "vec" else unit


def _grasp_how(g: Mapping[str, Any]) -> str:
    return g.get("mode", "pinch") + (", symmetric" if g.get("symmetric") else "")


def _action_cell(a: Mapping[str, Any]) -> str:
    where = f"along `{a['joint']}`" if a["joint"] else "toward"
    using = "; " + ", ".join(f"`{u}`" for u in a["using"]) if a["using"] else ""
    return f"`{a['name']}` ({a['verb']} {where}, {a['sense']}{using})"


def update_library_doc(path: str | Path, lib: Library) -> bool:
    """Write ``library_table(lib)`` between the markers of the markdown file ``path``; True if
    the file changed. Raises ``ValueError`` when the markers are missing."""
    path = Path(path)
    text = path.read_text("utf-8")
    span = _table_span(text)
    if span is None:
        raise ValueError(f"{path}: the generated-table markers are missing")
    start, end = span
    new = f"{text[:start]}\n\n{library_table(lib)}\n{text[end:]}"
    if new == text:
        return False
    path.write_text(new, "utf-8")
    return True


def generated_library_table(text: str) -> str | None:
    """The text between the markers of a markdown page (None without them)."""
    span = _table_span(text)
    return None if span is None else text[span[0] : span[1]].strip("\n") + "\n"


def _table_span(text: str) -> tuple[int, int] | None:
    """Where the generated tables sit: from the end of the begin marker to the end marker."""
    start, end = text.find(LIBRARY_TABLE_BEGIN), text.find(LIBRARY_TABLE_END)
    if start < 0 or end < start:
        return None
    return start + len(LIBRARY_TABLE_BEGIN), end


def main(argv: list[str]) -> None:
    from grace_dsl.runtime.library import load_library

    for target in argv or [str(Path(__file__).with_name("library.md"))]:
        changed = update_library_doc(target, load_library())
        print(f"{target}: {'updated' if changed else 'up to date'}")


if __name__ == "__main__":
    main(sys.argv[1:])
