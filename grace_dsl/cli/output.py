"""Terminal output: rich tables on a terminal, plain aligned text when piped, JSON on request."""

from __future__ import annotations

import json
import sys
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table

from grace_dsl.compiler.types import format_si


def console(stderr: bool = False) -> Console:
    return Console(stderr=stderr, highlight=False, soft_wrap=True)


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
            bar.update(task, total=total, completed=done, description=f"compiled {Path(file).name}")

        yield progress


def print_json(data: Any) -> None:
    sys.stdout.write(json.dumps(data, indent=2, default=_jsonable) + "\n")


def _jsonable(v: Any) -> Any:
    try:
        return float(v)
    except (TypeError, ValueError):
        return str(v)


def print_table(title: str, columns: Sequence[str], rows: Sequence[Sequence[str]]) -> None:
    out = console()
    if out.is_terminal:
        table = Table(title=title, title_justify="left")
        for c in columns:
            table.add_column(c, overflow="fold")
        for row in rows:
            table.add_row(*row)
        out.print(table)
        return
    widths = [max(len(str(x)) for x in [c, *(r[i] for r in rows)]) for i, c in enumerate(columns)]
    lines = [title, "  ".join(c.ljust(w) for c, w in zip(columns, widths)).rstrip()]
    lines += ["  ".join(str(x).ljust(w) for x, w in zip(r, widths)).rstrip() for r in rows]
    sys.stdout.write("\n".join(lines) + "\n")


def print_text(text: str, style: str | None = None) -> None:
    out = console()
    if out.is_terminal:
        out.print(text, style=style, markup=False)
    else:
        sys.stdout.write(text + "\n")


def fmt_value(value: Any, dim: str | None) -> str:
    """An SI value as people read it (``format_si``); ``-`` for none, quotes for a choice."""
    if value is None:
        return "-"
    if isinstance(value, str):
        return f'"{value}"'
    return format_si(value, dim)
