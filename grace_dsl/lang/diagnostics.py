"""Diagnostics are values: every pass returns them instead of raising.

A diagnostic renders as ``file:line:col: error[E012]: message``, followed by the source line, a
caret under the span and an optional hint.  Codes are documented in ``docs/errors.md``.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from grace_dsl.lang.ast import NO_SPAN, Span


@dataclass(frozen=True)
class Diagnostic:
    code: str
    message: str
    span: Span = NO_SPAN
    hint: str | None = None
    severity: str = "error"  # "error" | "warning"

    def render(self, source: str | None = None) -> str:
        """The diagnostic as text; with ``source`` it shows the line and a caret under the span."""
        s = self.span
        where = f"{s.file}:{s.line}:{s.col}" if s.line else s.file
        lines = [f"{where}: {self.severity}[{self.code}]: {self.message}"]
        if source is not None and s.line:
            lines += _excerpt(source, s)
        if self.hint:
            lines.append(f"  = hint: {self.hint}")
        return "\n".join(lines)

    def to_json(self) -> dict[str, object]:
        s = self.span
        return {
            "code": self.code,
            "severity": self.severity,
            "message": self.message,
            "file": s.file,
            "line": s.line,
            "col": s.col,
            "end_line": s.end_line,
            "end_col": s.end_col,
            "hint": self.hint,
        }


def _excerpt(source: str, span: Span) -> list[str]:
    src_lines = source.splitlines()
    if not 1 <= span.line <= len(src_lines):
        return []
    text = src_lines[span.line - 1].expandtabs(1)
    end = span.end_col if span.end_line == span.line else len(text) + 1
    width = max(1, end - span.col)
    gutter = f"{span.line:>4} | "
    return [gutter + text, " " * (len(gutter) + span.col - 1) + "^" * width]


def error(code: str, message: str, span: Span, hint: str | None = None) -> Diagnostic:
    return Diagnostic(code, message, span, hint)


def has_errors(diags: Iterable[Diagnostic]) -> bool:
    return any(d.severity == "error" for d in diags)


def closest(name: str, candidates: Iterable[str]) -> str | None:
    """The candidate a misspelt ``name`` most likely meant, or None when nothing is close."""
    matches = difflib.get_close_matches(name, list(candidates), n=1, cutoff=0.6)
    return matches[0] if matches else None


def did_you_mean(name: str, candidates: Iterable[str]) -> str | None:
    """A "did you mean `x`?" hint for a misspelt name, or None when nothing is close."""
    match = closest(name, candidates)
    return f"did you mean `{match}`?" if match else None


def render_all(diags: Sequence[Diagnostic], sources: dict[str, str]) -> str:
    """All diagnostics, sorted by position, each with its source excerpt."""
    ordered = sorted(diags, key=lambda d: (d.span.file, d.span.line, d.span.col, d.code))
    return "\n\n".join(d.render(sources.get(d.span.file)) for d in ordered)
