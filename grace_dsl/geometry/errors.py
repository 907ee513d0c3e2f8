"""The one exception type of the geometry package."""

from __future__ import annotations

from grace_dsl.errors import GraceError


class GeometryError(GraceError, ValueError):
    """A primitive name or parameter that cannot describe a solid; the message says the fix.
    A ``GraceError`` like every deliberate error of grace_dsl, and a ``ValueError`` as before."""
