"""Perception's typed errors: bad input that no estimate should be made from."""

from __future__ import annotations

from grace_dsl.errors import GraceError


class PerceptionError(GraceError, ValueError):
    """Base of perception's errors."""


class PointCloudError(PerceptionError):
    """The cloud is empty, too small, not (N, 3), or holds NaN or infinite values."""


class ModelWeightsError(PerceptionError):
    """Weights are missing, from another concept or model version, or fail their checksum."""
