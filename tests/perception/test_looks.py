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
