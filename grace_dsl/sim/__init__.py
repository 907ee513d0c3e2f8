"""Physical simulation in MuJoCo: concept instances as scenes, a flying hand, episodes.

``run_episode`` is imported on first use, so that ``grace_dsl.sim.records`` (the contract the
runner and the report share) stays importable without MuJoCo installed.
"""

from __future__ import annotations

from typing import Any

__all__ = ["run_episode"]


def __getattr__(name: str) -> Any:
    if name == "run_episode":
        from grace_dsl.sim.episode import run_episode

        return run_episode
    raise AttributeError(f"module 'grace_dsl.sim' has no attribute {name!r}")
