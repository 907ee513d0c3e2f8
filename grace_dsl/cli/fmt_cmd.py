"""``eacc fmt``: rewrite ``.eac`` files in canonical layout, or ``--check`` that they are.

A source file is the one thing here that exists nowhere else, so a rewrite must never lose it:
the new text goes to a temporary file beside the old one, is read back and parsed, and replaces
the old file only when it is the same program (``cli.files.atomic_write``). On a full disk, under
a file-size limit or after any other failure the original is untouched. A byte-order mark is
accepted (and kept), as the compiler accepts it; a read-only file is left alone.
"""

from __future__ import annotations

import argparse
import os
import stat
import sys
from pathlib import Path

from grace_dsl.cli.files import BOM, UserFileError, atomic_write, eac_files, read_bytes, read_source
from grace_dsl.cli.output import error, print_text, report_diagnostics, warning
from grace_dsl.lang import ast
from grace_dsl.lang.formatter import format_source
from grace_dsl.lang.parser import parse


def add_fmt_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("paths", nargs="+", help="files or directories; `-` reads stdin")
    p.add_argument("--check", action="store_true", help="exit 1 if a file is not formatted")


def run_fmt(args: argparse.Namespace) -> int:
    """Exit 0 when every file is (now) formatted, 1 when one is not or cannot be."""
    files, skipped = eac_files(args.paths)
    for s in skipped:
        if s.path in args.paths:
            error(f"{s.path}: {s.reason}")
        else:
            warning(f"skipped {s.path}: {s.reason}")
    status = 1 if any(s.path in args.paths for s in skipped) else 0
    for path in files:
        try:
            status |= _stdin(args.check) if path == "-" else _file(Path(path), args.check)
        except UserFileError as exc:
            error(str(exc))
            status = 1
    return status


def _stdin(check: bool) -> int:
    data = sys.stdin.buffer.read()
    try:
        text = data.decode("utf-8").removeprefix(BOM)
    except UnicodeDecodeError as exc:
        raise UserFileError(f"<stdin>: not UTF-8 text (byte 0x{data[exc.start]:02x})") from None
    result = format_source(text, "<stdin>")
    if result.text is None:
        report_diagnostics(list(result.diagnostics), {"<stdin>": text})
        return 1
    if check:
        return int(result.text != text)
    sys.stdout.write(result.text)
    return 0


def _file(path: Path, check: bool) -> int:
    source = read_source(path)
    result = format_source(source.text, str(path))
    if result.text is None:
        report_diagnostics(list(result.diagnostics), {str(path): source.text})
        return 1
    if result.text == source.text:
        return 0
    if check:
        print_text(f"would reformat {path}")
        return 1
    real = Path(os.path.realpath(path))  # a symlinked source: rewrite the file it names
    if not real.stat().st_mode & (stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH):
        raise UserFileError(f"{path}: the file is read-only; not reformatted")
    program = _program(source.text, str(path))
    new = (BOM if source.bom else "") + result.text
    atomic_write(real, new, verify=lambda tmp: _same_program(tmp, program, path))
    print_text(f"formatted {path}")
    return 0


Program = tuple[tuple[ast.Use, ...], tuple[ast.Concept, ...]]


def _program(text: str, path: str) -> Program | None:
    """The syntax tree without positions (``Span``s do not compare), None if it has errors."""
    parsed = parse(text, path)
    if parsed.module is None or any(d.severity == "error" for d in parsed.diagnostics):
        return None
    return parsed.module.uses, parsed.module.concepts


def _same_program(written: Path, program: Program | None, path: Path) -> None:
    """Refuse a written file that does not read back as the program it was formatted from."""
    try:
        text = read_bytes(written).decode("utf-8").removeprefix(BOM)
    except (UserFileError, UnicodeDecodeError):
        text = None
    if text is None or program is None or _program(text, str(path)) != program:
        raise UserFileError(
            f"{path}: the formatted text does not read back as the same program; the file is "
            "unchanged (please report this formatter bug)"
        )
