"""The domain's small values every layer speaks of: the door's nominal size and the tool's orientation.

This module imports nothing from doorloc, so the cell, the recipes, the robot and the services can all
import it without forming a circle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, get_args

__all__ = [
    "ArrisProfile",
    "DoorSize",
    "Quat",
    "TOOL_Y_ALONG_CELL_Y",
    "TOOL_Z_ALONG_CELL_Y",
    "tool_base_orientation",
]

ArrisProfile = Literal["chamfer", "round"]

#: unit quaternion, scalar first (w, x, y, z)
Quat = tuple[float, float, float, float]
#: default tool orientation at yaw 0: tool frame = cell axes, spindle along tool +Y = cell +Y
TOOL_Y_ALONG_CELL_Y: Quat = (1.0, 0.0, 0.0, 0.0)
#: alternative: spindle along tool +Z = cell +Y, tool +X = cell +X (a rotation by -90 deg about X)
TOOL_Z_ALONG_CELL_Y: Quat = (math.sqrt(0.5), -math.sqrt(0.5), 0.0, 0.0)


def tool_base_orientation(spindle_axis: Literal["y", "z"]) -> Quat:
    """Tool orientation at yaw 0 for a tool frame whose spindle is its +Y or its +Z axis."""
    return TOOL_Y_ALONG_CELL_Y if spindle_axis == "y" else TOOL_Z_ALONG_CELL_Y


@dataclass(frozen=True)
class DoorSize:
    """Nominal door dimensions, mm, and the arris on the edges around the hinge face.

    ``arris_mm`` is the chamfer's leg or the rounding's radius (0: sharp edges); ``arris_profile`` says which.
    """

    width_mm: float = 900.0
    thickness_mm: float = 50.0
    height_mm: float = 2100.0
    arris_mm: float = 0.0
    arris_profile: ArrisProfile = "chamfer"

    def __post_init__(self) -> None:
        for name in ("width_mm", "thickness_mm", "height_mm"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise ValueError(f"door {name} must be a positive number of millimetres, got {v!r}")
        if not (0 <= self.arris_mm < self.thickness_mm / 2):
            raise ValueError(f"door arris_mm must be in [0, thickness/2), got {self.arris_mm!r}")
        if self.arris_profile not in get_args(ArrisProfile):
            raise ValueError(f"door arris_profile must be 'chamfer' or 'round', got {self.arris_profile!r}")
