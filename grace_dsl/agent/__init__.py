"""The agent: an instruction in a scene -> a plan of verifiable sub-tasks (``parse``)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from grace_dsl.agent.plan import Plan, SceneSpec
    from grace_dsl.runtime.library import Library

_PARSERS: dict[int, Any] = {}


def parse(
    instruction: str,
    scene: SceneSpec | str | Path,
    *,
    lib: Library | None = None,
    image: Any = None,
) -> Plan:
    """The plan of ``instruction`` in ``scene`` (a ``SceneSpec``, a scene file or a shipped
    scene's name) by the offline parser; raises ``ParseError`` when it cannot or is ambiguous."""
    from grace_dsl.agent.offline import OfflineParser
    from grace_dsl.agent.plan import SceneSpec
    from grace_dsl.agent.scene_file import load_scene

    if lib is None:
        from grace_dsl import load_library

        lib = load_library()
    if not isinstance(scene, SceneSpec):
        scene = load_scene(scene, lib)
    parser = _PARSERS.get(id(lib))
    if parser is None:
        parser = _PARSERS[id(lib)] = OfflineParser(lib)
    return parser.parse(instruction, scene, image=image)


__all__ = ["parse"]
