"""The new primitives through the whole stack: a concept using all four compiles, its instance's
mesh, signed distance and surface samples agree with the primitives placed by hand, and its
MJCF and URDF exports load in MuJoCo and Pinocchio with the right geoms."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

import grace_dsl as eac
from grace_dsl.export import build_model, export_mjcf, export_urdf
from grace_dsl.export.model import ExportOptions
from grace_dsl.geometry import affordances, primitive_sdf, surface_area, volume

SOURCE = """use primitives.{TaperedCuboid, SphericalCap, Torus, Prism}

/// Test object: a tapered leg and a plain block, a hex knob with a domed top and a ball on a
/// spinning link, a half-torus handle on a hinged flap.
concept NewShapes {
    param leg : vec3 length in [(10mm, 100mm, 10mm), (100mm, 500mm, 100mm)] = (40mm, 300mm, 40mm)
    param sides : int in [3, 12] = 6
    shape taper = TaperedCuboid(size: leg, top: (25mm, 25mm), offset: (5mm, -3mm))
    shape block = TaperedCuboid(size: (60mm, 20mm, 60mm), top: (60mm, 60mm))
        at trans(0, -200mm, 0)
    link knob {
        shape hex = Prism(sides: sides, radius: 20mm, height: 15mm) at trans(0, 0, 100mm)
        shape dome = SphericalCap(radius: 25mm, height: 12mm) at trans(0, 0, 113.5mm)
        shape ball = SphericalCap(radius: 5mm, height: 10mm) at trans(0, 30mm, 120mm)
    }
    link flap {
        shape handle = Torus(r_major: 40mm, r_minor: 6mm, radian: 180deg)
            at trans(100mm, 0, 0) * rotx(90deg)
    }
    joint spin : continuous(base -> knob) axis (0, 0, 1) at (0, 0, 100mm)
    joint hinge : revolute(base -> flap) axis (0, 1, 0) at (100mm, 0, 0) range [0, 90deg]
}

/// Affordance cues of the new primitives, placed by a rotation: origin = center, and grasps
/// one metre along each cue's axis, with the cue's width.
concept Cued {
    param n : int in [3, 12] = 6
    param top : vec2 length in [(0mm, 0mm), (300mm, 300mm)] = (25mm, 25mm)
    param offset : vec2 length in [(-100mm, -100mm), (100mm, 100mm)] = (5mm, -3mm)
    param size : vec3 length in [(10mm, 10mm, 10mm), (300mm, 300mm, 300mm)] = (40mm, 60mm, 40mm)
    param cap : length in [1mm, 50mm] = 12mm
    shape taper = TaperedCuboid(size: size, top: top, offset: offset) at rpy(0.3rad, 0.2rad, 0.1rad)
    shape hex = Prism(sides: n, radius: 20mm, height: 15mm) at rpy(-0.4rad, 0.5rad, 1rad)
    shape dome = SphericalCap(radius: 25mm, height: cap) at rotx(0.3rad)
    shape handle = Torus(r_major: 40mm, r_minor: 6mm, radian: 180deg) at roty(0.7rad)
    grasp taper_axis = trans(taper.principal_axis * 1m) width taper.graspable_width
    grasp hex_axis = trans(hex.principal_axis * 1m) width hex.graspable_width
    grasp dome_axis = trans(dome.principal_axis * 1m) width dome.graspable_width
    grasp handle_axis = trans(handle.principal_axis * 1m) width handle.graspable_width
}
"""

SPIN = 0.7


def _trans(x: float, y: float, z: float) -> np.ndarray:
    out = np.eye(4)
    out[:3, 3] = (x, y, z)
    return out


def _rot(axis: int, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    out = np.eye(4)
    out[i, i], out[i, j], out[j, i], out[j, j] = c, -s, s, c
    return out


# The shapes as a hand would place them: (primitive, SI parameters, pose in the concept frame at
# the instance's joints: the knob turned by SPIN about its axis at z = 100 mm, the flap closed).
KNOB = _trans(0, 0, 0.1) @ _rot(2, SPIN) @ _trans(0, 0, -0.1)
SHAPES = [
    (
        "TaperedCuboid",
        {"size": (0.04, 0.3, 0.04), "top": (0.025, 0.025), "offset": (0.005, -0.003)},
        np.eye(4),
    ),
    ("TaperedCuboid", {"size": (0.06, 0.02, 0.06), "top": (0.06, 0.06)}, _trans(0, -0.2, 0)),
    ("Prism", {"sides": 6, "radius": 0.02, "height": 0.015}, KNOB @ _trans(0, 0, 0.1)),
    ("SphericalCap", {"radius": 0.025, "height": 0.012}, KNOB @ _trans(0, 0, 0.1135)),
    ("SphericalCap", {"radius": 0.005, "height": 0.01}, KNOB @ _trans(0, 0.03, 0.12)),
    (
        "Torus",
        {"r_major": 0.04, "r_minor": 0.006, "radian": math.pi},
        _trans(0.1, 0, 0) @ _rot(0, math.pi / 2),
    ),
]


@pytest.fixture(scope="module")
def lib(tmp_path_factory: pytest.TempPathFactory) -> eac.Library:
    path = tmp_path_factory.mktemp("newshapes") / "new_shapes.eac"
    path.write_text(SOURCE)
    return eac.compile_paths([path])


@pytest.fixture(scope="module")
def pose() -> np.ndarray:
    return _trans(0.3, -0.1, 0.5) @ _rot(1, 0.4) @ _rot(0, -0.2)


@pytest.fixture(scope="module")
def inst(lib: eac.Library, pose: np.ndarray) -> eac.Instance:
    return lib["NewShapes"].instantiate(pose=pose, joints={"spin": SPIN})


def _each(pose: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(shapes, N) distances of world points to each shape."""
    dists = []
    for name, params, place in SHAPES:
        inv = np.linalg.inv(pose @ place)
        dists.append(primitive_sdf(name, params, points @ inv[:3, :3].T + inv[:3, 3]))
    return np.array(dists)


def _by_hand(pose: np.ndarray, points: np.ndarray) -> np.ndarray:
    return np.min(_each(pose, points), axis=0)


def test_mesh_holds_every_shape_with_its_volume(inst: eac.Instance) -> None:
    mesh = inst.mesh()
    assert mesh.is_watertight
    total = sum(volume(name, params) for name, params, _ in SHAPES)
    assert abs(mesh.volume / total - 1) < 0.01


def test_sdf_is_the_union_of_the_primitives_placed_by_hand(
    inst: eac.Instance, pose: np.ndarray
) -> None:
    lo, hi = inst.mesh().bounds
    pts = np.random.default_rng(0).uniform(lo - 0.02, hi + 0.02, (4000, 3))
    np.testing.assert_allclose(inst.sdf(pts), _by_hand(pose, pts), atol=1e-12)


def test_surface_samples_lie_on_the_outer_surface(inst: eac.Instance, pose: np.ndarray) -> None:
    pts = inst.sample_surface(3000, seed=1)
    assert pts.shape == (3000, 3)
    assert np.max(np.abs(_by_hand(pose, pts))) < 1e-6
    on_each = np.sum(np.abs(_each(pose, pts)) < 1e-6, axis=1)
    assert np.all(on_each > 0), on_each
    again = inst.sample_surface(3000, seed=1)
    np.testing.assert_array_equal(pts, again)


def test_samples_are_spread_by_visible_area(inst: eac.Instance, pose: np.ndarray) -> None:
    """The dome's flat face (radius 21.4 mm) covers the hex top (circumradius 20 mm): those two
    hexagons are hidden; every other face is outer surface, so each shape's share of the samples
    is its visible area over the total."""
    n = 20_000
    pts = inst.sample_surface(n, seed=3)
    hexagon = 6 / 2 * 0.02**2 * math.sin(math.pi / 3)
    visible = np.array([surface_area(name, params) for name, params, _ in SHAPES])
    visible[2:4] -= hexagon  # the hex's top and the part of the dome's face resting on it
    share = visible / visible.sum()
    counts = np.sum(np.abs(_each(pose, pts)) < 1e-9, axis=1)
    sigma = np.sqrt(share * (1 - share) / n)
    assert np.all(np.abs(counts / n - share) < 4 * sigma + 1e-3), (counts / n, share)


def test_mjcf_loads_in_mujoco_with_native_geoms_only_where_exact(
    inst: eac.Instance, tmp_path: Path
) -> None:
    path = tmp_path / "new_shapes.xml"
    export_mjcf(inst, path)
    mj = mujoco.MjModel.from_xml_path(str(path))
    visual = mj.geom_group == 2  # the pieces whole; group 3 holds their convex collision pieces
    kinds = sorted(mujoco.mjtGeom(int(t)).name for t in mj.geom_type[visual])
    assert kinds == ["mjGEOM_BOX"] + ["mjGEOM_MESH"] * 4 + ["mjGEOM_SPHERE"]
    assert (mj.geom_group == 3).sum() >= len(kinds)  # every piece collides as one or more
    # the bodies' masses come from the exported solids: density times the analytic volumes
    density = ExportOptions().density
    total = sum(volume(name, params) for name, params, _ in SHAPES)
    assert abs(mj.body_mass.sum() / (density * total) - 1) < 0.01


def test_urdf_loads_in_pinocchio(inst: eac.Instance, tmp_path: Path) -> None:
    path = tmp_path / "new_shapes.urdf"
    export_urdf(inst, path)
    model = pin.buildModelFromUrdf(str(path))
    geoms = pin.buildGeomFromUrdf(
        model, str(path), pin.GeometryType.COLLISION, package_dirs=[str(tmp_path)]
    )
    built = build_model(inst)
    # every shape collides through its convex pieces (one or more per shape)
    assert geoms.ngeoms == sum(len(link.collision) for link in built.links) >= len(SHAPES)
    assert {j.name for j in built.joints} <= set(model.names)


def _rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    return (_rot(2, yaw) @ _rot(1, pitch) @ _rot(0, roll))[:3, :3]


@pytest.mark.parametrize(
    "values",
    [
        {},
        {"n": 3, "size": (0.05, 0.02, 0.03), "top": (0.0, 0.08), "offset": (-0.04, 0.01)},
        {"n": 4, "cap": 0.03, "top": (0.3, 0.0)},
        {"n": 5, "cap": 0.05, "size": (0.01, 0.3, 0.02)},
        {"n": 7, "offset": (0.1, -0.1)},
    ],
)
def test_cues_agree_with_the_geometry_affordances(
    lib: eac.Library, values: dict[str, object]
) -> None:
    inst = lib["Cued"].instantiate(**values)
    p = inst.params
    shapes = {
        "taper": (
            "TaperedCuboid",
            {"size": p["size"], "top": p["top"], "offset": p["offset"]},
            _rpy(0.3, 0.2, 0.1),
        ),
        "hex": ("Prism", {"sides": p["n"], "radius": 0.02, "height": 0.015}, _rpy(-0.4, 0.5, 1)),
        "dome": ("SphericalCap", {"radius": 0.025, "height": p["cap"]}, _rot(0, 0.3)[:3, :3]),
        "handle": (
            "Torus",
            {"r_major": 0.04, "r_minor": 0.006, "radian": math.pi},
            _rot(1, 0.7)[:3, :3],
        ),
    }
    for shape, (name, params, rot) in shapes.items():
        hint = affordances(name, params)
        grasp = f"{shape}_axis"
        np.testing.assert_allclose(
            inst.grasp(grasp)[:3, 3], rot @ hint["principal_axis"], atol=1e-9, err_msg=shape
        )
        assert math.isclose(inst.grasp_width(grasp), hint["graspable_width"], rel_tol=1e-12)
