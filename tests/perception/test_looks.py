"""Fused looks: several clouds, each with its own camera, fitted to one set of parameters."""

from __future__ import annotations

import math

import numpy as np
import pytest

from grace_dsl.perception.camera import DEFAULT_INTRINSICS, back_project, look_at, to_world
from grace_dsl.perception.errors import PointCloudError
from grace_dsl.perception.estimate import estimate
from grace_dsl.perception.labels import LabelError
from grace_dsl.perception.looks import Look, LookError, check_looks
from grace_dsl.perception.render import InstanceSDF, bounding_sphere, render

FRONT = (0.0, 0.0)  # azimuth, elevation (deg): level, from the front
SIDE = (75.0, 10.0)


def _square(z: float = 2.0) -> np.ndarray:
    g = np.arange(-0.2, 0.2 + 1e-9, 0.02)
    x, y = np.meshgrid(g, g)
    return np.stack([x.ravel(), y.ravel(), np.full(x.size, z)], axis=1)


def test_looks_are_checked_with_typed_errors(lib) -> None:
    pts, cam = _square(), np.eye(4)
    ok = Look(pts, cam, ["panel"] * len(pts))
    with pytest.raises(LookError, match="non-empty list"):
        check_looks([])
    with pytest.raises(LookError, match="look 1 is a tuple"):
        check_looks([ok, (pts, cam)])
    with pytest.raises(LookError, match="look 0: camera must be a finite 4x4 pose"):
        check_looks([Look(pts, np.zeros(3))])
    skew = np.eye(4)
    skew[0, 1] = 0.5
    with pytest.raises(LookError, match="not a rotation"):
        check_looks([Look(pts, skew)])
    with pytest.raises(LookError, match=r"looks \[1\] have no labels"):
        check_looks([ok, Look(pts, cam)])
    behind = np.diag([1.0, -1.0, -1.0, 1.0])  # turned round: the square is behind it
    with pytest.raises(LookError, match="look 0: its points lie behind its camera"):
        check_looks([Look(pts, behind)])
    with pytest.raises(PointCloudError, match="NaN"):
        check_looks([Look(np.full((40, 3), np.nan), cam)])
    with pytest.raises(LabelError, match="entries for"):
        check_looks([Look(pts, cam, ["panel"])])
    with pytest.raises(LookError, match="not both"):
        estimate(lib["CabinetDrawer"], pts, looks=[ok])
    with pytest.raises(LookError, match="give the points"):
        estimate(lib["CabinetDrawer"])
    checked = check_looks(ok)  # one Look alone is a list of one
    assert len(checked) == 1 and checked[0].labelled
    assert check_looks([Look(pts, cam)])[0].labels.tolist() == [""] * len(pts)


def _shot(inst, az: float, el: float):  # type: ignore[no-untyped-def]
    """Every pixel of ``inst`` seen from azimuth ``az`` and elevation ``el`` (degrees, about
    its front +z), noise-free: world points, camera pose, shape labels."""
    sdf, (c, r) = InstanceSDF(inst), bounding_sphere(inst)
    a, e = math.radians(az), math.radians(el)
    d = np.array([math.cos(e) * math.sin(a), math.sin(e), math.cos(e) * math.cos(a)])
    cam = look_at(c + 3.0 * r * d, c)
    shot = render(inst, cam, DEFAULT_INTRINSICS, sdf, (c, r))
    mask = shot.shape_labels >= 0
    pts = back_project(shot.depth, DEFAULT_INTRINSICS, mask)
    labels = [shot.shapes[k] for k in shot.shape_labels[(shot.depth > 0) & mask]]
    return to_world(pts, cam), cam, labels


@pytest.mark.slow
def test_two_looks_recover_the_depth_one_front_look_cannot_see(lib) -> None:
    """A HingedCabinet 400 mm deep (the default: 560 mm) seen level from the front shows no
    depth at all; a look from the side shows it. Fitted together: the depth, the handle and
    the pose from both."""
    concept = lib["HingedCabinet"]
    inst = concept.instantiate(params={"size": (0.5, 0.8, 0.4)})
    front, side = _shot(inst, FRONT[0], FRONT[1]), _shot(inst, SIDE[0], SIDE[1])
    inv = np.linalg.inv(front[1])
    alone = estimate(concept, to_world(front[0], inv), labels=front[2])
    depth_alone = abs(alone.params["size[2]"] - 0.4) * 1000
    est = estimate(concept, looks=[Look(*front), Look(*side)])
    depth = abs(est.params["size[2]"] - 0.4) * 1000
    width, height = (abs(est.params[f"size[{k}]"] - inst.params["size"][k]) * 1000 for k in (0, 1))
    origin = float(np.linalg.norm(est.pose[:3, 3] - inst.pose[:3, 3])) * 1000
    assert depth_alone > 60, depth_alone
    assert depth < 10 and width < 10 and height < 10, (depth, width, height)
    assert origin < 10 and est.confidence > 0.8, (origin, est.confidence)
