"""Terminal output: rich tables on a terminal, plain aligned text when piped, JSON on request.

Doc strings, help texts, names and file contents are the user's text, not the program's: every
path to the terminal goes through ``clean`` (control characters escaped, so no ESC or OSC
sequence can retitle the window or fill the clipboard) and reaches rich as ``Text`` (so
``[link=...]`` or ``[/]`` is printed, never interpreted as markup).
"""

from __future__ import annotations

import json
import os
import re
import sys
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.table import Table
from rich.text import Text

from grace_dsl.compiler.types import format_si
from grace_dsl.lang.diagnostics import Diagnostic, has_errors, render_all

# C0 controls but tab and newline, DEL, C1 controls, and the bidirectional overrides that make a
# line read differently from what it holds.
_CONTROL = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\u200e\u200f\u202a-\u202e\u2066-\u2069]")


def clean(text: str) -> str:
    """``text`` safe for a terminal: control characters as escapes (``\\x1b``, ``\\u202e``)."""
    return _CONTROL.sub(_escape, text)


def _escape(m: re.Match[str]) -> str:
    code = ord(m.group())
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"


def console(stderr: bool = False) -> Console:
    return Console(stderr=stderr, highlight=False, soft_wrap=True, emoji=False, markup=False)


def error(message: str) -> None:
    """One line on stderr: ``eacc: <message>``."""
    sys.stderr.write(f"eacc: {clean(message)}\n")


def warning(message: str) -> None:
    sys.stderr.write(f"eacc: warning: {clean(message)}\n")


@contextmanager
def build_progress(enabled: bool = True) -> Iterator[Callable[[str, int, int], None] | None]:
    """A progress callback for builds: a transient bar on a terminal, nothing when piped."""
    out = console(stderr=True)
    if not (enabled and out.is_terminal):
        yield None
        return
    from rich.progress import Progress

    with Progress(console=out, transient=True) as bar:
        task = bar.add_task("compiling concepts", total=None)

        def progress(file: str, done: int, total: int) -> None:
            name = escape(clean(Path(file).name))  # a progress description is rich markup
            bar.update(task, total=total, completed=done, description=f"compiled {name}")

        yield progress


def print_json(data: Any) -> None:
    sys.stdout.write(json.dumps(data, indent=2, default=_jsonable) + "\n")


def _jsonable(v: Any) -> Any:
    try:
        return float(v)
    except (TypeError, ValueError):
        return str(v)


def print_table(title: str, columns: Sequence[str], rows: Sequence[Sequence[str]]) -> None:
    title = clean(title)
    rows = [[clean(str(x)) for x in r] for r in rows]
    out = console()
    if out.is_terminal:
        table = Table(title=Text(title), title_justify="left")
        for c in columns:
            table.add_column(Text(c), overflow="fold")
        for row in rows:
            table.add_row(*(Text(x) for x in row))
        out.print(table)
        return
    widths = [max(len(str(x)) for x in [c, *(r[i] for r in rows)]) for i, c in enumerate(columns)]
    lines = [title, "  ".join(c.ljust(w) for c, w in zip(columns, widths)).rstrip()]
    lines += ["  ".join(str(x).ljust(w) for x, w in zip(r, widths)).rstrip() for r in rows]
    sys.stdout.write("\n".join(lines) + "\n")


def print_text(text: str, style: str | None = None, stderr: bool = False) -> None:
    """A line (or lines) of text, styled on a terminal, with control characters escaped."""
    text = clean(text)
    out = console(stderr)
    if out.is_terminal:
        out.print(Text(text, style=style or ""))
    else:
        (sys.stderr if stderr else sys.stdout).write(text + "\n")


def count(n: int, one: str, many: str | None = None) -> str:
    """``count(1, "link")`` -> "1 link", ``count(2, "joint axis", "joint axes")`` -> "2 joint
    axes"."""
    return f"{n} {one if n == 1 else many or one + 's'}"


def fmt_value(value: Any, dim: str | None) -> str:
    """An SI value as people read it (``format_si``); ``-`` for none, quotes for a choice."""
    if value is None:
        return "-"
    if isinstance(value, str):
        return f'"{value}"'
    return format_si(value, dim)


# ---- diagnostics --------------------------------------------------------------------------------


def shown(path: str) -> str:
    """Paths below the working directory print relative to it, as the user typed them."""
    try:
        rel = os.path.relpath(path)
    except ValueError:
        return path
    return path if rel.startswith("..") else rel


def report_diagnostics(diags: Sequence[Diagnostic], sources: dict[str, str]) -> None:
    """Diagnostics with their source lines on stderr (red or yellow on a terminal), then the
    error count; source text is the user's, so control characters are escaped."""
    if not diags:
        return
    diags = [replace(d, span=replace(d.span, file=shown(d.span.file))) for d in diags]
    text = clean(render_all(diags, {shown(k): v for k, v in sources.items()}))
    err = console(stderr=True)
    if err.is_terminal:
        err.print(Text(text, style="red" if has_errors(diags) else "yellow"))
    else:
        sys.stderr.write(text + "\n")
    n = sum(d.severity == "error" for d in diags)
    sys.stderr.write(f"{n} error{'s' if n != 1 else ''}\n")
