"""Physical simulation in MuJoCo: concept instances as scenes, a flying hand, episodes.

``run_episode``, ``Scene`` and ``Camera`` are imported on first use, so that
``grace_dsl.sim.records`` (the contract the runner and the report share) stays importable
without MuJoCo installed.
"""

from __future__ import annotations

from typing import Any

__all__ = ["Camera", "Scene", "run_episode"]


def __getattr__(name: str) -> Any:
    if name == "run_episode":
        from grace_dsl.sim.episode import run_episode

        return run_episode
    if name == "Scene":
        from grace_dsl.sim.scene import Scene

        return Scene
    if name == "Camera":
        from grace_dsl.sim.camera import Camera

        return Camera
    raise AttributeError(f"module 'grace_dsl.sim' has no attribute {name!r}")
