"""SAPIEN 3's PhysX as the second engine of the flying-hand episodes: the URDF export loads in a
scene of a PhysX CPU system alone, the hand floats and opens there as in MuJoCo, a real drawer
episode succeeds, and ``engine`` is checked. The tests that need SAPIEN skip without it (the
optional ``sapien`` extra); the checks of the export and of the configuration run everywhere."""

from __future__ import annotations

import importlib.util
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.export import build_model, write_urdf
from grace_dsl.runtime.errors import ParameterError
from grace_dsl.runtime.gripper import Gripper
from grace_dsl.sim.episode import Z_UP, run_episode
from grace_dsl.sim.records import EpisodeConfig

needs_sapien = pytest.mark.skipif(
    importlib.util.find_spec("sapien") is None,
    reason="SAPIEN 3 is not installed (the optional extra: pip install -e '.[sapien]')",
)


def _physx_scene():  # type: ignore[no-untyped-def]
    import sapien

    return sapien.Scene([sapien.physx.PhysxCpuSystem()])  # no render system: CPU physics only


def test_the_urdf_collides_through_the_convex_pieces_and_can_leave_out_visuals(
    lib: eac.Library, tmp_path: Path
) -> None:
    """The URDF's collision elements are the export's convex pieces (a sliding window's ring
    frame as its four bars, not the ring whose hull is a solid block over the sash)."""
    model = build_model(lib["SlidingWindow"].instantiate(pose=Z_UP))
    full = ET.fromstring(write_urdf(model, tmp_path / "w.urdf"))
    bare = ET.fromstring(write_urdf(model, tmp_path / "bare.urdf", visual=False))
    for link in model.links:
        [el] = [e for e in full.iter("link") if e.get("name") == link.name]
        assert len(el.findall("visual")) == len(link.geoms)
        assert len(el.findall("collision")) == len(link.collision or link.geoms)
    assert not list(bare.iter("visual"))
    assert len(list(bare.iter("collision"))) == len(list(full.iter("collision")))


@needs_sapien
@pytest.mark.slow  # the first export of a concept computes its convex pieces
@pytest.mark.parametrize("concept", ["CabinetDrawer", "HingedCabinet"])
def test_the_urdf_export_loads_in_a_physx_scene_with_its_joints_and_limits(
    lib: eac.Library, tmp_path: Path, concept: str
) -> None:
    """Loaded by SAPIEN's URDF loader, the articulation has the export's joints, kinds and
    limits, and at a joint value its link sits where the runtime puts it."""
    inst = lib[concept].instantiate(pose=Z_UP)
    model = build_model(inst)
    path = tmp_path / "object.urdf"
    write_urdf(model, path, visual=False)
    scene = _physx_scene()  # kept alive: the articulation lives in it
    art = scene.create_urdf_loader().load(str(path))
    moving = [j for j in model.joints if j.kind != "fixed"]
    assert [j.name for j in art.active_joints] == [j.name for j in moving]
    kinds = {"revolute": "revolute_unwrapped", "prismatic": "prismatic"}
    for joint, spec in zip(art.active_joints, moving, strict=True):
        assert joint.type == kinds[spec.kind]
        assert np.allclose(joint.limit, [[spec.lo, spec.hi]], atol=1e-6)
    for link in model.links:
        [found] = [x for x in art.links if x.name == link.name]
        assert len(found.collision_shapes) == len(link.collision)
    q = np.array([0.7 * (j.hi or 0.0) for j in moving], dtype=np.float32)
    art.set_qpos(q)
    moved = inst.with_joints({j.source: float(v) for j, v in zip(moving, q, strict=True)})
    for link in model.links:
        [found] = [x for x in art.links if x.name == link.name]
        expected = moved.link_pose(link.source) @ link.offset
        pose = found.entity_pose.to_transformation_matrix()
        assert np.allclose(pose, expected, atol=1e-5), link.name


@needs_sapien
def test_the_sapien_hand_floats_in_place_and_opens_at_finger_speed(lib: eac.Library) -> None:
    from grace_dsl.sim.sapien_world import SapienWorld

    inst = lib["CabinetDrawer"].instantiate(pose=Z_UP, joints={"slide": 0.1})
    away = np.eye(4)
    away[:3, 3] = (1.0, 0.0, 1.0)  # far from the object: the fingers move freely
    world = SapienWorld.build(inst, Gripper.panda(), away, driven="slide")
    assert world.hand.grasp_force == 70.0 and len(world.hand.fingers) == 2
    assert world.q("slide") == pytest.approx(0.1, abs=1e-6)
    world.set_fingers(0.08)
    for _ in range(100):  # 0.2 s: 20 mm per finger at 0.1 m/s, not yet the 40 mm asked
        world.step(away)
    assert world.opening() == pytest.approx(0.04, abs=3e-3)
    for _ in range(500):
        world.step(away)
    assert world.opening() == pytest.approx(0.08, abs=1e-3)
    assert np.allclose(world.hand_pose(), away, atol=1e-3)  # weightless, held by its spring
    assert world.q("slide") == pytest.approx(0.1, abs=1e-4)  # balanced and untouched: it stays
    assert world.time == pytest.approx(1.2) and not world.unstable()


@needs_sapien
@pytest.mark.slow
def test_a_drawer_opens_under_the_hand_in_sapien() -> None:
    """One real episode on PhysX: the same draw as MuJoCo's test (closed start), opened past
    half its range, and the same record again from the same seed."""
    config = EpisodeConfig("CabinetDrawer", "open", engine="sapien")
    record = run_episode(config, 0)
    assert record.q_initial == 0.0
    assert record.strict and record.lenient, record.detail
    lo, hi = record.q_range
    assert record.q_final >= lo + 0.5 * (hi - lo)
    assert record.option.endswith("(pinch)") and record.config.engine == "sapien"
    again = run_episode(config, 0)
    assert again.q_final == record.q_final  # a pure function of (config, seed)


def test_the_engine_is_checked() -> None:
    with pytest.raises(ParameterError, match="engine"):
        run_episode(EpisodeConfig("CabinetDrawer", engine="bullet"), 0)  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="agent='gripper'"):
        run_episode(EpisodeConfig("CabinetDrawer", agent="arm", engine="sapien"), 0)
    assert EpisodeConfig("CabinetDrawer").engine == "mujoco"  # the default is unchanged


def test_bench_refuses_sapien_for_the_arm() -> None:
    from grace_dsl.cli.grace import main

    assert main(["bench", "--engine", "sapien", "--agent", "arm", "--episodes", "1"]) == 1


def test_without_sapien_the_engine_says_how_to_install_it(
    lib: eac.Library, monkeypatch: pytest.MonkeyPatch
) -> None:
    from grace_dsl.sim.sapien_world import SapienWorld, available

    monkeypatch.setitem(sys.modules, "sapien", None)  # import sapien now fails
    assert not available()
    inst = lib["CabinetDrawer"].instantiate(pose=Z_UP)
    with pytest.raises(ParameterError, match=r"\[sapien\]"):
        SapienWorld.build(inst, Gripper.panda(), np.eye(4))
