"""Scene files: the objects of a room (concept instances with poses, parameters and joint values).

A scene file is JSON (``.json``) or YAML (``.yaml``/``.yml``, read with PyYAML when it is
installed)::

    {"name": "kitchen", "description": "...",
     "objects": [{"name": "chest", "concept": "ChestOfDrawers", "params": {"travel": 0.35},
                  "position": [1.2, 0.0, 0.0], "yaw": 3.1416, "joints": {"slide1": 0.0}}]}

Units are SI. ``position`` is the object's place in the world (z up): x and y are where its
concept origin stands, z is the height of its lowest point above the floor (0: it stands on the
floor, 0.9: on a worktop). ``yaw`` (rad, about world z) turns it; at 0 its front faces world +x.
``object_pose`` gives the 4x4 world pose of the concept frame (concept +y is world +z, as
``grace_dsl.sim.model.zup_pose`` stands a concept up).

Every problem is a ``SceneFileError`` naming the file, the entry (``objects[2].params.size``)
and what is wrong, with a suggestion for a misspelt concept, parameter or joint name.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import asdict
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from grace_dsl.agent.errors import SceneFileError
from grace_dsl.agent.plan import SceneObject, SceneSpec
from grace_dsl.errors import GraceError
from grace_dsl.runtime.concept import suggest

if TYPE_CHECKING:
    from grace_dsl.runtime.instance import Instance
    from grace_dsl.runtime.library import Library

_OBJECT_KEYS = ("name", "concept", "params", "position", "yaw", "joints")


# ---- reading and writing -----------------------------------------------------------------------


def shipped_scenes() -> dict[str, Path]:
    """``{name: path}`` of the example scenes that come with the package."""
    root = resources.files("grace_dsl") / "scenes"
    return {
        Path(str(p)).stem: Path(str(p))
        for p in sorted(root.iterdir(), key=lambda p: p.name)
        if p.name.endswith((".json", ".yaml", ".yml"))
    }


def resolve_scene_path(name_or_path: str | Path) -> Path:
    """A path as given, or the shipped scene of that name (``kitchen``)."""
    path = Path(name_or_path)
    if path.exists():
        return path
    shipped = shipped_scenes()
    if str(name_or_path) in shipped:
        return shipped[str(name_or_path)]
    raise SceneFileError(
        f"{name_or_path}: no such file and no shipped scene of that name"
        f"; shipped scenes: {', '.join(shipped)}"
    )


def load_scene(path: str | Path, lib: Library | None = None) -> SceneSpec:
    """Read and check a scene file (a shipped scene's name works too); with ``lib``, also check
    its concept, parameter and joint names and values against the library."""
    path = resolve_scene_path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise SceneFileError(f"{path}: cannot read: {exc.strerror or exc}") from exc
    data = _decode(text, path)
    scene = scene_from_data(data, str(path))
    if lib is not None:
        check_scene(scene, lib, str(path))
    return scene


def save_scene(scene: SceneSpec, path: str | Path) -> Path:
    """Write ``scene`` as JSON or YAML (by the suffix); returns the path."""
    path = Path(path)
    data = scene_to_data(scene)
    if path.suffix in (".yaml", ".yml"):
        text = _yaml().safe_dump(data, sort_keys=False)
    else:
        text = json.dumps(data, indent=2) + "\n"
    try:
        path.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise SceneFileError(f"{path}: cannot write: {exc.strerror or exc}") from exc
    return path


def scene_to_data(scene: SceneSpec) -> dict[str, Any]:
    data = asdict(scene)
    for obj in data["objects"]:
        obj["position"] = list(obj["position"])
    return data


def _yaml() -> Any:
    try:
        import yaml
    except ImportError as exc:  # pragma: no cover - PyYAML is installed almost everywhere
        raise SceneFileError("YAML scene files need PyYAML: pip install pyyaml") from exc
    return yaml


def _decode(text: str, path: Path) -> Any:
    if path.suffix in (".yaml", ".yml"):
        yaml = _yaml()
        try:
            return yaml.safe_load(text)
        except yaml.YAMLError as exc:
            raise SceneFileError(f"{path}: not valid YAML: {exc}") from exc
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise SceneFileError(
            f"{path}: not valid JSON at line {exc.lineno}, column {exc.colno}: {exc.msg}"
        ) from exc


def scene_from_data(data: Any, source: str = "<scene>") -> SceneSpec:
    """A ``SceneSpec`` from decoded JSON/YAML, checking its shape (not yet its names)."""
    if not isinstance(data, Mapping):
        raise SceneFileError(f"{source}: the top level must be a mapping with 'objects'")
    unknown = set(data) - {"name", "description", "objects"}
    if unknown:
        raise SceneFileError(
            f"{source}: unknown top-level key {sorted(unknown)[0]!r}; "
            "known: name, description, objects"
        )
    objects = data.get("objects")
    if not isinstance(objects, list) or not objects:
        raise SceneFileError(f"{source}: 'objects' must be a non-empty list")
    parsed = tuple(_object(o, f"{source}: objects[{i}]") for i, o in enumerate(objects))
    seen: set[str] = set()
    for i, obj in enumerate(parsed):
        if obj.name in seen:
            raise SceneFileError(
                f"{source}: objects[{i}]: the name {obj.name!r} is used twice; names must differ"
            )
        seen.add(obj.name)
    name = data.get("name", Path(source).stem)
    return SceneSpec(str(name), parsed, str(data.get("description", "")))


def _object(o: Any, where: str) -> SceneObject:
    if not isinstance(o, Mapping):
        raise SceneFileError(f"{where}: an object must be a mapping with 'name' and 'concept'")
    for key in o:
        if key not in _OBJECT_KEYS:
            raise SceneFileError(f"{where}: unknown key {key!r}" + suggest(str(key), _OBJECT_KEYS))
    for key in ("name", "concept"):
        if not isinstance(o.get(key), str) or not o[key]:
            raise SceneFileError(f"{where}: {key!r} must be a non-empty string")
    where = f"{where} ({o['name']})"
    params = o.get("params", {})
    joints = o.get("joints", {})
    for key, value in (("params", params), ("joints", joints)):
        if not isinstance(value, Mapping):
            raise SceneFileError(f"{where}: {key!r} must be a mapping of names to values")
    position = o.get("position", [0.0, 0.0, 0.0])
    if (
        not isinstance(position, (list, tuple))
        or len(position) != 3
        or not all(_number(x) for x in position)
    ):
        raise SceneFileError(f"{where}.position: must be three numbers [x, y, z] in metres")
    yaw = o.get("yaw", 0.0)
    if not _number(yaw):
        raise SceneFileError(f"{where}.yaw: must be a number (radians), not {yaw!r}")
    for jname, value in joints.items():
        if not _number(value):
            raise SceneFileError(f"{where}.joints.{jname}: must be a number, not {value!r}")
    return SceneObject(
        name=o["name"],
        concept=o["concept"],
        params=dict(params),
        position=(float(position[0]), float(position[1]), float(position[2])),
        yaw=float(yaw),
        joints={str(k): float(v) for k, v in joints.items()},
    )


def _number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


# ---- checking against a library and placing in the world -------------------------------------


def check_scene(scene: SceneSpec, lib: Library, source: str = "<scene>") -> None:
    """Every object's concept, parameter names and values, and joint names and values are the
    library's; raises ``SceneFileError`` naming the first that is not."""
    for i, obj in enumerate(scene.objects):
        object_instance(obj, lib, f"{source}: objects[{i}] ({obj.name})")


def object_instance(obj: SceneObject, lib: Library, where: str | None = None) -> Instance:
    """``obj``'s concept instantiated with its parameters and joints (concept frame, no pose)."""
    where = where or f"object {obj.name!r}"
    if obj.concept not in lib:
        raise SceneFileError(
            f"{where}.concept: no concept {obj.concept!r} in the library"
            + suggest(obj.concept, list(lib))
        )
    concept = lib[obj.concept]
    names = [p.name for p in concept.params]
    for key in obj.params:
        if key not in names:
            raise SceneFileError(
                f"{where}.params: {obj.concept} has no parameter {key!r}" + suggest(key, names)
            )
    try:
        inst = concept.instantiate(**obj.params)
    except GraceError as exc:
        raise SceneFileError(f"{where}.params: {exc}") from exc
    known = list(inst.joints)
    for key in obj.joints:
        if key not in known:
            raise SceneFileError(
                f"{where}.joints: {obj.concept} has no joint {key!r}" + suggest(key, known)
            )
    try:
        return inst.with_joints(dict(obj.joints))
    except GraceError as exc:
        raise SceneFileError(f"{where}.joints: {exc}") from exc


def object_pose(obj: SceneObject, inst: Instance) -> np.ndarray:
    """The world pose (4x4) of ``obj``'s concept frame: stood up as the simulator does (concept
    +y -> world +z), its front turned to face world +x rotated by ``obj.yaw``, its concept origin
    above ``position[:2]`` and its lowest point (joints closed) at height ``position[2]``."""
    from grace_dsl.sim.model import zup_pose

    # zup_pose at yaw 0 turns the concept's front (+z) to world -y; a quarter turn more faces +x
    pose = zup_pose(inst, obj.position[:2], obj.yaw + math.pi / 2)
    pose[2, 3] += obj.position[2]
    return pose


def world_instances(scene: SceneSpec, lib: Library) -> dict[str, Instance]:
    """``{object name: instance}``, each at its world pose with the scene's joint values: what
    the simulator and the grounding place in the room."""
    out = {}
    for obj in scene.objects:
        inst = object_instance(obj, lib)
        out[obj.name] = inst.with_pose(object_pose(obj, inst))
    return out
