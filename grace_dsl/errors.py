"""The root of the errors grace_dsl raises on purpose, at the bottom of the layering.

Why here and not in ``runtime``: the geometry kernel and the compiler's native code generator sit
below the runtime yet raise errors a user should be able to catch as one family
(``except eac.GraceError``). This module imports nothing, so every layer can derive from it;
``grace_dsl.runtime.errors`` re-exports it, so existing imports keep working.
"""

from __future__ import annotations

__all__ = ["GraceError"]


class GraceError(Exception):
    """Base of every error grace_dsl raises on purpose."""
