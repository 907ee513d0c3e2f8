"""The expand pass: ``for`` loops and variant parts unrolled into plain declarations.

The strongest check is numerical: a chest whose drawers come from a loop must have exactly the
link poses and grasp poses of the same chest written out drawer by drawer, and so must the
masked form (a loop bounded by an ``int`` parameter, unrolled to its largest value) and the
variant form (the handle chosen by a ``match``) at the same values.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np
import pytest

from grace_dsl.compiler.build import front_end
from grace_dsl.compiler.expand import const_int, expand, split_indexed
from grace_dsl.compiler.functions import casadi_functions
from grace_dsl.lang import ast
from grace_dsl.lang.diagnostics import has_errors
from grace_dsl.lang.parser import parse

HEAD = """use primitives.{Cuboid}
use handles.{StraightHandle, RingPull}
"""

PARAMS = """
    param size : vec3 length in [(400mm, 500mm, 350mm), (1200mm, 1300mm, 600mm)]
        = (800mm, 780mm, 480mm)
    param travel : length in [200mm, 550mm] = 350mm
    param hl : length in [60mm, 300mm] = 160mm
    param hr : length in [4mm, 8mm] = 6mm
    let gap = 20mm
    let w = size.x - 2 * gap
    let t = 18mm
"""

LOOP_BODY = """
        let y[i] = size.y / 2 - gap - h / 2 - i * (h + gap)
        link drawer[i] {
            shape front[i] = Cuboid(size: (w, h, t)) at trans(0, y[i], size.z / 2 + t / 2)
            part handle[i] = HANDLE at trans(0, y[i], size.z / 2 + t + 32mm)
            grasp push[i](s in [-w / 2 + 30mm, w / 2 - 30mm] = 0) =
                trans(s, y[i] - h / 2 + 15mm, size.z / 2 + t) * roty(180deg) * rotz(90deg)
                by push
        }
        joint slide[i] : prismatic(base -> drawer[i]) axis (0, 0, 1) range [0, travel]
        action open[i] = pull along slide[i] using handle[i].pull
"""
BAR = "StraightHandle(length: hl, radius: hr, standoff: 32mm)"

LOOP = (
    "concept ChestLoop {" + PARAMS + "    let h = (size.y - 4 * gap) / 3\n"
    "    for i in 0..3 {" + LOOP_BODY.replace("HANDLE", BAR) + "    }\n}\n"
)
MASKED = (
    "concept ChestMasked {" + PARAMS + "    param n : int in [1, 5] = 3\n"
    "    let h = (size.y - (n + 1) * gap) / n\n"
    "    for i in 0..n {" + LOOP_BODY.replace("HANDLE", BAR) + "    }\n}\n"
)
VARIANT = (
    "concept ChestVariant {" + PARAMS + "    param n : int in [1, 5] = 3\n"
    '    param kind : choice{"bar", "ring"} = "bar"\n'
    "    let h = (size.y - (n + 1) * gap) / n\n"
    "    for i in 0..n {"
    + LOOP_BODY.replace("HANDLE", f'match kind {{ "bar" => {BAR}, "ring" => RingPull() }}')
    + "    }\n}\n"
)
# The same chest written out by hand, drawer by drawer.
HAND = (
    "concept ChestHand {"
    + PARAMS
    + """    let h = (size.y - 4 * gap) / 3
    link drawer1 {
        shape front1 = Cuboid(size: (w, h, t)) at trans(0, gap + h, size.z / 2 + t / 2)
        part handle1 = StraightHandle(length: hl, radius: hr, standoff: 32mm)
            at trans(0, gap + h, size.z / 2 + t + 32mm)
        grasp push1(s in [-w / 2 + 30mm, w / 2 - 30mm] = 0) =
            trans(s, gap + h / 2 + 15mm, size.z / 2 + t) * roty(180deg) * rotz(90deg) by push
    }
    link drawer2 {
        shape front2 = Cuboid(size: (w, h, t)) at trans(0, 0, size.z / 2 + t / 2)
        part handle2 = StraightHandle(length: hl, radius: hr, standoff: 32mm)
            at trans(0, 0, size.z / 2 + t + 32mm)
        grasp push2(s in [-w / 2 + 30mm, w / 2 - 30mm] = 0) =
            trans(s, -h / 2 + 15mm, size.z / 2 + t) * roty(180deg) * rotz(90deg) by push
    }
    link drawer3 {
        shape front3 = Cuboid(size: (w, h, t)) at trans(0, -gap - h, size.z / 2 + t / 2)
        part handle3 = StraightHandle(length: hl, radius: hr, standoff: 32mm)
            at trans(0, -gap - h, size.z / 2 + t + 32mm)
        grasp push3(s in [-w / 2 + 30mm, w / 2 - 30mm] = 0) =
            trans(s, -gap - 3 * h / 2 + 15mm, size.z / 2 + t) * roty(180deg) * rotz(90deg)
            by push
    }
    joint slide1 : prismatic(base -> drawer1) axis (0, 0, 1) range [0, travel]
    joint slide2 : prismatic(base -> drawer2) axis (0, 0, 1) range [0, travel]
    joint slide3 : prismatic(base -> drawer3) axis (0, 0, 1) range [0, travel]
    action open1 = pull along slide1 using handle1.pull
    action open2 = pull along slide2 using handle2.pull
    action open3 = pull along slide3 using handle3.pull
}
"""
)


@pytest.fixture(scope="module")
def chests(tmp_path_factory: pytest.TempPathFactory) -> Any:
    path = tmp_path_factory.mktemp("chests") / "chests.eac"
    path.write_text(HEAD + LOOP + MASKED + VARIANT + HAND, encoding="utf-8")
    _, checked, diags = front_end([path])
    assert not has_errors(diags), diags
    return checked


def _evaluate(checked: Any, concept: str, values: dict[str, Any]) -> Any:
    """The concept's CasADi functions and a call ``f(kind, member, q by joint, s)``."""
    compiled = casadi_functions(checked, concept)
    low = compiled.lowered
    p = []
    for info in low.params:
        v = values.get(info.name, info.default)
        p += list(v) if isinstance(v, tuple) else [v]
    joints = [j.name for j in low.joints if j.kind != "fixed"]

    def call(kind: str, member: str, q: dict[str, float], s: float = 0.0) -> np.ndarray:
        qv = [q.get(j, 0.0) for j in joints]
        fn = compiled.functions[f"{kind}:{member}"]
        args = [p, qv] + ([[s]] if kind == "grasp" else [])
        return np.array(ca.DM(fn(*args)), dtype=float)

    return call, low


def test_unrolled_chest_equals_the_hand_written_one(chests: Any) -> None:
    rng = np.random.default_rng(7)
    for _ in range(5):
        values = {
            "size": (rng.uniform(0.4, 1.2), rng.uniform(0.5, 1.3), rng.uniform(0.35, 0.6)),
            "travel": rng.uniform(0.2, 0.55),
            "hl": rng.uniform(0.06, 0.3),
            "hr": rng.uniform(0.004, 0.008),
            "n": 3.0,
        }
        hand, _ = _evaluate(chests, "ChestHand", values)
        q_hand = {f"slide{k + 1}": rng.uniform(0, 0.3) for k in range(3)}
        s = rng.uniform(-0.05, 0.05)
        for concept in ("ChestLoop", "ChestMasked", "ChestVariant"):
            other, _ = _evaluate(chests, concept, values)
            q = {f"slide[{k}]": q_hand[f"slide{k + 1}"] for k in range(3)}
            for k in range(3):
                handle = f"handle[{k}]@bar" if concept == "ChestVariant" else f"handle[{k}]"
                pairs = [
                    ("link", f"drawer[{k}]", f"drawer{k + 1}"),
                    ("grasp", f"push[{k}]", f"push{k + 1}"),
                    ("grasp", f"{handle}.pull", f"handle{k + 1}.pull"),
                ]
                for kind, mine, theirs in pairs:
                    np.testing.assert_allclose(
                        other(kind, mine, q, s), hand(kind, theirs, q_hand, s), atol=1e-12
                    )


def test_masked_loop_unrolls_to_the_largest_count(chests: Any) -> None:
    _, low = _evaluate(chests, "ChestMasked", {})
    assert [j.name for j in low.joints] == [f"slide[{k}]" for k in range(5)]
    assert low.masks["drawer[3]"] == [("n", 3)] and "drawer[0]" not in low.masks
    assert low.masks["handle[4]"] == [("n", 4)]
    assert list(low.actions["open[2]"].using) == ["handle[2].pull"]


def test_variant_parts_are_masked_by_their_choice(chests: Any) -> None:
    _, low = _evaluate(chests, "ChestVariant", {})
    assert low.variants["handle[1]"] == ("kind", {"bar": "handle[1]@bar", "ring": "handle[1]@ring"})
    assert low.masks["handle[0]@ring"] == [("kind", "ring")]
    assert low.masks["handle[1]@ring"] == [("n", 1), ("kind", "ring")]
    assert low.masks["handle[2]@ring"] == [("n", 2), ("kind", "ring")]
    assert low.actions["open[0]"].using == ("handle[0]@bar.pull", "handle[0]@ring.pull")
    assert "handle[0]@ring.r_out" in [p.name for p in low.params]


def _expanded(text: str) -> tuple[ast.Concept, list[Any]]:
    module = parse(text, "t.eac").module
    assert module is not None
    out, diags, _ = expand(module)
    return out.concepts[0], diags


def test_constant_selector_picks_its_option() -> None:
    c, diags = _expanded(
        'concept C { for i in 0..3 { part h[i] = match (if i == 0 then "k" else "b") '
        '{ "k" => K(), "b" => B() } } }'
    )
    assert diags == []
    assert [(m.name, m.concept) for m in c.members] == [("h[0]", "K"), ("h[1]", "B"), ("h[2]", "B")]
    assert c.masks == () and c.variants == ()


def test_loop_variable_and_nested_indices() -> None:
    c, diags = _expanded(
        "concept C { for r in 0..2 { for k in 1..3 { let x[r][k] = r * 10 + k - x0[r] } } "
        "let x0[0] = 1 }"
    )
    names = [m.name for m in c.members]
    assert names == ["x[0][1]", "x[0][2]", "x0[0]"]  # x[1][k] read x0[1], which does not exist
    assert [d.code for d in diags] == ["E122"]
    values = [m.value for m in c.members if m.name == "x[0][2]"]
    assert isinstance(values[0], ast.Binary)


def test_const_int_and_split_indexed() -> None:
    e = parse("concept C { let a = 2 * i - 1 }").module.concepts[0].members[0].value  # type: ignore[union-attr]
    assert const_int(e, {"i": 4}) == 7 and const_int(e, {}) is None
    assert split_indexed("door[1][2]") == ("door", (1, 2))
    assert split_indexed("door") is None


def test_files_without_loops_are_untouched(tmp_path: Path) -> None:
    """The expand pass returns the very same declarations for a plain file."""
    text = (Path(__file__).resolve().parents[2] / "concepts" / "handles.eac").read_text()
    module = parse(text, "handles.eac").module
    assert module is not None
    out, diags, quiet = expand(module)
    assert diags == [] and not quiet
    assert all(a is b for a, b in zip(out.concepts, module.concepts, strict=True))


@pytest.mark.parametrize(
    ("body", "code"),
    [
        ("param n : int in [0, 100] = 3\n for i in 0..n { let a[i] = i }", "E121"),
        ("param n : int in [1, 4] = 2\n for n in 0..n { let a[n] = 1 }", "E123"),
        ("for i in 0..3 { param p : length = 1mm }", "E114"),
        ("for i in 0.5..3 { let a[i] = i }", "E120"),
        ("let a = 1\n let b = a[0]", "E125"),
        ('param k : choice{"a", "b"} = "a"\n part h = match k { "a" => X(), "c" => Y() }', "E126"),
        ('part h = match 3 { "a" => X() }', "E126"),
        ('part h = match "z" { "a" => X() }', "E126"),
    ],
)
def test_diagnostics(body: str, code: str) -> None:
    _, diags = _expanded("concept C {\n" + body + "\n}")
    assert code in [d.code for d in diags], diags


NESTED = """use primitives.{Cuboid}
use handles.{StraightHandle, RingPull}

concept Row {
    param n : int in [1, 3] = 2
    param kind : choice{"bar", "ring"} = "bar"
    for i in 0..n {
        link d[i] {
            shape f[i] = Cuboid(size: (100mm, 100mm, 10mm)) at trans(i * 110mm, 0, 0)
            part h[i] = match kind { "bar" => StraightHandle(), "ring" => RingPull() }
        }
        joint s[i] : prismatic(base -> d[i]) axis (0, 0, 1) range [0, 100mm]
    }
}

concept Host {
    param m : int in [1, 3] = 3
    param style : choice{"bar", "ring"} = "ring"
    part a = Row(n: 2, kind: "ring")
    part b = Row()
    part c = Row(n: m, kind: style)
    for i in 0..2 {
        part r[i] = Row(n: 1, kind: if i == 0 then "bar" else "ring") at trans(0, i * 200mm, 0)
    }
}
"""


def test_masks_of_parts_follow_what_the_host_binds(tmp_path: Path) -> None:
    path = tmp_path / "nested.eac"
    path.write_text(NESTED, encoding="utf-8")
    _, checked, diags = front_end([path])
    assert not has_errors(diags), diags
    low = casadi_functions(checked, "Host").lowered
    masks = low.masks
    assert "a.d[1]" not in masks and masks["a.d[2]"] == [("", 0)]  # n: 2 decided here
    assert masks["a.h[0]@bar"] == [("", 0)] and "a.h[0]@ring" not in masks
    assert masks["b.d[2]"] == [("b.n", 2)]  # lifted: the part's own count
    assert masks["b.h[1]@ring"] == [("b.n", 1), ("b.kind", "ring")]
    assert masks["c.d[2]"] == [("m", 2)]  # bound to the host's count
    assert masks["c.h[0]@bar"] == [("style", "bar")]
    assert low.variants["c.h[0]"] == ("style", {"bar": "c.h[0]@bar", "ring": "c.h[0]@ring"})
    # a per-copy choice, an expression of the loop variable: bar for r[0], ring for r[1]
    assert masks["r[0].h[0]@ring"] == [("", 0)] and "r[0].h[0]@bar" not in masks
    assert masks["r[1].h[0]@bar"] == [("", 0)] and "r[1].h[0]@ring" not in masks


def test_declarations_on_a_masked_copy_share_its_mask() -> None:
    c, diags = _expanded(
        "concept C {\n param n : int in [1, 3] = 2\n"
        " for i in 0..n { link d[i] { shape f[i] = Cuboid() } "
        "joint s[i] : prismatic(base -> d[i]) axis (0, 0, 1) range [0, 1] }\n"
        " link knob { shape k = Cuboid() }\n"
        " joint spin : revolute(d[2] -> knob) axis (0, 0, 1) range [0, 1]\n"
        " action turn = turn along spin\n}"
    )
    assert diags == []
    masks = dict(c.masks)
    assert masks["d[2]"] == (("n", 2),)
    assert masks["spin"] == masks["knob"] == masks["k"] == masks["turn"] == (("n", 2),)
    assert "d[0]" not in masks and "s[0]" not in masks
