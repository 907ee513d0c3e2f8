"""Typed errors of the runtime: each says what was wrong and what to do about it.

``GraceError``, their base, lives in :mod:`grace_dsl.errors` (below every layer) and is re-exported
here.
"""

from __future__ import annotations

from collections.abc import Sequence

from grace_dsl.errors import GraceError

__all__ = [
    "CompileError",
    "GraceError",
    "GraspConditionError",
    "ParameterError",
    "RequirementError",
    "UnknownNameError",
]


class CompileError(GraceError):
    """A library did not compile; ``diagnostics`` holds every problem, ``str()`` renders them."""

    def __init__(self, rendered: str, diagnostics: Sequence[object]):
        super().__init__(rendered)
        self.diagnostics = diagnostics


class UnknownNameError(GraceError, KeyError):
    """A concept, parameter, joint, link, grasp or action that does not exist."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0])


class ParameterError(GraceError, ValueError):
    """A parameter value of the wrong shape, not finite, or outside its range."""


class GraspConditionError(ParameterError):
    """A grasp family asked for where its ``when`` condition fails (a hook behind a drawer's
    front while the drawer is shut): the message names the condition and the joint values."""


class RequirementError(ParameterError):
    """Parameter values that violate one of the concept's ``require`` constraints."""


class EvaluationError(GraceError, ArithmeticError):
    """A compiled formula gave a non-finite value (NaN, inf) at these inputs; the message names
    the formula's ``file:line`` (or its concept and member) and the values it was given."""
