"""Segmentation: the ground-truth segmenter's name matching, and any Segmenter's clouds."""

from __future__ import annotations

import numpy as np

from grace_dsl.perception.camera import back_project
from grace_dsl.perception.render import DepthRender
from grace_dsl.perception.segment import GroundTruthSegmenter, clouds, query_words
from grace_dsl.perception.types import Intrinsics, Segmenter

K = Intrinsics(fx=10.0, fy=10.0, cx=2.0, cy=1.5, width=4, height=3)


def _shot() -> DepthRender:
    labels = np.array([[-1, 0, 0, 1], [-1, 0, 1, 1], [-1, -1, 1, 1]], dtype=np.int16)
    shapes = np.array([[-1, 0, 0, 1], [-1, 0, 2, 2], [-1, -1, 2, 2]], dtype=np.int16)
    depth = np.where(labels >= 0, 1.0, 0.0)
    return DepthRender(
        depth, labels, ("base", "drawer"), np.eye(4), K, shapes, ("carcass", "panel", "handle.bar")
    )


def test_ground_truth_segmenter_matches_links_and_parts_by_name() -> None:
    shot = _shot()
    seg = GroundTruthSegmenter(shot, "CabinetDrawer")
    rgb = np.zeros((3, 4, 3), dtype=np.uint8)
    drawer = seg.segment(rgb, shot.depth, "the drawer")
    assert list(drawer) == ["drawer"]
    np.testing.assert_array_equal(drawer["drawer"], shot.labels == 1)
    handle = seg.segment(rgb, shot.depth, "Handle")
    assert list(handle) == ["handle"]
    np.testing.assert_array_equal(handle["handle"], shot.shape_labels == 2)
    assert seg.segment(rgb, shot.depth, "door") == {}
    assert seg.segment(rgb, shot.depth, "the") == {}
    assert set(seg.segment(rgb, shot.depth, "cabinet drawer")) == {"drawer"}
    assert query_words("Open the TOP drawer!") == ["open", "top", "drawer"]


class _FakeSegmenter:
    """A stand-in open-vocabulary model: a fixed box for any query that names a knob."""

    def segment(self, rgb: np.ndarray, depth: np.ndarray, query: str) -> dict[str, np.ndarray]:
        if "knob" not in query:
            return {}
        mask = np.zeros(depth.shape, bool)
        mask[1:, 1:3] = True
        return {"knob": mask}


def test_clouds_back_project_what_any_segmenter_returns() -> None:
    fake: Segmenter = _FakeSegmenter()
    depth = np.full((3, 4), 0.5)
    depth[2, 2] = 0.0  # no return: dropped
    rgb = np.zeros((3, 4, 3), dtype=np.uint8)
    out = clouds(fake, rgb, depth, K, "turn the knob")
    mask = np.zeros((3, 4), bool)
    mask[1:, 1:3] = True
    np.testing.assert_allclose(out["knob"], back_project(depth, K, mask))
    assert len(out["knob"]) == 3
    assert clouds(fake, rgb, depth, K, "open the door") == {}
