"""Robustness: mangled .eac input yields diagnostics, never an exception, through the whole front
end (parse, resolve, check).

Every test starts from the valid library files in ``grace_dsl/concepts``, damages one of them
(token edits, truncation, random bytes and text, huge numbers, absurd nesting, very long lines),
writes it into a fresh directory next to unmodified copies of the other library files (so ``use``
still resolves, now to the damaged copy), runs resolve + check on that directory and checks that

* no exception escapes;
* every diagnostic has a code from ``CODES``, names a file of the program, and has a line >= 1
  (0 only for whole-file errors such as unreadable bytes, or for an empty file);
* ``render_all`` renders them.

A last property test recombines realistic member declarations into new concepts, to reach the
evaluation at the defaults that random damage rarely gets to.

Hypothesis runs derandomized, so the examples are the same on every run.  Inputs that made the
front end raise are kept at the end: as plain regression tests once fixed, and as
``xfail(strict=True)`` tests whose reason starts with "BUG:" while open (when the compiler is
fixed they start passing, and the marker must be removed).
"""

from __future__ import annotations

import re
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from random import Random

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from grace_dsl.compiler.check import check
from grace_dsl.compiler.resolve import resolve, stdlib_dir
from grace_dsl.lang.codes import CODES
from grace_dsl.lang.diagnostics import Diagnostic, render_all

LIBRARY: dict[str, bytes] = {p.name: p.read_bytes() for p in sorted(stdlib_dir().glob("*.eac"))}
FILES = sorted(LIBRARY)
#: file -> the library files that import it (`use MODULE.{...}`)
USERS: dict[str, tuple[str, ...]] = {
    name: tuple(
        f
        for f in FILES
        if re.search(rb"^use " + re.escape(name[:-4].encode()) + rb"\.", LIBRARY[f], re.M)
    )
    for name in FILES
}

# Crude tokens: comments, strings, numbers with an optional unit, words, two-character operators
# and any other single non-blank character.
TOKEN_RE = re.compile(
    r'//[^\n]*|"(?:[^"\\\n]|\\.)*"|(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?(?:mm|cm|m|deg|rad)?'
    r"|[A-Za-z_]\w*|->|<=|>=|==|!=|\S"
)
NUMBER_RE = re.compile(r"(?<![\w.])(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")

FUZZ = settings(
    derandomize=True,
    max_examples=30,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)


# ---- running the front end ------------------------------------------------------------------


@contextmanager
def _library_with(name: str | None = None, data: bytes = b"") -> Iterator[Path]:
    """A temporary copy of the library in which file ``name`` (if given) holds ``data``."""
    with tempfile.TemporaryDirectory(prefix="eac-fuzz-") as tmp:
        root = Path(tmp)
        for other, original in LIBRARY.items():
            (root / other).write_bytes(data if other == name else original)
        yield root


def _run(target: Path) -> list[Diagnostic]:
    """Resolve + check ``target`` (a file or directory); assert the invariants on the result."""
    return _run_all([target])


def _run_all(targets: list[Path]) -> list[Diagnostic]:
    """Resolve + check ``targets`` as one program; assert the invariants on the result."""
    prog, diags = resolve(targets)
    _, more = check(prog)
    everything = diags + more
    texts = prog.sources()
    for d in everything:
        _assert_located(d, texts)
    assert "Traceback" not in render_all(everything, texts)
    return everything


def front_end(name: str, data: bytes | str) -> list[Diagnostic]:
    """The library with file ``name`` replaced by ``data``, run on that file and the library files
    that ``use`` it (what a damaged module can reach; the rest of the library cannot see it)."""
    raw = data.encode("utf-8") if isinstance(data, str) else data
    with _library_with(name, raw) as root:
        return _run_all([root / f for f in (name, *USERS[name])])


def probe(text: str) -> list[Diagnostic]:
    """A new file ``probe.eac`` placed next to the unmodified library."""
    with _library_with() as root:
        (root / "probe.eac").write_text(text, encoding="utf-8")
        return _run(root / "probe.eac")


def _assert_located(d: Diagnostic, texts: dict[str, str]) -> None:
    s = d.span
    assert d.code in CODES, d
    assert s.file in texts, f"diagnostic names no file of the program: {d}"
    text = texts[s.file]
    if s.line == 0:
        assert d.code == "E006" or not text.strip(), f"diagnostic without a line: {d}"
        return
    assert 1 <= s.line <= text.count("\n") + 1, f"line outside the file: {d}"
    assert s.col >= 1, f"column < 1: {d}"


# ---- token edits ----------------------------------------------------------------------------


def _tokens(text: str) -> list[re.Match[str]]:
    return list(TOKEN_RE.finditer(text))


def _edit(text: str, op: str, i: int, j: int) -> str:
    """Delete, duplicate, swap or replace tokens ``i`` and ``j`` (taken modulo the count)."""
    toks = _tokens(text)
    if not toks:
        return text
    a, b = toks[i % len(toks)], toks[j % len(toks)]
    if op == "delete":
        return text[: a.start()] + text[a.end() :]
    if op == "duplicate":
        return text[: a.end()] + " " + a.group() + text[a.end() :]
    if op == "replace":
        return text[: a.start()] + b.group() + text[a.end() :]
    first, second = sorted((a, b), key=lambda m: m.start())
    if first.start() == second.start():
        return text
    return (
        text[: first.start()]
        + second.group()
        + text[first.end() : second.start()]
        + first.group()
        + text[second.end() :]
    )


EDITS = st.lists(
    st.tuples(
        st.sampled_from(["delete", "duplicate", "swap", "replace"]),
        st.integers(0, 10_000),
        st.integers(0, 10_000),
    ),
    min_size=1,
    max_size=4,
)


@pytest.mark.slow
@settings(FUZZ, max_examples=60)
@given(name=st.sampled_from(FILES), edits=EDITS)
def test_token_edits(name: str, edits: list[tuple[str, int, int]]) -> None:
    text = LIBRARY[name].decode()
    for op, i, j in edits:
        text = _edit(text, op, i, j)
    front_end(name, text)


@pytest.mark.slow
@settings(FUZZ, max_examples=25)
@given(name=st.sampled_from(FILES), where=st.floats(0, 1))
def test_truncation(name: str, where: float) -> None:
    data = LIBRARY[name]
    front_end(name, data[: int(len(data) * where)])


@pytest.mark.slow
@FUZZ
@given(
    name=st.sampled_from(FILES),
    where=st.floats(0, 1),
    junk=st.one_of(
        st.binary(min_size=1, max_size=16),
        st.sampled_from(
            [
                b"\x00",
                b"\x00" * 8,
                b"\xff",
                b"\xc3",
                b"\xed\xa0\x80",
                b"\xef\xbb\xbf",
                b"\r",
                b"\t",
                b"\x0c",
            ]
        ),
    ),
)
def test_random_bytes(name: str, where: float, junk: bytes) -> None:
    data = LIBRARY[name]
    at = int(len(data) * where)
    front_end(name, data[:at] + junk + data[at:])


@pytest.mark.slow
@FUZZ
@given(name=st.sampled_from(FILES), where=st.floats(0, 1), junk=st.text(min_size=1, max_size=12))
def test_random_text(name: str, where: float, junk: str) -> None:
    text = LIBRARY[name].decode()
    at = int(len(text) * where)
    front_end(name, text[:at] + junk + text[at:])


HUGE = [
    "1e400",
    "1e400mm",
    "9" * 400,
    "9" * 400 + "deg",
    "1" + "0" * 308,
    "1e308",
    "1.8e308",
    "0." + "0" * 400 + "1",
    "1e-400mm",
    "4e-324",
    "0",
    "0mm",
    "-0",
    "1e308m",
]


@pytest.mark.slow
@settings(FUZZ, max_examples=20)
@given(name=st.sampled_from(FILES), which=st.integers(0, 10_000), huge=st.sampled_from(HUGE))
def test_huge_numbers(name: str, which: int, huge: str) -> None:
    text = LIBRARY[name].decode()
    numbers = list(NUMBER_RE.finditer(text))
    m = numbers[which % len(numbers)]
    front_end(name, text[: m.start()] + huge + text[m.end() :])


# ---- nesting and long lines -----------------------------------------------------------------

DEPTH = 10_000


def _with_let(expr: str) -> str:
    """handles.eac with one extra ``let`` holding ``expr``."""
    text = LIBRARY["handles.eac"].decode()
    anchor = "    shape bar ="
    return text.replace(anchor, f"    let probe = {expr}\n{anchor}", 1)


NESTED: dict[str, Callable[[], str]] = {
    "parens": lambda: "(" * DEPTH + "r_in" + ")" * DEPTH,
    "negations": lambda: "-(" * DEPTH + "r_in" + ")" * DEPTH,
    "bare_minus": lambda: "-" * DEPTH + "r_in",
    "sin": lambda: "sin(" * DEPTH + "radian" + ")" * DEPTH,
    "not": lambda: "not " * DEPTH + "(r_in > r_out)",
    "if": lambda: "if r_in > r_out then " * DEPTH + "r_in" + " else r_out" * DEPTH,
    "power": lambda: "^".join(["2"] * DEPTH),
    "sum": lambda: " + ".join(["r_in"] * DEPTH),
    "members": lambda: "(r_in, r_out, height)" + ".x" * DEPTH,
    "vector": lambda: "(" * DEPTH + "r_in, r_out" + ")" * DEPTH,
    "long_vector": lambda: "(" + ", ".join(["r_in"] * DEPTH) + ")",
    "long_call": lambda: "min(" + ", ".join(["r_in"] * DEPTH) + ")",
    "unclosed": lambda: "(" * DEPTH + "r_in",
    "unopened": lambda: "r_in" + ")" * DEPTH,
}


@pytest.mark.parametrize("kind", sorted(NESTED))
def test_deep_nesting(kind: str) -> None:
    front_end("handles.eac", _with_let(NESTED[kind]()))


LONG_LINES: dict[str, Callable[[], str]] = {
    "spaces": lambda: "r_in" + " " * 200_000,
    "sum": lambda: " + ".join(["1mm"] * 60) + " " * 100_000,
    "name": lambda: "r" * 200_000,
    "number": lambda: "1" * 200_000 + "mm",
    "string": lambda: '"' + "x" * 200_000 + '"',
    "comment": lambda: "r_in // " + "x" * 200_000,
}


@pytest.mark.parametrize("kind", sorted(LONG_LINES))
def test_long_lines(kind: str) -> None:
    front_end("handles.eac", _with_let(LONG_LINES[kind]()))


@pytest.mark.parametrize(
    "data",
    [
        b"",
        b"\n\n\n",
        b"\x00",
        b"\x00" * 1000,
        b"\xff\xfe\x00c",
        "\ufeff".encode() + LIBRARY["handles.eac"],
        LIBRARY["handles.eac"].replace(b"\n", b"\r\n"),
        LIBRARY["handles.eac"].replace(b"\n", b"\r"),
    ],
    ids=["empty", "newlines", "nul", "nuls", "utf16", "bom", "crlf", "cr"],
)
def test_odd_files(data: bytes) -> None:
    front_end("handles.eac", data)


def test_library_is_clean() -> None:
    """The unmodified library compiles without diagnostics (the baseline of every mutation)."""
    assert front_end("handles.eac", LIBRARY["handles.eac"]) == []


# ---- recombined members -----------------------------------------------------------------------
# Realistic declarations that refer to each other; every example keeps all parameters and the
# part ``h`` and adds a random selection of the rest in random order, so that many examples get
# past type checking into the evaluation at the defaults.  ``slid2`` bounds a free grasp
# parameter by another (it crashed once; now a diagnostic).

BASE = [
    "param w : length in [10mm, 500mm] = 100mm",
    "param d : length in [1mm, 50mm] = 20mm",
    "param a : angle in [0deg, 180deg] = 90deg",
    "param n : int in [1, 5] = 2",
    'param side : choice{"left", "right"} = "left"',
    "param flip : bool = false",
    "param v : vec3 length = (10mm, 20mm, 30mm)",
    "param s : scalar in [-1, 1] = 0",
    "part h = CurveHandle(r_in: d, r_out: d + 8mm) at trans(0, 0, half)",
]
EXTRA = [
    "grasp slid2(t in [0mm, w], u in [t, w]) = trans(t, u, 0)",
    'require w > d "wide enough"',
    'require side == "left" or flip',
    "require v.x < w and n >= 1",
    "require h.r_in < w",
    "let half = w / 2",
    "let r = sqrt(w * d)",
    'let sign = if side == "left" then -1 else 1',
    "let ratio = d / w",
    "let off = trans(half, 0, 0) * rotz(a)",
    "let tip = v + (half, 0mm, 0mm)",
    "let q = h.r_out - h.r_in",
    "let q2 = q * 2",
    "let count = n * 2 + 1",
    "let dir = normalize(cross((1, 0, 0), (0, 1, 0)))",
    "let ang = atan2(d, w) + asin(0.5) + acos(s)",
    "let m = clamp(d, 1mm, w) + min(d, w) - max(d, 0mm)",
    "let rot = axis_angle(dir, a) * inv(rotx(a))",
    "let l = norm(v) + dot(v, v) / w",
    "let arc = h.radian * h.r_in",
    "let e = if flip then (1, 0, 0) else (0, 1, 0)",
    "shape body = Cuboid(size: (w, w, d))",
    "shape rod = Cylinder(radius: d / 2, height: w) at off",
    "shape both = union(body, rod)",
    "shape hole = difference(body, rod)",
    "shape ring = Ring(r_in: d, r_out: d + 5mm, height: 5mm, radian: a)",
    "link leaf { shape panel = Cuboid(size: (w, w, 5mm)) }",
    "link lid {\n part knob = CurveHandle() at trans(0, 0, h.height)\n"
    "    grasp rim = trans(0, half, 0) width d\n}",
    "link drawer {\n part inner = CurveHandle(radian: a) at rot\n let depth = w - d\n}",
    "joint hinge : revolute(base -> leaf) axis (0, sign, 0) at (half, 0, 0) range [0, a] opens +",
    "joint slide : prismatic(base -> lid) axis (0, 0, 1) range [0mm, w]",
    "joint weld : fixed(leaf -> lid)",
    "joint spin : continuous(leaf -> lid) axis (0, 0, 1)",
    "grasp pinch(t in [-half, half] = 0mm) = trans(t, 0, d) * rpy(90deg, 0, 0) width d",
    "grasp turn(th in [0, a]) = rotz(th) * trans(0, -h.r_out, 0) width h.height",
    "grasp slid(t in [0mm, w], u in [0mm, w] = 5mm) = trans(t, u, 0) width h.height",
    "grasp hold = off width 2 * d",
    "action open = pull along hinge using pinch",
    "action push_it = press toward (0, 0, -1) using h.pull",
    "action out = slide along slide closing using knob.pull, rim",
    "action poke = press toward e",
    "action twist = turn along spin using turn",
]
# Members that may appear a second time (E105 and everything after it).
DUPLICABLE = BASE + EXTRA
HEADER = "use primitives.{Cuboid, Cylinder, Ring}\nuse handles.{CurveHandle}\n\nconcept Probe {\n"


def _concept(members: list[str]) -> str:
    return HEADER + "".join(f"    {m}\n" for m in members) + "}\n"


@pytest.mark.slow
@settings(FUZZ, max_examples=40)
@given(
    chosen=st.lists(st.sampled_from(EXTRA), unique=True, max_size=14),
    twice=st.lists(st.sampled_from(DUPLICABLE), max_size=2),
    data=st.randoms(),
)
def test_member_combinations(chosen: list[str], twice: list[str], data: Random) -> None:
    members = BASE + chosen + twice
    data.shuffle(members)
    probe(_concept(members))


# ---- regressions ------------------------------------------------------------------------------


def test_dropped_parameter_used_later() -> None:
    """A parameter lost to a syntax error (here a `;`) and used afterwards (crashed once)."""
    diags = probe(
        "concept A {\n    param h : length = 10mm;\n    let area = h * 2\n"
        "    require area > 1mm\n}\n"
    )
    assert [d.code for d in diags] == ["E001"]


def test_bool_literal_is_located() -> None:
    """Errors involving `true` / `false` used to point at `<builtin>` with no line."""
    diags = probe("concept A {\n    let x = true + 1mm\n}\n")
    assert [(d.code, d.span.line) for d in diags] == [("E202", 2)]


def test_free_parameter_range_uses_earlier_free_parameter() -> None:
    """A free parameter's range may not use another free parameter (crashed once with KeyError)."""
    diags = probe(
        "concept A {\n    param w : length in [1mm, 10mm] = 5mm\n"
        "    grasp g(t in [0mm, w], u in [t, 2 * w]) = trans(t, u, 0)\n}\n"
    )
    assert [(d.code, d.span.line, d.span.col) for d in diags] == [("E106", 3, 34)]


def test_let_using_part_parameter_used_by_another_let() -> None:
    """A let read on demand that uses a part's parameter (crashed once with KeyError 'h')."""
    assert (
        probe(
            "use handles.{CurveHandle}\nconcept A {\n    part h = CurveHandle()\n"
            "    let q = h.r_out\n    let p = q * 2\n}\n"
        )
        == []
    )


def test_duplicate_let_with_computed_value() -> None:
    """A copy-pasted `let` (crashed once in Evaluator.type_of); now only E105."""
    diags = probe(
        "concept A {\n    param w : length = 100mm\n    let half = w / 2\n    let half = w / 2\n}\n"
    )
    assert [d.code for d in diags] == ["E105"]
