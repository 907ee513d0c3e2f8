"""Scene files: reading, writing, located errors, and where objects stand in the world."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from itertools import combinations
from pathlib import Path

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.agent.errors import SceneFileError
from grace_dsl.agent.plan import SceneSpec
from grace_dsl.agent.scene_file import (
    load_scene,
    object_instance,
    object_pose,
    save_scene,
    scene_from_data,
    shipped_scenes,
    world_instances,
)


def test_shipped_scenes_load_and_spread_out(scenes: dict[str, SceneSpec]) -> None:
    assert set(shipped_scenes()) >= {"kitchen", "hall", "bathroom"}
    kitchen = {o.concept for o in scenes["kitchen"].objects}
    assert {"ChestOfDrawers", "Microwave"} <= kitchen
    assert any("Door" in o.concept for o in scenes["hall"].objects)
    for scene in scenes.values():
        assert len(scene.objects) >= 3
        for a, b in combinations(scene.objects, 2):  # room for a flying hand between them
            assert math.dist(a.position[:2], b.position[:2]) >= 1.2, (a.name, b.name)


@pytest.mark.parametrize("suffix", [".json", ".yaml"])
def test_round_trip(
    scenes: dict[str, SceneSpec], tmp_path: Path, suffix: str, lib: eac.Library
) -> None:
    path = save_scene(scenes["hall"], tmp_path / f"hall{suffix}")
    again = load_scene(path, lib)
    assert again == scenes["hall"]


def _write(tmp_path: Path, data: object) -> Path:
    path = tmp_path / "room.json"
    path.write_text(json.dumps(data))
    return path


def _room(**changes: object) -> dict[str, object]:
    obj: dict[str, object] = {"name": "mw", "concept": "Microwave", "position": [0, 0, 0.9]}
    obj.update(changes)
    return {"name": "room", "objects": [obj]}


@pytest.mark.parametrize(
    ("data", "words"),
    [
        (_room(concept="Microwve"), ["objects[0] (mw).concept", "did you mean 'Microwave'"]),
        (_room(params={"sise": [0.5, 0.3, 0.4]}), ["objects[0] (mw).params", "'size'"]),
        (_room(joints={"hinge": 9.0}), ["objects[0] (mw).joints"]),
        (_room(joints={"hing": 0.1}), ["no joint 'hing'", "did you mean 'hinge'"]),
        (_room(position=[0, 0]), ["objects[0] (mw).position", "three numbers"]),
        (_room(colour="red"), ["objects[0]", "unknown key 'colour'"]),
        ({"objects": []}, ["non-empty list"]),
    ],
)
def test_located_errors(tmp_path: Path, lib: eac.Library, data: object, words: list[str]) -> None:
    path = _write(tmp_path, data)
    with pytest.raises(SceneFileError) as info:
        load_scene(path, lib)
    message = str(info.value)
    assert str(path) in message
    for w in words:
        assert w in message, message


def test_bad_json_and_duplicate_names(tmp_path: Path) -> None:
    path = tmp_path / "bad.json"
    path.write_text('{"objects": [\n  {"name": "a",}\n]}')
    with pytest.raises(SceneFileError, match=r"bad.json: not valid JSON at line 2"):
        load_scene(path)
    twice = {"objects": [{"name": "a", "concept": "Microwave"}] * 2}
    with pytest.raises(SceneFileError, match="'a' is used twice"):
        scene_from_data(twice, "twice.json")
    with pytest.raises(SceneFileError, match="shipped scenes: .*kitchen"):
        load_scene("no-such-room")


def test_world_pose_stands_the_concept_up_facing_x(lib: eac.Library) -> None:
    spec = scene_from_data(_room(), "room")
    obj = spec.objects[0]
    inst = object_instance(obj, lib)
    pose = object_pose(obj, inst)
    assert np.allclose(pose[:3, :3] @ [0, 0, 1], [1, 0, 0], atol=1e-9)  # front -> world +x
    assert np.allclose(pose[:3, :3] @ [0, 1, 0], [0, 0, 1], atol=1e-9)  # up -> world +z
    turned = replace(obj, yaw=math.pi / 2, position=(1.0, 2.0, 0.9))
    pose2 = object_pose(turned, inst)
    assert np.allclose(pose2[:3, :3] @ [0, 0, 1], [0, 1, 0], atol=1e-9)
    assert np.allclose(pose2[:2, 3], [1.0, 2.0])
    # the lowest point of the closed microwave sits at the given height (0.9 m, a worktop)
    from grace_dsl.runtime.shapes import instance_meshes

    placed = world_instances(SceneSpec("r", (turned,)), lib)["mw"]
    z_min = min(np.asarray(m.vertices)[:, 2].min() for m in instance_meshes(placed, resolution=16))
    assert z_min == pytest.approx(0.9, abs=2e-3)
