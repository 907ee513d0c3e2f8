"""Fixtures of the agent's tests: one offline parser and the shipped scenes per session."""

from __future__ import annotations

import pytest

import grace_dsl as eac
from grace_dsl.agent.offline import OfflineParser
from grace_dsl.agent.plan import SceneSpec
from grace_dsl.agent.suite import shipped_scene_specs


@pytest.fixture(scope="session")
def parser(lib: eac.Library) -> OfflineParser:
    return OfflineParser(lib)


@pytest.fixture(scope="session")
def scenes(lib: eac.Library) -> dict[str, SceneSpec]:
    return shipped_scene_specs(lib)
