"""The agent's typed errors: what a person must change when an instruction cannot be carried out."""

from __future__ import annotations

from grace_dsl.errors import GraceError


class ParseError(GraceError, ValueError):
    """The instruction cannot be parsed into a plan, or it is ambiguous in this scene.

    The message names the words at fault and what would resolve them (a known concept, a
    selector that picks one part)."""


class SceneFileError(GraceError, ValueError):
    """A scene file is malformed: the message names the file, the entry and the problem."""


class ExecutionError(GraceError, RuntimeError):
    """A plan could not be executed (not a failed sub-task, which is a result, but a bad plan)."""


class VLMError(GraceError, RuntimeError):
    """The vision-language model's server could not be reached or configured (not a bad reply,
    which is re-asked and then a ``ParseError``)."""
