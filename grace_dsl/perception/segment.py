"""Segmentation behind the ``Segmenter`` interface: the renderer's ground truth.

``GroundTruthSegmenter`` answers a text query with the masks of the rendered instance's links
whose names match it (every word of the query must appear in the link's name, its part's name
or its concept's name, case-insensitive; "the drawer" finds ``drawer``, "handle" finds the
links of the part ``handle``). No open-vocabulary model that runs offline here beats the
renderer's own labels, so this is the default; a model such as Grounded-SAM plugs in behind
the same ``segment`` call.
"""

from __future__ import annotations

import re

import numpy as np

from grace_dsl.perception.camera import back_project
from grace_dsl.perception.render import DepthRender
from grace_dsl.perception.types import Intrinsics, Segmenter

STOP_WORDS = frozenset({"the", "a", "an", "of", "on", "to", "its", "part", "object"})


def query_words(query: str) -> list[str]:
    """The query's content words, lower case."""
    return [w for w in re.findall(r"[a-z0-9]+", query.lower()) if w not in STOP_WORDS]


class GroundTruthSegmenter:
    """Masks from a ``DepthRender``'s labels, matched to the query by name: its links
    (``drawer``) and its parts (the prefix of a shape's name: ``handle`` of ``handle.bar``)."""

    def __init__(self, shot: DepthRender, concept: str = ""):
        self.shot, self.concept = shot, concept

    def candidates(self) -> dict[str, np.ndarray]:
        """Every named region the render can tell apart: links, then parts."""
        out = {link: self.shot.labels == i for i, link in enumerate(self.shot.links)}
        if self.shot.shape_labels is not None:
            for i, shape in enumerate(self.shot.shapes):
                if "." in shape:
                    part = shape.rsplit(".", 1)[0]
                    mask = self.shot.shape_labels == i
                    out[part] = out[part] | mask if part in out else mask
        return out

    def segment(self, rgb: np.ndarray, depth: np.ndarray, query: str) -> dict[str, np.ndarray]:
        words = query_words(query)
        if not words:
            return {}
        out = {}
        for name, mask in self.candidates().items():
            text = f"{name.replace('.', ' ').replace('_', ' ')} {self.concept}".lower()
            if all(re.search(rf"\b{re.escape(w)}", text) for w in words) and mask.any():
                out[name] = mask
        return out


def clouds(
    segmenter: Segmenter, rgb: np.ndarray, depth: np.ndarray, intr: Intrinsics, query: str
) -> dict[str, np.ndarray]:
    """The camera-frame cloud of every part ``segmenter`` finds for ``query`` (pixels with no
    depth dropped): the input ``estimate`` takes, from any segmenter."""
    return {
        name: back_project(depth, intr, mask)
        for name, mask in segmenter.segment(rgb, depth, query).items()
    }
