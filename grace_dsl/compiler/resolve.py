"""Resolve pass: files and imports -> a ``Program`` of visible, uniquely named concepts.

Loads every file reachable through ``use`` from the library search path, reports missing modules,
import cycles, duplicate concepts and members, unknown parts, links, joints and grasps, and
concepts that contain themselves.  Names inside expressions are checked by the ``check`` pass,
which knows their types.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from grace_dsl.compiler import variants
from grace_dsl.compiler.expand import VARIANT_SEP, expand, split_indexed
from grace_dsl.lang import ast
from grace_dsl.lang.diagnostics import Diagnostic, did_you_mean, error
from grace_dsl.lang.parser import KEYWORDS, parse

BASE_LINK = "base"
BUILTIN_NAMES = frozenset(
    [
        "sin",
        "cos",
        "tan",
        "asin",
        "acos",
        "atan2",
        "sqrt",
        "abs",
        "min",
        "max",
        "clamp",
        "dot",
        "cross",
        "norm",
        "normalize",
        "rotx",
        "roty",
        "rotz",
        "rpy",
        "axis_angle",
        "trans",
        "inv",
        "union",
        "difference",
        "pi",
        "base",
    ]
)


@dataclass(frozen=True)
class SourceFile:
    path: str
    text: str
    module: ast.Module | None
    dropped: frozenset[str] = frozenset()


@dataclass(frozen=True)
class ConceptEntry:
    decl: ast.Concept
    file: str


@dataclass
class Program:
    files: dict[str, SourceFile] = field(default_factory=dict)
    concepts: dict[str, ConceptEntry] = field(default_factory=dict)
    visible: dict[str, dict[str, str]] = field(default_factory=dict)  # file -> name -> file
    imports: dict[str, list[str]] = field(default_factory=dict)
    use_targets: dict[str, list[str | None]] = field(default_factory=dict)  # per `use`, in order
    roots: list[str] = field(default_factory=list)
    # Names a failed `use` should have brought in ("*" for a whole module): no follow-on errors.
    unresolved: dict[str, set[str]] = field(default_factory=dict)

    def concept(self, name: str) -> ast.Concept:
        return self.concepts[name].decl

    def sources(self) -> dict[str, str]:
        return {p: f.text for p, f in self.files.items()}

    def dropped(self, file: str) -> frozenset[str]:
        """Names later passes should not complain about: lost to syntax or import errors."""
        return self.files[file].dropped | self.unresolved.get(file, set())


def stdlib_dir() -> Path:
    """The standard concept library shipped with the package."""
    return Path(__file__).resolve().parent.parent / "concepts"


def env_search_path() -> list[Path]:
    """Directories from ``GRACE_EAC_PATH`` (separated like PATH), searched before the stdlib."""
    value = os.environ.get("GRACE_EAC_PATH", "")
    return [Path(p) for p in value.split(os.pathsep) if p]


def search_dirs(search_path: Sequence[str | Path] = ()) -> list[Path]:
    """Where ``use`` looks after the using file's own directory, in order."""
    return [Path(p) for p in search_path] + env_search_path() + [stdlib_dir()]


def resolve(
    paths: Sequence[str | Path], search_path: Sequence[str | Path] = ()
) -> tuple[Program, list[Diagnostic]]:
    """Load ``paths`` (files or directories of .eac files) and everything they import."""
    diags: list[Diagnostic] = []
    prog = Program()
    search = search_dirs(search_path)
    roots = root_files(paths, diags)
    prog.roots = [str(p) for p in roots]
    queue = list(roots)
    while queue:
        path = queue.pop(0)
        key = str(path)
        if key in prog.files:
            continue
        src = _load(path, diags)
        prog.files[key] = src
        prog.imports[key], prog.use_targets[key] = [], []
        if src.module is None:
            continue
        for use in src.module.uses:
            target = find_module(use.module, path.parent, search)
            if target is not None and target.suffix != ".eac":  # a symlink to another file
                diags.append(_not_source(use, target))  # never read: no excerpt of it leaks
                prog.use_targets[key].append(None)
                prog.unresolved.setdefault(key, set()).update(use.names or ("*",))
                continue
            prog.use_targets[key].append(str(target) if target is not None else None)
            if target is None:
                diags.append(_missing_module(use, path.parent, search))
                prog.unresolved.setdefault(key, set()).update(use.names or ("*",))
                continue
            prog.imports[key].append(str(target))
            queue.append(target)
    diags += _import_cycles(prog)
    diags += _collect_concepts(prog)
    diags += _visibility(prog)
    diags += _variant_pass(prog)
    for entry in prog.concepts.values():
        diags += _check_members(entry, prog)
    diags += _part_cycles(prog)
    return prog, diags


# ---- files and modules --------------------------------------------------------------------------


def root_files(paths: Sequence[str | Path], diags: list[Diagnostic]) -> list[Path]:
    files: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            # regular .eac files only: a FIFO would block, a loop raise, a symlink to
            # /etc/passwd be quoted in diagnostics (the command line warns about each)
            files += sorted(q.resolve() for q in p.rglob("*.eac") if _plain_source(q))
        elif p.is_file():
            files.append(p.resolve())
        else:
            diags.append(
                error("E006", f"no such file or directory: {p}", ast.Span(str(p), 0, 0, 0, 0))
            )
    return files


def _plain_source(path: Path) -> bool:
    return path.is_file() and Path(os.path.realpath(path)).suffix == ".eac"


def _load(path: Path, diags: list[Diagnostic]) -> SourceFile:
    try:
        data = path.read_bytes()
        text = data.decode("utf-8").removeprefix("\ufeff")  # a byte-order mark is not code
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        col = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
        diags.append(
            error(
                "E006",
                f"not UTF-8 text: byte 0x{data[exc.start]:02x} at line {line}, column {col}",
                ast.Span(str(path), 0, 0, 0, 0),
                "save the file as UTF-8",
            )
        )
        return SourceFile(str(path), "", None)
    except OSError as exc:
        reason = exc.strerror
        diags.append(
            error("E006", f"cannot read {path}: {reason}", ast.Span(str(path), 0, 0, 0, 0))
        )
        return SourceFile(str(path), "", None)
    result = parse(text, str(path))
    diags += result.diagnostics
    if result.module is None:
        return SourceFile(str(path), text, None, result.dropped)
    module, more, quiet = expand(result.module)
    diags += more
    return SourceFile(str(path), text, module, result.dropped | quiet)


def find_module(module: tuple[str, ...], here: Path, search: list[Path]) -> Path | None:
    rel = Path(*module).with_suffix(".eac")
    for base in [here, *search]:
        candidate = base / rel
        if candidate.is_file():
            return candidate.resolve()
    return None


def _not_source(use: ast.Use, target: Path) -> Diagnostic:
    name = ".".join(use.module)
    return error(
        "E006",
        f"module `{name}` is a symlink to {target}, which is not a .eac file; it is not read",
        use.module_span,
        "point the symlink at a .eac file",
    )


def _missing_module(use: ast.Use, here: Path, search: list[Path]) -> Diagnostic:
    name = ".".join(use.module)
    known = {p.stem for base in [here, *search] if base.is_dir() for p in base.glob("*.eac")}
    hint = did_you_mean(name, known) or "looked in " + ", ".join(str(s) for s in [here, *search])
    return error("E101", f"module `{name}` not found", use.module_span, hint)


def _import_cycles(prog: Program) -> list[Diagnostic]:
    diags: list[Diagnostic] = []
    state: dict[str, int] = {}  # 1 visiting, 2 done

    def visit(f: str, stack: list[str]) -> None:
        state[f] = 1
        for g in prog.imports.get(f, []):
            if state.get(g) == 1:
                path = [*stack, f]
                cycle = " -> ".join(Path(x).stem for x in [*path[path.index(g) :], g])
                hint = (
                    "a file sees its own concepts without `use`; remove this line"
                    if g == f
                    else "move the shared concepts into a module both can import"
                )
                diags.append(error("E102", f"import cycle: {cycle}", _use_span(prog, f, g), hint))
            elif g not in state:
                visit(g, [*stack, f])
        state[f] = 2

    for f in prog.files:
        if f not in state:
            visit(f, [])
    return diags


def _use_span(prog: Program, f: str, target: str) -> ast.Span:
    mod = prog.files[f].module
    stem = Path(target).stem
    if mod is not None:
        for use in mod.uses:
            if use.module[-1] == stem:
                return use.module_span
    return ast.Span(f, 0, 0, 0, 0)


# ---- concepts -----------------------------------------------------------------------------------


def _collect_concepts(prog: Program) -> list[Diagnostic]:
    diags = []
    for path, src in prog.files.items():
        if src.module is None:
            continue
        for c in src.module.concepts:
            first = prog.concepts.get(c.name)
            if first is not None:
                s = first.decl.name_span
                diags.append(
                    error(
                        "E104",
                        f"concept `{c.name}` is defined twice",
                        c.name_span,
                        f"first defined at {s.file}:{s.line}:{s.col}",
                    )
                )
                continue
            prog.concepts[c.name] = ConceptEntry(c, path)
    return diags


def _visibility(prog: Program) -> list[Diagnostic]:
    diags = []
    by_file: dict[str, list[str]] = {}
    for name, entry in prog.concepts.items():
        by_file.setdefault(entry.file, []).append(name)
    for path, src in prog.files.items():
        seen = {n: path for n in by_file.get(path, [])}
        if src.module is not None:
            for use, target in zip(src.module.uses, prog.use_targets[path]):
                if target is None:
                    continue
                exported = by_file.get(target, [])
                wanted = use.names if use.names is not None else tuple(exported)
                for i, name in enumerate(wanted):
                    if name in exported:
                        seen[name] = target
                    elif use.names is not None:
                        prog.unresolved.setdefault(path, set()).add(name)
                        span = use.name_spans[i] if i < len(use.name_spans) else use.span
                        diags.append(
                            error(
                                "E103",
                                f"`{name}` is not defined in module `{'.'.join(use.module)}`",
                                span,
                                did_you_mean(name, exported),
                            )
                        )
        prog.visible[path] = seen
    return diags


def flat_members(c: ast.Concept) -> Iterable[ast.Member_]:
    """Every member of a concept, with the members of its links spliced in."""
    for m in c.members:
        yield m
        if isinstance(m, ast.Link):
            yield from m.members


def _check_members(entry: ast.Concept | ConceptEntry, prog: Program) -> list[Diagnostic]:
    assert isinstance(entry, ConceptEntry)
    c, file = entry.decl, entry.file
    diags: list[Diagnostic] = []
    seen: dict[str, ast.Span] = {}
    seen_base: set[tuple[str, ast.Span]] = set()
    dropped = prog.dropped(file)
    for m in flat_members(c):
        if c.kind == "primitive" and not isinstance(m, (ast.Param, ast.Require)):
            diags.append(
                error(
                    "E114",
                    f"a primitive declares only `param` and `require`, not "
                    f"`{type(m).__name__.lower()}`",
                    m.span,
                    "its geometry comes from grace_dsl.geometry",
                )
            )
        if isinstance(m, (ast.Require, ast.For)):  # no `for` is left after unrolling
            continue
        name = m.name
        span = getattr(m, "name_span", m.span)
        source = _source_name(m)
        if source == BASE_LINK and isinstance(m, (ast.Part, ast.Link)):
            if (source, span) not in seen_base:  # the copies and options share one source
                seen_base.add((source, span))
                diags.append(_base_clash(m, span))
            continue
        if name in KEYWORDS:  # only reachable for names the parser let through
            diags.append(
                error(
                    "E113",
                    f"`{name}` is a keyword and cannot name a declaration",
                    span,
                    f"rename it, e.g. `{name}_`",
                )
            )
        elif name in BUILTIN_NAMES:
            diags.append(
                error(
                    "E113",
                    f"`{name}` is a built-in name and cannot be redefined",
                    span,
                    f"rename it, e.g. `{name}_`",
                )
            )
        elif name in seen:
            first = seen[name]
            diags.append(
                error(
                    "E105",
                    f"`{name}` is already defined in `{c.name}`",
                    span,
                    f"first defined at line {first.line}",
                )
            )
        else:
            seen[name] = span
    visible = prog.visible.get(file, {})
    links = {m.name for m in c.members if isinstance(m, ast.Link)}
    joints = {m.name for m in c.members if isinstance(m, ast.Joint)}
    for m in flat_members(c):
        quiet = m.concept in dropped or "*" in dropped if isinstance(m, ast.Part) else True
        if isinstance(m, ast.Part) and m.concept not in visible and not quiet:
            hint = did_you_mean(m.concept, visible) or (
                f"import it with `use ...{{{m.concept}}}`" if m.concept in prog.concepts else None
            )
            diags.append(error("E107", f"unknown concept `{m.concept}`", m.concept_span, hint))
        if isinstance(m, ast.Action):
            known_joint = (
                m.joint is None
                or m.joint in joints
                or ("." in m.joint and m.joint in all_joints(prog, c))
            )
            if not known_joint and m.joint is not None and m.joint.split(".")[0] not in dropped:
                diags.append(
                    error(
                        "E109",
                        f"`{m.joint}` is not a joint of `{c.name}`",
                        m.joint_span,
                        did_you_mean(m.joint, all_joints(prog, c)),
                    )
                )
            for g in m.using:
                if not grasp_exists(prog, c, g) and VARIANT_SEP in g.split(".")[0]:
                    diags += _variant_lacks(prog, c, m, g)
                elif not grasp_exists(prog, c, g) and g.split(".")[0] not in dropped:
                    diags.append(
                        error(
                            "E110",
                            f"`{g}` is not a grasp of `{c.name}`",
                            m.span,
                            did_you_mean(g, all_grasps(prog, c)),
                        )
                    )
    diags += _check_link_tree(c, links, dropped)
    return _once_per_span(diags)


def _variant_pass(prog: Program) -> list[Diagnostic]:
    """Reads, pass-through arguments and grasps of variant parts, made concrete (variants.py)."""

    def concept(name: str) -> ast.Concept | None:
        entry = prog.concepts.get(name)
        return entry.decl if entry is not None else None

    scope = variants.Scope(concept)
    diags: list[Diagnostic] = []
    for name, entry in list(prog.concepts.items()):
        if variants.uses_variants(entry.decl, scope):
            decl, more = variants.rewrite_concept(entry.decl, scope)
            prog.concepts[name] = ConceptEntry(decl, entry.file)
            diags += more
    return diags


def _source_name(m: Any) -> str:
    """The name as written: ``base`` for ``base[2]`` (a loop's copy) or ``base@legs`` (an
    option of a variant part), whose unrolled names escape the checks on plain names."""
    name = m.variant[0] if isinstance(m, ast.Part) and m.variant is not None else m.name
    split = split_indexed(name)
    return split[0] if split is not None else name


def _base_clash(m: ast.Part | ast.Link, span: ast.Span) -> Diagnostic:
    """A part or link named ``base``: the root link of every concept has that name, so joints
    (``revolute(base -> door)``) and the part's own links (``base.frame``) would be ambiguous."""
    kind = "part" if isinstance(m, ast.Part) else "link"
    return error(
        "E130",
        f"a {kind} cannot be named `base`: `base` is the root link of every concept",
        span,
        "rename it for what it is, e.g. `plinth`, `stand` or `carcass`",
    )


def _once_per_span(diags: list[Diagnostic]) -> list[Diagnostic]:
    """The copies a ``for`` loop made share their source: report each problem there once."""
    seen: set[tuple[str, ast.Span, str]] = set()
    out = []
    for d in diags:
        key = (d.code, d.span, d.message if d.code != "E127" else "")
        if key not in seen:
            seen.add(key)
            out.append(d)
    return out


def _variant_lacks(prog: Program, c: ast.Concept, a: ast.Action, g: str) -> list[Diagnostic]:
    """An option of a variant part without a grasp the host's action uses (E127)."""
    head, _, rest = g.partition(".")
    part = next((m for m in flat_members(c) if isinstance(m, ast.Part) and m.name == head), None)
    if part is None or part.variant is None or part.concept not in prog.concepts:
        return []
    name, option = part.variant
    has = sorted(set(all_grasps(prog, prog.concept(part.concept))))
    return [
        error(
            "E127",
            f'option "{option}" of part `{name}` ({part.concept}) has no grasp `{rest}`, which '
            f"action `{a.name}` uses",
            part.concept_span,
            f"{part.concept} has "
            + (", ".join(f"`{x}`" for x in has) or "no grasps")
            + f"; every option must provide `{rest}`",
        )
    ]


def all_grasps(prog: Program, c: ast.Concept) -> list[str]:
    """Every grasp reachable in a concept's part tree, by qualified name."""
    return _reachable(prog, c, ast.Grasp)


def all_joints(prog: Program, c: ast.Concept) -> list[str]:
    """Every joint reachable in a concept's part tree, by qualified name (``knob.spin``)."""
    return _reachable(prog, c, ast.Joint)


def _reachable(
    prog: Program, c: ast.Concept, kind: type, prefix: str = "", depth: int = 0
) -> list[str]:
    found: list[str] = []
    for m in flat_members(c):
        if isinstance(m, kind):
            found.append(prefix + m.name)  # type: ignore[union-attr]
        elif isinstance(m, ast.Part) and m.concept in prog.concepts and depth < 16:
            sub = prog.concept(m.concept)
            found += _reachable(prog, sub, kind, f"{prefix}{m.name}.", depth + 1)
    return found


def grasp_exists(prog: Program, c: ast.Concept, dotted: str) -> bool:
    """Whether ``a.b.g`` names a grasp of part ``a``'s part ``b`` (or ``g`` one of ``c``)."""
    head, _, rest = dotted.partition(".")
    for m in flat_members(c):
        if not rest and isinstance(m, ast.Grasp) and m.name == head:
            return True
        if rest and isinstance(m, ast.Part) and m.name == head and m.concept in prog.concepts:
            return grasp_exists(prog, prog.concept(m.concept), rest)
    return False


def _check_link_tree(c: ast.Concept, links: set[str], dropped: frozenset[str]) -> list[Diagnostic]:
    diags: list[Diagnostic] = []
    parent_of: dict[str, str] = {}
    known = links | {BASE_LINK}
    unknown_ends = False  # after an unknown link name, "not attached" would only repeat it
    for j in (m for m in c.members if isinstance(m, ast.Joint)):
        for end, span in ((j.parent, j.parent_span), (j.child, j.child_span)):
            if end not in known:
                unknown_ends = True
            if end not in known and end not in dropped:
                diags.append(
                    error(
                        "E108",
                        f"unknown link `{end}`",
                        span,
                        did_you_mean(end, known) or "declare it with `link name { ... }`",
                    )
                )
        if j.child == BASE_LINK:
            diags.append(
                error("E112", "`base` is the root link and cannot be a joint's child", j.child_span)
            )
        elif j.child in parent_of:
            diags.append(
                error(
                    "E112",
                    f"link `{j.child}` already has a parent joint",
                    j.child_span,
                    "a link hangs from exactly one joint",
                )
            )
        else:
            parent_of[j.child] = j.parent
    reported: set[str] = set()
    for link in sorted(links):
        seen, node = [link], link
        while node in parent_of:
            node = parent_of[node]
            if node in seen:
                cycle = seen[seen.index(node) :]
                if not reported & set(cycle):
                    reported.update(cycle)
                    chain = " -> ".join([*cycle, node])
                    diags.append(
                        error(
                            "E112",
                            f"the joints form a cycle: {chain}",
                            _link_span(c, node),
                            "every link hangs from `base` through a chain of joints",
                        )
                    )
                break
            seen.append(node)
        else:
            if node != BASE_LINK and node not in dropped and not unknown_ends:
                diags.append(
                    error(
                        "E112",
                        f"link `{node}` is not attached to `base`",
                        _link_span(c, node),
                        f"add `joint j : fixed(base -> {node})`",
                    )
                )
    return diags


def _link_span(c: ast.Concept, name: str) -> ast.Span:
    return next(
        (m.name_span for m in c.members if isinstance(m, ast.Link) and m.name == name), c.name_span
    )


def _part_cycles(prog: Program) -> list[Diagnostic]:
    """A concept whose part tree reaches itself again would instantiate forever."""
    diags = []
    for name, entry in prog.concepts.items():
        for first in (m for m in flat_members(entry.decl) if isinstance(m, ast.Part)):
            chain = _path_back(prog, first.concept, name, (name, first.concept))
            if chain is not None:
                diags.append(
                    error(
                        "E111",
                        f"`{name}` contains itself: {' -> '.join(chain)}",
                        first.concept_span,
                    )
                )
                break
    return diags


def _path_back(prog: Program, cur: str, goal: str, path: tuple[str, ...]) -> tuple[str, ...] | None:
    if cur == goal:
        return path
    entry = prog.concepts.get(cur)
    if entry is None or len(path) > len(prog.concepts) + 1:
        return None
    for m in flat_members(entry.decl):
        if isinstance(m, ast.Part) and (m.concept == goal or m.concept not in path):
            found = _path_back(prog, m.concept, goal, (*path, m.concept))
            if found is not None:
                return found
    return None
