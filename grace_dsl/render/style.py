"""Colours and proportions shared by every picture (PNG, HTML) and by the coloured GLB export.

One place, so a grasp frame is the same red/green/blue in a PNG, in the browser and in a test
that looks for it, and the object's own colours stay clear of those three.
"""

from __future__ import annotations

RGB = tuple[float, float, float]

# Links, in tree order: muted, light tones that shade well and never read as an axis colour.
LINK_COLORS: tuple[RGB, ...] = (
    (0.78, 0.74, 0.68),  # warm grey: the body (root link)
    (0.55, 0.68, 0.78),  # steel blue: the first moving link (a door, a drawer, a lid)
    (0.86, 0.72, 0.50),  # sand
    (0.62, 0.76, 0.66),  # sage
    (0.76, 0.62, 0.74),  # mauve
    (0.64, 0.64, 0.70),  # slate
)

AXIS_X: RGB = (0.90, 0.10, 0.10)  # a frame's x axis
AXIS_Y: RGB = (0.10, 0.75, 0.15)  # y: the closing direction of a gripper frame
AXIS_Z: RGB = (0.10, 0.25, 0.95)  # z: the approach direction
FRAME_AXES: tuple[RGB, RGB, RGB] = (AXIS_X, AXIS_Y, AXIS_Z)
FORCE: RGB = (0.85, 0.15, 0.80)  # magenta: the way the gripper must move for an action
TWIST: RGB = (0.55, 0.20, 0.90)  # violet: the axis a hand turns about (grasp on a joint axis)
JOINT: RGB = (1.00, 0.58, 0.00)  # orange: a joint's axis, arrow head on its opening sense
BACKGROUND: RGB = (0.93, 0.94, 0.95)  # neutral light grey

# Decoration sizes, as fractions of the scene's size (the diagonal of its bounding box).
FRAME_LENGTH = 0.08
FRAME_MIN = 0.04  # metres: about a Panda finger, so a frame shows even on a small handle...
FRAME_MAX = 0.25  # ...but never more than this fraction of the scene
PRIMITIVE_FRAME = 0.45  # a primitive's own frame, in its picture...
PRIMITIVE_OPACITY = 0.6  # ...seen through the solid
FORCE_LENGTH = 0.18
FORCE_MIN = 0.06  # metres, within FORCE_MAX of the scene (as for frames)
FORCE_MAX = 0.45
JOINT_LENGTH = 0.30  # at least; a revolute axis also spans what it moves, plus JOINT_PAD each end
JOINT_PAD = 0.12
JOINT_THINNER = 0.7  # a joint axis's radius relative to other decorations
LINE_RADIUS = 0.035  # of a decoration's own length, kept within these fractions of the scene size:
MIN_RADIUS = 0.002
MAX_RADIUS = 0.006


def link_color(index: int) -> RGB:
    """The colour of the link at ``index`` in tree order (the palette repeats)."""
    return LINK_COLORS[index % len(LINK_COLORS)]


def hex_color(rgb: RGB) -> str:
    return "#" + "".join(f"{round(255 * max(0.0, min(1.0, c))):02x}" for c in rgb)
