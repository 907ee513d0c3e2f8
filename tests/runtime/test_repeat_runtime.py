"""Instances of a concept with repeated and variant members (``runtime/masks.py``).

One compiled unit serves every count: an instance with ``n = 2`` has drawers 0 and 1 only
(typed errors name the valid indices), ``handle[i].pull`` is the grasp of the option the
instance has chosen, and its mesh, links and exported model hold only what it has.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from grace_dsl.compiler.build import build
from grace_dsl.export.model import build_model
from grace_dsl.runtime.errors import ParameterError, UnknownNameError
from grace_dsl.runtime.library import Library

pytestmark = pytest.mark.slow  # the `stack` fixture compiles a unit (tests/runtime/conftest.py)


def test_count_and_indices(stack: Any) -> None:
    for n in (1, 2, 4):
        inst = stack.instantiate(n=n)
        assert inst.count("drawer") == n == inst.count("slide")
        assert inst.indices("open") == [f"[{k}]" for k in range(n)]
        assert inst.links == ("base", *(f"drawer[{k}]" for k in range(n)))
    with pytest.raises(UnknownNameError, match="repeats nothing called 'body'"):
        stack.instantiate().count("body")


def test_missing_copies_are_typed_errors_naming_the_valid_indices(stack: Any) -> None:
    inst = stack.instantiate(n=2)
    with pytest.raises(
        UnknownNameError, match=r"no grasp 'handle\[2\]\.pull' at n = 2.*\[0\], \[1\]"
    ):
        inst.grasp("handle[2].pull")
    with pytest.raises(UnknownNameError, match=r"no action 'open\[3\]' at n = 2"):
        inst.rank("open[3]")
    with pytest.raises(UnknownNameError, match=r"no link 'drawer\[2\]'"):
        inst.link_pose("drawer[2]")
    with pytest.raises(ParameterError):
        stack.instantiate(n=5)  # outside the count's range


def test_the_same_copy_does_not_depend_on_the_count(stack: Any) -> None:
    """Masking leaves the copies that exist alone: drawer 1 is where it is for n = 2 and 4."""
    a, b = stack.instantiate(n=2), stack.instantiate(n=4)
    np.testing.assert_array_equal(a.grasp("handle[1].pull"), b.grasp("handle[1].pull"))
    np.testing.assert_array_equal(a.link_pose("drawer[1]"), b.link_pose("drawer[1]"))


def test_variant_grasps_follow_the_choice(stack: Any) -> None:
    bar, ring = stack.instantiate(kind="bar"), stack.instantiate(kind="ring")
    np.testing.assert_array_equal(bar.grasp("handle[1].pull"), bar.grasp("handle[1]@bar.pull"))
    np.testing.assert_array_equal(ring.grasp("handle[1].pull"), ring.grasp("handle[1]@ring.pull"))
    assert not np.allclose(bar.grasp("handle[1].pull"), ring.grasp("handle[1].pull"))
    with pytest.raises(UnknownNameError, match='kind = "ring"'):
        ring.grasp("handle[0]@bar.pull")
    # the hook exists on a bar only; rank judges only the chosen option's grasps
    assert {o.grasp for o in ring.rank("open[0]")} == {"handle[0]@ring.pull"}
    assert {o.grasp for o in bar.rank("open[0]")} == {"handle[0]@bar.pull"}


def test_mesh_and_export_hold_only_the_present_copies(stack: Any, tmp_path: Path) -> None:
    # the body reaches y = 2h = 0.3 m; front k's top is at k h + (h - 10 mm) / 2
    tops = [stack.instantiate(n=n).mesh().bounds[1][1] for n in (2, 3, 4)]
    np.testing.assert_allclose(tops, [0.3, 0.3 + 0.07, 0.45 + 0.07], atol=1e-6)
    model = build_model(stack.instantiate(n=2, kind="ring"))
    assert [link.name for link in model.links] == ["base", "drawer_0", "drawer_1"]
    assert [j.name for j in model.joints] == ["slide_0", "slide_1"]
    for link in model.links:
        ET.fromstring(f"<x name='{link.name}'/>")  # a valid XML name
        assert all(c.isalnum() or c == "_" for c in link.name)


def test_the_chest_tutorial_steps(tmp_path: Path) -> None:
    """The values docs/language.md's chest tutorial shows (section 10, step 5)."""
    example = Path(__file__).resolve().parents[2] / "docs" / "examples" / "chest_of_drawers.eac"
    result = build([example], tmp_path / "cache", use_native=False)
    assert result.ok, result.diagnostics
    chest = Library(result.units, result)["ChestOfNDrawers"]
    two = chest.instantiate(n=2)
    assert (two.count("drawer"), two.indices("drawer")) == (2, ["[0]", "[1]"])
    assert two.links == ("base", "drawer[0]", "drawer[1]")
    np.testing.assert_allclose(two.grasp("handle[1].pull")[:3, 3], [0, -0.19, 0.29], atol=1e-12)
    with pytest.raises(UnknownNameError, match=r"indices \[0\], \[1\]"):
        two.grasp("handle[2].pull")
    force = two.force("open[1]", grasp=two.grasp("handle[1].pull"))
    np.testing.assert_allclose(force, [0, 0, 1], atol=1e-12)
    four = chest.instantiate(n=4, handle_kind="ring")
    np.testing.assert_allclose(four.grasp("handle[3].pull")[:3, 3], [0, -0.307, 0.278], atol=1e-12)
    ((lo, hi),) = four.grasp_range("handle[3].pull").values()
    assert (lo, hi) == pytest.approx((-0.698, 0.698), abs=1e-3)
    assert [o.grasp for o in four.rank("open[0]")] == ["handle[0]@ring.pull"]


def test_pictures_and_mesh_files_hold_only_the_present_copies(stack: Any) -> None:
    from grace_dsl.export.meshes import instance_meshes
    from grace_dsl.render.scene import describe

    inst = stack.instantiate(n=2, kind="ring")
    scene = describe(inst, grasps=1, resolution=16)
    assert {p.link for p in scene.parts} == {"base", "drawer[0]", "drawer[1]"}
    assert {a.joint for a in scene.joints} == {"slide[0]", "slide[1]"}
    assert {f.grasp for f in scene.frames} == {
        "handle[0]@ring.pull", "handle[0]@ring.push", "handle[1]@ring.pull", "handle[1]@ring.push"
    }  # fmt: skip
    forces = {(f.action, f.grasp) for f in scene.forces}
    assert {("open[0]", "handle[0]@ring.pull"), ("open[1]", "handle[1]@ring.pull")} <= forces
    assert not any("@bar" in a + g or "[2]" in a + g for a, g in forces)
    assert set(instance_meshes(inst, resolution=16)) == {"base", "drawer[0]", "drawer[1]"}


def test_explain_lists_repeats_and_variants(stack: Any, capsys: pytest.CaptureFixture[str]) -> None:
    from grace_dsl.cli.eacc import _explain_repeats

    _explain_repeats(stack)
    out = capsys.readouterr().out
    assert "drawer  [0] .. [3]  n" in out
    assert 'handle[1]  kind       "bar": StraightHandle (handle[1]@bar), "ring": RingPull' in out
