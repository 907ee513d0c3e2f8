"""The default task parser: deterministic, offline (no model, no network).

The lexicon comes from the prompt catalog (``lexicon.Lexicon.from_catalog``), the grammar splits
and labels the words (``grammar``), and grounding turns each clause into a sub-task on one part
of one scene object (``grounding``). It refuses, with a ``ParseError`` that says why, whatever it
cannot read or resolve to exactly one part.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from grace_dsl.agent.grammar import parse_clause, split_clauses
from grace_dsl.agent.grounding import GroundedScene, build_plan, ground_scene
from grace_dsl.agent.lexicon import Lexicon
from grace_dsl.agent.plan import Plan, SceneSpec

if TYPE_CHECKING:
    from grace_dsl.runtime.library import Library


class OfflineParser:
    """A ``TaskParser`` that reads English instructions with the catalog's words."""

    def __init__(self, lib: Library | None = None, lexicon: Lexicon | None = None):
        if lib is None:
            from grace_dsl import load_library

            lib = load_library()
        self.lib = lib
        self.lexicon = lexicon or Lexicon.from_library(lib)

    def ground(self, scene: SceneSpec) -> GroundedScene:
        return ground_scene(scene, self.lib)

    def parse(self, instruction: str, scene: SceneSpec, *, image: np.ndarray | None = None) -> Plan:
        """The plan of ``instruction`` in ``scene`` (the image is not used offline)."""
        grounded = self.ground(scene)
        extra = grounded.nouns
        clauses = [parse_clause(c, self.lexicon, extra) for c in split_clauses(instruction)]
        return build_plan(instruction, clauses, grounded, self.lexicon)
