"""Part labels of a cloud's points, resolved to the concept's shapes each point is measured
against.

Why: every source of clouds here already knows which part each pixel shows (the renderer's link
and shape labels, the simulator's geom names, a ``Segmenter``'s mask per named part), and a fit
that measures each point against the union of all shapes lets a handle's few points sit on the
front and a box's back pass for its front. A label is a name at any of three grains:

- a link (``drawer``): every outermost shape on that link;
- a part, the prefix of shape names (``handle`` covers ``handle.bar`` and ``handle@bar.bar``);
- a shape (``handle.bar``): itself.

A name matching several grains covers the union of what it matches. ``""`` marks a point with
no label: it is measured against every shape, as in the unlabelled fit.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from grace_dsl.perception.errors import PerceptionError

UNLABELLED = ""


class LabelError(PerceptionError):
    """Labels that do not fit the cloud (wrong length, not names) or name no part of the
    concept."""


def _parts(shapes: Sequence[str]) -> list[str]:
    """Every part prefix of the shape names: ``handle@bar.bar`` gives ``handle@bar`` and
    ``handle``."""
    out: list[str] = []
    for name in shapes:
        for i, ch in enumerate(name):
            if ch in ".@" and name[:i] not in out:
                out.append(name[:i])
    return out


def valid_labels(shapes: Sequence[str], links: Sequence[str]) -> list[str]:
    """The names a label may take for a concept with these outermost shapes and their links."""
    out: list[str] = []
    for name in [*dict.fromkeys(links), *_parts(shapes), *shapes]:
        if name not in out:
            out.append(name)
    return out


def covered(name: str, shapes: Sequence[str], links: Sequence[str]) -> np.ndarray:
    """(S,) bool: the shapes the label ``name`` covers (all of them for ``UNLABELLED``)."""
    if name == UNLABELLED:
        return np.ones(len(shapes), bool)
    return np.array(
        [
            s == name or link == name or s.startswith(name + ".") or s.startswith(name + "@")
            for s, link in zip(shapes, links, strict=True)
        ],
        bool,
    )


def check_labels(labels: Any, n_points: int) -> np.ndarray:
    """``labels`` as an (N,) array of str, or ``LabelError`` naming what is wrong."""
    if isinstance(labels, str | bytes) or not isinstance(labels, Sequence | np.ndarray):
        raise LabelError(
            f"labels must be a sequence of part names, one per point; got {type(labels).__name__}"
        )
    out = np.asarray(labels, dtype=object).reshape(-1)
    if len(out) != n_points:
        raise LabelError(
            f"labels has {len(out)} entries for {n_points} points: give one part name per point "
            "(or build both with labelled_points)"
        )
    if isinstance(labels, np.ndarray) and labels.dtype.kind == "U":
        return labels.reshape(-1)  # already str: no per-point check needed
    bad = [x for x in out[:n_points] if not isinstance(x, str)]
    if bad:
        raise LabelError(f"labels must be str part names, got {type(bad[0]).__name__} {bad[0]!r}")
    return out.astype(str)


def label_masks(
    labels: np.ndarray, shapes: Sequence[str], links: Sequence[str], concept: str = ""
) -> np.ndarray:
    """(N, S) bool: per point, the shapes its label covers; ``LabelError`` for an unknown
    name, listing the valid ones."""
    names, inverse = np.unique(labels, return_inverse=True)
    rows = []
    for name in names:
        mask = covered(str(name), shapes, links)
        if not mask.any():
            valid = ", ".join(valid_labels(shapes, links))
            raise LabelError(
                f"label {str(name)!r} names no part of {concept or 'the concept'}; "
                f"valid: {valid} (or '' for an unlabelled point)"
            )
        rows.append(mask)
    return np.stack(rows)[inverse.reshape(-1)]


def labelled_points(clouds: Mapping[str, Any]) -> tuple[np.ndarray, list[str]]:
    """One cloud with a label per point from clouds per part name (``segment.clouds`` gives
    them): the ``points`` and ``labels`` ``estimate`` takes."""
    if not clouds:
        raise LabelError("no part clouds given: segment the object first")
    pts, names = [], []
    for name, cloud in clouds.items():
        arr = np.asarray(cloud, float).reshape(-1, 3)
        pts.append(arr)
        names += [str(name)] * len(arr)
    return np.concatenate(pts), names


def subsample(labels: np.ndarray, limit: int, rng: np.random.Generator) -> np.ndarray:
    """Indices of at most ``limit`` points that keep every label's points in proportion, but
    at least ``min(count, limit // (2 * labels))`` of each: a handle's few points survive a
    cabinet's many."""
    names, inverse = np.unique(labels, return_inverse=True)
    inverse = inverse.reshape(-1)
    if len(labels) <= limit:
        return np.arange(len(labels))
    counts = np.bincount(inverse, minlength=len(names))
    floor = np.minimum(counts, limit // (2 * len(names)))
    rest = limit - int(floor.sum())
    extra = counts - floor
    share = np.floor(rest * extra / max(int(extra.sum()), 1)).astype(int)
    keep = []
    for k in range(len(names)):
        idx = np.nonzero(inverse == k)[0]
        take = min(len(idx), int(floor[k] + share[k]))
        keep.append(rng.choice(idx, take, replace=False))
    return np.sort(np.concatenate(keep))
