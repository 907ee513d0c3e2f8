"""``eacc``: the .eac compiler's command line (thin: parse arguments, call the library, print).

Exit codes: 0 success, 1 diagnostics (or files that need formatting), 2 usage errors.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from grace_dsl.cli.files import UserFileError, atomic_write, eac_files, read_source
from grace_dsl.cli.output import (
    build_progress,
    count,
    error,
    fmt_value,
    print_json,
    print_table,
    print_text,
    report_diagnostics,
    warning,
)
from grace_dsl.compiler.build import build, export_library, front_end
from grace_dsl.compiler.resolve import stdlib_dir
from grace_dsl.lang.diagnostics import has_errors


def main(argv: Sequence[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help()
        return 2
    try:
        return int(args.run(args))
    except KeyboardInterrupt:
        return 130


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="eacc", description="Compile executable analytic concepts.")
    sub = p.add_subparsers(dest="command")

    c = sub.add_parser("check", help="report every problem in .eac files")
    c.add_argument("paths", nargs="+", help=".eac files or directories")
    c.add_argument("--json", action="store_true", help="machine-readable diagnostics")
    _search_path(c)
    c.set_defaults(run=cmd_check)

    b = sub.add_parser("build", help="compile .eac files into a cached library artifact")
    b.add_argument("paths", nargs="+")
    b.add_argument("-o", "--output", type=Path, help="write a self-contained artifact here")
    b.add_argument("--cache-dir", type=Path, help="cache directory (default: user cache)")
    b.add_argument("--no-native", action="store_true", help="skip compiling C kernels")
    b.add_argument("--json", action="store_true")
    _search_path(b)
    b.set_defaults(run=cmd_build)

    from grace_dsl.cli.fmt_cmd import add_fmt_arguments, run_fmt

    f = sub.add_parser("fmt", help="format .eac files in place (or check them)")
    add_fmt_arguments(f)
    f.set_defaults(run=run_fmt)

    ls = sub.add_parser("list", help="list the concepts of a library")
    ls.add_argument("paths", nargs="*", help="default: the standard library")
    ls.add_argument("--json", action="store_true")
    _search_path(ls)
    ls.set_defaults(run=cmd_list)

    e = sub.add_parser("explain", help="parameters, grasps, actions and formulas of a concept")
    e.add_argument("concept")
    e.add_argument("paths", nargs="*", help="default: the standard library")
    e.add_argument("--json", action="store_true")
    _search_path(e)
    e.set_defaults(run=cmd_explain)

    pr = sub.add_parser("prompt", help="the concept catalog a vision-language model reads")
    pr.add_argument("paths", nargs="*", help="default: the standard library")
    pr.add_argument("--format", choices=("md", "json"), default="md")
    pr.add_argument("--json", action="store_const", const="json", dest="format")
    pr.add_argument("-o", "--output", type=Path, help="write here instead of stdout")
    pr.add_argument("--concept", action="append", default=[], metavar="NAME", help="only these")
    _search_path(pr)
    pr.set_defaults(run=cmd_prompt)

    from grace_dsl.cli.export_cmd import add_export_arguments
    from grace_dsl.cli.show_cmd import add_gallery_arguments, add_show_arguments

    x = sub.add_parser("export", help="write an instance as URDF, MJCF or a mesh (OBJ/STL/GLB)")
    add_export_arguments(x)
    _search_path(x)
    x.set_defaults(run=cmd_export)

    sh = sub.add_parser("show", help="draw an instance: a PNG (MuJoCo) or an HTML viewer")
    add_show_arguments(sh)
    _search_path(sh)
    sh.set_defaults(run=cmd_show)

    ga = sub.add_parser("gallery", help="a PNG of every concept and primitive (docs/gallery)")
    add_gallery_arguments(ga)
    _search_path(ga)
    ga.set_defaults(run=cmd_gallery)

    from grace_dsl.cli.verify import add_verify_arguments

    v = sub.add_parser("verify", help="check every concept's grasps and actions over random draws")
    add_verify_arguments(v)
    _search_path(v)
    v.set_defaults(run=cmd_verify)
    return p


def _search_path(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "-I",
        "--search-path",
        action="append",
        default=[],
        metavar="DIR",
        help="look for imported modules here too (also: GRACE_EAC_PATH)",
    )


# ---- check / build ------------------------------------------------------------------------------


def sources(paths: Sequence[str]) -> list[str] | None:
    """The .eac files that ``paths`` name, for the compiler: directories are searched here, so
    that what cannot be read (a FIFO, a symlink loop, a symlink to a file that is not .eac) is
    skipped with a warning instead of blocking or failing the command; a file named directly
    that cannot be read is an error (None)."""
    files, skipped = eac_files(paths)
    bad = False
    for s in skipped:
        if s.path in paths:
            error(f"{s.path}: {s.reason}")
            bad = True
        else:
            warning(f"skipped {s.path}: {s.reason}")
    return None if bad else files


def cmd_check(args: argparse.Namespace) -> int:
    paths = sources(args.paths)
    if paths is None:
        return 1
    prog, checked, diags = front_end(paths, args.search_path)
    if args.json:
        print_json(
            {
                "ok": not has_errors(diags),
                "files": list(prog.files),
                "concepts": sorted(prog.concepts),
                "diagnostics": [d.to_json() for d in diags],
            }
        )
    else:
        report_diagnostics(diags, prog.sources())
        if not has_errors(diags):
            concepts, files = count(len(prog.concepts), "concept"), count(len(prog.files), "file")
            print_text(f"ok: {concepts} in {files}")
    return 1 if has_errors(diags) else 0


def cmd_build(args: argparse.Namespace) -> int:
    paths = sources(args.paths)
    if paths is None:
        return 1
    with build_progress(not args.json) as progress:
        result = build(
            paths,
            args.cache_dir,
            args.search_path,
            use_native=not args.no_native,
            progress=progress,
        )
    diags = list(result.diagnostics)
    if result.ok and args.output is not None:
        diags += export_library(result, args.output)
    ok = not has_errors(diags)
    if args.json:
        print_json(
            {
                "ok": ok,
                "diagnostics": [d.to_json() for d in diags],
                "cache_dir": str(result.cache_dir) if result.cache_dir else None,
                "output": str(args.output) if args.output else None,
                "units": [
                    {
                        "file": u.file,
                        "key": u.key,
                        "concepts": sorted(u.concepts),
                        "rebuilt": u.file in result.rebuilt,
                    }
                    for u in result.units
                ],
            }
        )
        return 0 if ok else 1
    report_diagnostics(diags, result.sources)
    if ok:
        n = sum(len(u.concepts) for u in result.units)
        where = args.output or result.cache_dir
        print_text(
            f"built {n} concepts from {len(result.units)} files "
            f"({len(result.rebuilt)} compiled, {len(result.units) - len(result.rebuilt)} "
            f"cached) -> {where}"
        )
    return 0 if ok else 1


# ---- list / explain -----------------------------------------------------------------------------


def _library(paths: Sequence[str], search_path: Sequence[str]) -> Any:
    from grace_dsl.runtime.errors import CompileError
    from grace_dsl.runtime.library import compile_paths

    files = sources(paths) if paths else [str(stdlib_dir())]
    if files is None:
        return None
    try:
        with build_progress() as progress:
            return compile_paths(files, search_path=search_path, progress=progress)
    except CompileError as exc:
        report_diagnostics(list(exc.diagnostics), _sources_of(exc))  # type: ignore[arg-type]
        return None


def _sources_of(exc: Exception) -> dict[str, str]:
    """The source texts a ``CompileError``'s diagnostics point into (for their excerpts)."""
    sources: dict[str, str] = {}
    for d in getattr(exc, "diagnostics", ()):
        f = d.span.file
        if f not in sources:
            with contextlib.suppress(UserFileError):
                sources[f] = read_source(Path(f)).text
    return sources


def cmd_list(args: argparse.Namespace) -> int:
    lib = _library(args.paths, args.search_path)
    if lib is None:
        return 1
    concepts = [lib[n] for n in lib]
    if args.json:
        print_json(
            [
                {
                    "name": c.name,
                    "kind": c.entry["kind"],
                    "file": c.entry["file"],
                    "doc": c.doc,
                    "params": [p.name for p in c.params],
                    "grasps": list(c.grasps),
                    "actions": list(c.actions),
                    "joints": list(c.joints),
                }
                for c in concepts
            ]
        )
        return 0
    rows = [
        [
            c.name,
            c.entry["kind"],
            c.entry["file"],
            str(len(c.params)),
            ", ".join(c.grasps) or "-",
            ", ".join(c.actions) or "-",
            (c.doc.splitlines() or [""])[0],
        ]
        for c in concepts
    ]
    print_table(
        count(len(rows), "concept"),
        ["concept", "kind", "file", "params", "grasps", "actions", "synopsis"],
        rows,
    )
    return 0


def _explain_repeats(c: Any) -> None:
    """Repeated members and variant parts, when the concept has any (``runtime/masks.py``)."""
    from grace_dsl.runtime.masks import repeats

    rows = [
        [base, f"{r['indices'][0]} .. {r['indices'][-1]}", ", ".join(r["counts"]) or "-"]
        for base, r in repeats(c.entry).items()
    ]
    if rows:
        print_table("repeated (a copy exists while its index is below the count)",
                    ["name", "indices", "count"], rows)  # fmt: skip
    variants = c.entry.get("variants") or {}
    if variants:
        print_table(
            "variant parts (the choice picks the part; NAME.grasp is the chosen option's grasp)",
            ["part", "chosen by", "options"],
            [
                [name, v["param"], ", ".join(_option(c, o, p) for o, p in v["options"].items())]
                for name, v in variants.items()
            ],
        )


def _option(c: Any, option: str, part: str) -> str:
    return f'"{option}": {c.parts.get(part, "?")} ({part})'


def cmd_explain(args: argparse.Namespace) -> int:
    lib = _library(args.paths, args.search_path)
    if lib is None:
        return 1
    if args.concept not in lib:
        try:
            lib[args.concept]
        except KeyError as exc:
            error(str(exc) + _defined_here(args.concept))
        return 1
    c = lib[args.concept]
    if args.json:
        print_json(c.entry)
        return 0
    print_text(f"{c.name} ({c.entry['kind']}, {c.entry['file']})", style="bold")
    if c.doc:
        print_text(c.doc)
    print_table(
        "parameters",
        ["name", "type", "range", "default", "meaning"],
        [
            [
                p.name,
                p.type,
                f"[{fmt_value(p.lo, p.dim)}, {fmt_value(p.hi, p.dim)}]"
                if p.lo is not None
                else "-",
                fmt_value(p.decode([p.default]) if p.kind == "choice" else p.default, p.dim),
                " ".join(x for x in (p.help or "", p.doc) if x),
            ]
            for p in c.params
        ],
    )
    _explain_repeats(c)
    if c.joints:
        print_table(
            "joints",
            ["name", "kind", "parent -> child", "doc"],
            [
                [j["name"], j["kind"], f"{j['parent']} -> {j['child']}", j["doc"]]
                for j in c.joints.values()
            ],
        )
    for g in c.grasps.values():
        free = ", ".join(f["name"] for f in g["free"]) or "no free parameters"
        how = g.get("mode", "pinch") + (", symmetric" if g.get("symmetric") else "")
        print_text(f"grasp {g['name']}({free}) on link {g['link']}, by {how}", style="bold")
        if g["doc"]:
            print_text("  " + g["doc"].replace("\n", "\n  "))
        if g.get("when"):
            print_text(f"  applies only when {g['when']['condition']} ({g['when']['where']})")
        if "." in g["name"]:
            part = g["name"].rsplit(".", 1)[0]
            print_text(
                f"  from part {part} ({c.parts.get(part, '?')}): its formula there, placed "
                "by the part's pose and the joints above it"
            )
        else:
            print_text(f"  G = {g['source']}")
            print_text(f"    = {g['formula']['text']}")
    if c.actions:
        print_table(
            "actions",
            ["name", "verb", "along", "sense", "using", "synopsis"],
            [
                [
                    a["name"],
                    a["verb"],
                    a["joint"] or "fixed direction",
                    a["sense"],
                    ", ".join(a["using"]) or "-",
                    a["doc"],
                ]
                for a in c.actions.values()
            ],
        )
    return 0


def _defined_here(name: str) -> str:
    """``"; ./door.eac defines it: eacc explain Door door.eac"`` when a ``.eac`` file in the
    working directory declares ``name`` (read with the parser, so comments do not count)."""
    from grace_dsl.lang.parser import parse

    for path in sorted(Path.cwd().glob("*.eac")):
        try:
            module = parse(read_source(path).text, str(path)).module
        except UserFileError:
            continue
        if module is not None and any(c.name == name for c in module.concepts):
            return f"; {path.name} in this directory defines it: eacc explain {name} {path.name}"
    return ""


def cmd_prompt(args: argparse.Namespace) -> int:
    from grace_dsl.agent.catalog import build_catalog, render_json, render_markdown
    from grace_dsl.runtime.errors import UnknownNameError

    lib = _library(args.paths, args.search_path)
    if lib is None:
        return 1
    try:
        catalog = build_catalog(lib, args.concept or None)
    except UnknownNameError as exc:
        error(str(exc.args[0]))
        return 1
    text = render_json(catalog) if args.format == "json" else render_markdown(catalog)
    if args.output is None:
        sys.stdout.write(text)
        return 0
    try:
        note = atomic_write(args.output, text).note()
    except UserFileError as exc:
        error(str(exc))
        return 1
    if note:
        print_text(f"note: {note}", stderr=True)
    return 0


# ---- export -------------------------------------------------------------------------------------


def cmd_export(args: argparse.Namespace) -> int:
    from grace_dsl.cli.export_cmd import run_export

    lib = _library(args.paths, args.search_path)
    return 1 if lib is None else run_export(args, lib)


# ---- show / gallery -----------------------------------------------------------------------------


def cmd_show(args: argparse.Namespace) -> int:
    from grace_dsl.cli.show_cmd import run_show

    lib = _library(args.paths, args.search_path)
    return 1 if lib is None else run_show(args, lib)


def cmd_gallery(args: argparse.Namespace) -> int:
    from grace_dsl.cli.show_cmd import run_gallery

    lib = _library(args.paths, args.search_path)
    return 1 if lib is None else run_gallery(args, lib)


# ---- verify -------------------------------------------------------------------------------------


def cmd_verify(args: argparse.Namespace) -> int:
    from grace_dsl.cli.verify import run_verify

    lib = _library(args.paths, args.search_path)
    return 1 if lib is None else run_verify(args, lib)


if __name__ == "__main__":
    raise SystemExit(main())
