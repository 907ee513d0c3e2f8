"""The paper's minimal-rotation rule for grasps on rotationally symmetric parts.

A grasp declared ``symmetric about a`` is equally good at any spin about the axis ``a`` (given in
the grasp frame): a round knob pinched across its rim, a cap, a button pressed head-on.  Its
orientation is then made unique by spinning it about ``a`` to the orientation *closest to a
reference* (the hand's current or home orientation): the spin ``phi`` that maximises
``trace(R_ref^T R0 Rot(a, phi))``, i.e. the smallest rotation the wrist has to make.

With ``K = [a]x`` and Rodrigues' formula ``Rot = I + sin(phi) K + (1 - cos(phi)) K^2`` the
objective is ``B sin(phi) - C cos(phi) + const`` with ``B = tr(A K)``, ``C = tr(A K^2)``,
``A = R_ref^T R0``, so the optimum has the closed form ``phi = atan2(B, -C)``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from grace_dsl.runtime.inputs import as_rotation

# The Panda's hand at its ready pose, in the robot's base frame: approaching straight down (+z of
# the gripper along world -z) with the fingers closing along world -y.  The default reference:
# the minimal rotation from it is the smallest wrist turn away from where the arm starts.
HAND_HOME = np.diag([1.0, -1.0, -1.0])


def _skew(a: np.ndarray) -> np.ndarray:
    """(..., 3) -> (..., 3, 3) cross-product matrices."""
    k = np.zeros(a.shape[:-1] + (3, 3))
    k[..., 0, 1], k[..., 0, 2] = -a[..., 2], a[..., 1]
    k[..., 1, 0], k[..., 1, 2] = a[..., 2], -a[..., 0]
    k[..., 2, 0], k[..., 2, 1] = -a[..., 1], a[..., 0]
    return k


def _rotation(a: np.ndarray, phi: np.ndarray) -> np.ndarray:
    k = _skew(a)
    s, c = np.sin(phi)[..., None, None], np.cos(phi)[..., None, None]
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)


# A quarter turn about the reference's x axis: the tie-breaking reference (see minimal_spin).
_TIE_BREAK = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def minimal_spin(r0: np.ndarray, axis: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """The spin angle(s) about ``axis`` (grasp frame, unit) that bring ``r0 Rot(axis, phi)``
    closest to ``reference``; shapes (..., 3, 3), (..., 3), (3, 3) -> (...).

    Every spin is equally close when the symmetry axis is turned exactly half-way from the
    reference (e.g. a hand approaching opposite to the reference's approach); the spin is then
    taken closest to the reference turned a quarter about its x axis, which is not degenerate
    there, so the result stays unique.
    """
    b, c = _objective(r0, axis, reference)
    tied = b * b + c * c < 1e-18
    if np.any(tied):
        b2, c2 = _objective(r0, axis, reference @ _TIE_BREAK)
        b, c = np.where(tied, b2, b), np.where(tied, c2, c)
    return np.arctan2(b, -c)


def _objective(r0: np.ndarray, axis: np.ndarray, reference: np.ndarray) -> tuple[Any, Any]:
    """(B, C) of trace(R_ref^T r0 Rot(axis, phi)) = B sin(phi) - C cos(phi) + const."""
    a = reference.T @ r0
    k = _skew(axis)
    return np.einsum("...ij,...ji->...", a, k), np.einsum("...ij,...ji->...", a, k @ k)


def spin_about(poses: np.ndarray, axes: np.ndarray, angle: float) -> np.ndarray:
    """Poses (..., 4, 4) turned by ``angle`` about their own axes (..., 3, grasp frame)."""
    axes = axes / np.linalg.norm(axes, axis=-1, keepdims=True)
    out = poses.copy()
    out[..., :3, :3] = poses[..., :3, :3] @ _rotation(axes, np.full(axes.shape[:-1], angle))
    return out


def spin_to_reference(poses: np.ndarray, axes: np.ndarray, reference: Any) -> np.ndarray:
    """Poses (..., 4, 4) spun about their symmetry axes (..., 3) to the minimal rotation from
    ``reference`` (a 3x3 rotation or a 4x4 pose, world frame)."""
    ref = _reference(reference)
    axes = axes / np.linalg.norm(axes, axis=-1, keepdims=True)
    phi = minimal_spin(poses[..., :3, :3], axes, ref)
    out = poses.copy()
    out[..., :3, :3] = poses[..., :3, :3] @ _rotation(axes, phi)
    return out


def _reference(reference: Any) -> np.ndarray:
    return HAND_HOME if reference is None else as_rotation(reference)
