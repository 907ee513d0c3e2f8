"""The one exception type of the geometry package."""

from __future__ import annotations


class GeometryError(ValueError):
    """A primitive name or parameter that cannot describe a solid; the message says the fix."""
