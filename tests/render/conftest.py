"""Fixtures of the picture tests: a small test library (every moving joint kind, a part with its
own grasp, action and joint, a grasp on its joint's axis) and what the machine can render with."""

from __future__ import annotations

import ctypes.util
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

import grace_dsl as eac

HERE = Path(__file__).parent
TOYBOX = HERE / "toybox.eac"


@pytest.fixture(scope="session")
def toy() -> eac.Library:
    return eac.compile_paths([TOYBOX])


def random_pose(rng: np.random.Generator) -> np.ndarray:
    """A random rigid transform (rotation from a normalised Gaussian quaternion)."""
    q = rng.normal(size=4)
    w, x, y, z = q / np.linalg.norm(q)
    pose = np.eye(4)
    pose[:3, :3] = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]
    pose[:3, 3] = rng.uniform(-1, 1, 3)
    return pose


def gl_available() -> bool:
    """Whether the MuJoCo GL backend the tests use (MUJOCO_GL, set in tests/conftest.py) has its
    library installed (Debian: libosmesa6 for osmesa, libegl1 for egl)."""
    backend = os.environ.get("MUJOCO_GL", "")
    library = {"osmesa": "OSMesa", "egl": "EGL"}.get(backend)
    return library is None or ctypes.util.find_library(library) is not None


def chromium() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


needs_gl = pytest.mark.skipif(
    not gl_available(), reason="no OpenGL library for MUJOCO_GL (make system-deps installs it)"
)
needs_chromium = pytest.mark.skipif(
    chromium() is None, reason="chromium is not installed (make system-deps installs it)"
)
