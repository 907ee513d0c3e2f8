"""The examples of docs/language.md and docs/examples/ are true.

How docs/language.md marks its code blocks (the HTML comment stands on the line right above the
opening fence; an HTML comment at the top of the page repeats this):

- ```eac blocks carry exactly one marker:
  ``<!-- eac: check [as NAME.eac] -->``       a whole file that compiles without errors;
  ``<!-- eac: error E204 E106 [as NAME] -->`` a whole file whose error codes are exactly these
                                              (a multiset: list a code twice if it occurs twice);
  ``<!-- eac: file docs/examples/X.eac -->``  a verbatim copy of that file (compiled below);
  ``<!-- eac: fragment -->``                  a piece of a concept, not compiled.
  A block is written to a fresh directory as NAME (default ``example.eac``) and checked with
  ``front_end`` (parse, resolve, check: no code generation, so this stays fast), with
  docs/examples/ on the search path so that blocks can ``use bar_handle.{BarHandle}``.
- ```console blocks marked ``<!-- eac: output -->`` start with ``$ eacc check NAME`` and show what
  ``eacc check`` prints for the nearest eac block above (diagnostics with the directory stripped
  from file names, then the error count; or the ``ok:`` line).
- ```console blocks marked ``<!-- eac: explain -->`` show ``eacc explain CONCEPT FILE`` for a file
  of docs/examples/.

The tutorial's Python steps are replayed here through the public API (the markdown is not
executed) and the values the page shows are asserted.
"""

from __future__ import annotations

import re
import shutil
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from grace_dsl.cli.output import count
from grace_dsl.compiler.build import front_end
from grace_dsl.lang.diagnostics import render_all

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "language.md"
EXAMPLES = ROOT / "docs" / "examples"

MARKER = re.compile(r"^<!-- eac: (?P<kind>\w+)(?P<rest>[^>]*?)\s*-->\s*$")
FENCE = re.compile(r"^```(?P<lang>\w*)\s*$")


@dataclass(frozen=True)
class Block:
    lang: str
    kind: str | None  # the marker's kind, None when unmarked
    args: tuple[str, ...]
    text: str
    line: int  # line of the opening fence, 1-based

    @property
    def name(self) -> str:
        """The file name the block is compiled as (``as NAME`` in its marker)."""
        if "as" in self.args:
            return self.args[self.args.index("as") + 1]
        return "example.eac"

    @property
    def codes(self) -> list[str]:
        """The error codes an ``error`` block documents."""
        return sorted(a for a in self.args if re.fullmatch(r"E\d{3}", a))

    def __str__(self) -> str:
        return f"language.md:{self.line}"


def read_blocks(path: Path = DOC) -> list[Block]:
    """Every fenced block of a markdown file with the marker right above its fence."""
    lines = path.read_text(encoding="utf-8").splitlines()
    blocks: list[Block] = []
    i = 0
    while i < len(lines):
        fence = FENCE.match(lines[i])
        if fence is None:
            i += 1
            continue
        start = i
        i += 1
        body: list[str] = []
        while i < len(lines) and not lines[i].startswith("```"):
            body.append(lines[i])
            i += 1
        marker = MARKER.match(lines[start - 1]) if start > 0 else None
        kind = marker["kind"] if marker else None
        args = tuple(marker["rest"].split()) if marker else ()
        blocks.append(Block(fence["lang"], kind, args, "\n".join(body) + "\n", start + 1))
        i += 1
    return blocks


BLOCKS = read_blocks()
EAC = [b for b in BLOCKS if b.lang == "eac"]


def compile_block(block: Block, tmp: Path) -> tuple[list, str]:
    """Diagnostics of a block compiled as its own file, and their rendering as eacc prints it."""
    path = tmp / block.name
    path.write_text(block.text, encoding="utf-8")
    prog, _, diags = front_end([path], search_path=[EXAMPLES])
    text = render_all(diags, prog.sources()).replace(str(tmp.resolve()) + "/", "")
    errors = [d for d in diags if d.severity == "error"]
    if errors:
        n = len(errors)
        text += f"\n{n} error{'s' if n != 1 else ''}"
    else:
        concepts = count(len(prog.concepts), "concept")
        text = f"ok: {concepts} in {count(len(prog.files), 'file')}"
    return errors, text


def _ids(blocks: list[Block]) -> list[str]:
    return [str(b) for b in blocks]


# ---- the markdown ---------------------------------------------------------------------------


def test_the_page_has_examples() -> None:
    kinds = Counter(b.kind for b in EAC)
    assert kinds["check"] >= 5 and kinds["error"] >= 4 and kinds["file"] == 3


@pytest.mark.parametrize("block", EAC, ids=_ids(EAC))
def test_every_eac_block_is_marked(block: Block) -> None:
    assert block.kind in ("check", "error", "file", "fragment"), (
        f"{block}: put <!-- eac: check|error CODES|file PATH|fragment --> right above the fence"
    )


CHECK = [b for b in EAC if b.kind == "check"]


@pytest.mark.parametrize("block", CHECK, ids=_ids(CHECK))
def test_complete_blocks_compile(block: Block, tmp_path: Path) -> None:
    errors, text = compile_block(block, tmp_path)
    assert not errors, f"{block} does not compile:\n{text}"


ERROR = [b for b in EAC if b.kind == "error"]


@pytest.mark.parametrize("block", ERROR, ids=_ids(ERROR))
def test_error_blocks_report_their_codes(block: Block, tmp_path: Path) -> None:
    assert block.codes, f"{block}: an error block lists the codes it shows"
    errors, text = compile_block(block, tmp_path)
    assert sorted(d.code for d in errors) == block.codes, f"{block}:\n{text}"


FILES = [b for b in EAC if b.kind == "file"]


@pytest.mark.parametrize("block", FILES, ids=_ids(FILES))
def test_file_blocks_are_the_example_files(block: Block) -> None:
    (path,) = block.args
    assert block.text == (ROOT / path).read_text(encoding="utf-8"), f"{block} differs from {path}"


def _outputs() -> list[tuple[Block, Block]]:
    pairs = []
    for i, b in enumerate(BLOCKS):
        if b.lang == "console" and b.kind == "output":
            source = next(s for s in reversed(BLOCKS[:i]) if s.kind in ("check", "error"))
            pairs.append((b, source))
    return pairs


OUTPUTS = _outputs()


@pytest.mark.parametrize("output,source", OUTPUTS, ids=[str(o) for o, _ in OUTPUTS])
def test_shown_diagnostics_are_what_eacc_prints(
    output: Block, source: Block, tmp_path: Path
) -> None:
    command, _, shown = output.text.partition("\n")
    assert command == f"$ eacc check {source.name}", f"{output}: the command names {source.name}"
    _, text = compile_block(source, tmp_path)
    assert shown.rstrip("\n") == text, f"{output}: eacc check prints\n{text}"


# ---- docs/examples and the tutorial ---------------------------------------------------------


def test_example_files_compile() -> None:
    files = sorted(EXAMPLES.glob("*.eac"))
    assert {f.name for f in files} >= {"bar_handle.eac", "drawer.eac"}
    prog, _, diags = front_end(files)
    assert not diags, render_all(diags, prog.sources())
    assert {"BarHandle", "Drawer"} <= set(prog.concepts)


@pytest.fixture(scope="module")
def library(tmp_path_factory: pytest.TempPathFactory):  # type: ignore[no-untyped-def]
    import grace_dsl as eac

    cache = tmp_path_factory.mktemp("cache")
    return eac.compile_paths([EXAMPLES / "drawer.eac"], cache_dir=cache), cache


def test_tutorial_python_steps(library) -> None:  # type: ignore[no-untyped-def]
    import grace_dsl as eac

    lib, _ = library
    drawer = lib["Drawer"]
    assert [p.name for p in drawer.params] == [
        "front",
        "depth",
        "travel",
        "handle.length",
        "handle.radius",
        "handle.standoff",
    ]

    R = np.array([[0, 0, -1], [-1, 0, 0], [0, 1, 0]], dtype=float)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, (0.8, 0.0, 0.45)
    inst = drawer.instantiate(pose=T, front=(0.5, 0.2, 0.02), **{"handle.length": 0.3})

    ((lo, hi),) = inst.grasp_range("handle.hold").values()
    assert (lo, hi) == pytest.approx((-0.132, 0.132))
    G = inst.grasp("handle.hold", s=0.05)
    assert G[:3, 3] == pytest.approx([0.76, -0.05, 0.45])
    assert G[:3, 2] == pytest.approx([1, 0, 0])
    assert G[:3, 1] == pytest.approx([0, 0, 1])
    assert inst.grasp_width("handle.hold") == pytest.approx(0.012)

    assert inst.force("open", grasp=G) == pytest.approx([-1, 0, 0])
    assert inst.force("close", grasp=G) == pytest.approx([1, 0, 0])
    path = inst.follow("open", grasp=G, to=0.25, steps=6)
    assert path.shape == (6, 4, 4)
    assert path[-1][:3, 3] == pytest.approx([0.51, -0.05, 0.45])
    assert path[-1][:3, :3] == pytest.approx(G[:3, :3])

    half = drawer.instantiate(pose=T, joints={"slide": 0.1})
    assert half.link_pose("drawer")[:3, 3] == pytest.approx([0.7, 0, 0.45])
    assert inst.grasps("handle.hold", n=3)[:, 1, 3] == pytest.approx([0.132, 0, -0.132])

    with pytest.raises(eac.RequirementError, match="the drawer stays on its runners"):
        drawer.instantiate(travel=0.5)
    with pytest.raises(
        eac.ParameterError, match=re.escape("joint slide = 0.5 is outside its range [0, 0.35]")
    ):
        drawer.instantiate(joints={"slide": 0.5})


def test_explain_output_is_what_eacc_prints(library, monkeypatch, capsys) -> None:  # type: ignore[no-untyped-def]
    from grace_dsl.cli import eacc

    _, cache = library
    monkeypatch.setenv("GRACE_CACHE_DIR", str(cache))  # reuse the module's build
    shown = [b for b in BLOCKS if b.lang == "console" and b.kind == "explain"]
    assert shown
    for block in shown:
        command, _, text = block.text.partition("\n")
        words = command.split()
        assert words[:3] == ["$", "eacc", "explain"], f"{block}"
        concept, file = words[3], words[4]
        capsys.readouterr()
        monkeypatch.chdir(EXAMPLES)
        assert eacc.main(["explain", concept, file]) == 0
        assert capsys.readouterr().out == text, f"{block}"


def test_examples_work_from_a_copy(tmp_path: Path) -> None:
    """The tutorial's files depend on nothing but each other and the standard library."""
    for f in EXAMPLES.glob("*.eac"):
        shutil.copy(f, tmp_path / f.name)
    prog, _, diags = front_end([tmp_path / "drawer.eac"])
    assert not diags, render_all(diags, prog.sources())
