"""The numerical tolerances shared across grace_dsl, in one place so that the compiler's checks,
the runtime's validation and the exporters agree on what "equal" and "inside" mean.

Each value is absolute and in SI units (metres, radians) or unitless, as stated. Tolerances that
belong to one algorithm alone (a verifier's drift budget, a mesh's sampling offset) stay beside
it; these are the ones several modules must share.
"""

from __future__ import annotations

__all__ = ["DEGENERATE", "EXACT", "ON_AXIS", "RANGE_SLACK", "ROTATION"]

#: How far outside a declared range ``[lo, hi]`` a value may lie and still count as inside
#: (parameters, joint values, free grasp parameters, gripper widths): the rounding of unit
#: conversions (mm -> m, deg -> rad) and of ``lo + u (hi - lo)``, never a real excess.
RANGE_SLACK = 1e-12

#: Entries that must hold exactly up to float rounding (a pose's last row 0 0 0 1, a tapered
#: box whose top equals its base): unitless or metres.
EXACT = 1e-12

#: Largest entry of ``|R^T R - I|`` for a matrix to count as a rotation: a pose typed with six or
#: seven significant digits passes, a scaled or sheared one does not (unitless).
ROTATION = 1e-6

#: A length or norm below which a direction is undefined (a zero axis, a gimbal-locked rotation,
#: a segment of no length): metres or unitless. Angles this close count as equal (radians).
DEGENERATE = 1e-9

#: Metres (times the axis' unit length): a point this close to a revolute joint's axis has no
#: linear force direction (the compiled force is NaN there, not rounding noise).
ON_AXIS = 1e-6
