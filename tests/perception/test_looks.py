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
from grace_dsl.perception.views import split_params

FRONT = (0.0, 10.0)  # azimuth, elevation (deg): nearly level, from the front
SIDE = (75.0, 10.0)  # from the side


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
def test_two_looks_recover_what_neither_look_alone_does(lib) -> None:
    """A HingedCabinet 400 mm deep (the default: 560 mm), noise-free. Nearly level from the
    front its depth is a sliver of the top: fitted alone, confidently 100 mm off (measured)
    with the origin 50 mm off. From the side its width and the handle's inset are foreshortened
    (10 mm off each). Fitted together, every length is within 8 mm and the origin within 6."""
    concept = lib["HingedCabinet"]
    inst = concept.instantiate(params={"size": (0.5, 0.8, 0.4)})
    truth = {k: v for k, v in split_params(concept, inst.params)[0].items()}
    looks = [Look(*_shot(inst, *FRONT)), Look(*_shot(inst, *SIDE))]

    def errors(est) -> dict[str, float]:  # type: ignore[no-untyped-def]
        return {k: 1000 * abs(est.params[k] - v) for k, v in truth.items()}

    alone = []
    for look in looks:
        inv = np.linalg.inv(look.camera)
        alone.append(errors(estimate(concept, to_world(look.points, inv), labels=look.labels)))
    assert alone[0]["size[2]"] > 50, alone[0]  # the depth, from the front
    assert max(alone[1]["size[0]"], alone[1]["handle_inset"]) > 7, alone[1]  # from the side
    est = estimate(concept, looks=looks)
    both = errors(est)
    origin = 1000 * float(np.linalg.norm(est.pose[:3, 3] - inst.pose[:3, 3]))
    assert max(both.values()) < 8, both
    assert origin < 6 and est.confidence > 0.8, (origin, est.confidence)
    # the fused fit reports its spread like a single look's (one per float parameter)
    assert set(est.spread) == set(est.params)
    assert all(0 < s < float("inf") for s in est.spread.values()), est.spread
