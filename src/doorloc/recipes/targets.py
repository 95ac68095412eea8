"""Robot targets: the recipe's door-frame path points moved into the cell by the measured door pose.

Positions go through :func:`doorloc.pose.door_to_cell` (the one implementation of the thesis's
eq. 3.46-3.50); force-displacement corrections are already in the door-frame points
(:mod:`doorloc.recipes.paths`).

**Tool orientation.** A target's ``quat`` is the orientation of the *tool frame* in the cell frame,
unit, scalar first ``[q1, q2, q3, q4]`` with ``q1 >= 0`` (ABB's ``orient``). For a door at yaw 0 the
tool frame is parallel to the cell frame and the spindle axis is the tool frame's **+Y** (pointing
into the hinge face); the door's yaw turns the tool with the door, a rotation by ``-yaw`` about +Y::

    quat = [cos(yaw/2), 0, -sin(yaw/2), 0]

so only q1 and q3 change, as the thesis says (section 3.8, figure 3.27). This needs the tool frame's
+Y along the spindle; the RAPID module's default tooldata (:class:`doorloc.recipes.rapid.RobotSetup`)
defines it so (``tframe.rot`` turns flange +Z into tool +Y). A tool frame with the spindle along its
+Z (ABB's habit) would make all four components change with the yaw, which the thesis rules out; a
cell that wants it passes ``base_orientation=TOOL_Z_ALONG_CELL_Y`` (the quaternion becomes
``q_yaw * base``).
"""

from __future__ import annotations

import numpy as np
from pydantic import BaseModel, ConfigDict
from scipy.spatial.transform import Rotation

from doorloc.domain import TOOL_Y_ALONG_CELL_Y, TOOL_Z_ALONG_CELL_Y, Quat
from doorloc.pose import DoorPose, door_to_cell
from doorloc.recipes.models import DoorRecipe
from doorloc.recipes.paths import DEFAULT_CLEARANCE_MM, PathPoint, PointKind, recipe_path

__all__ = [
    "Target",
    "tool_quaternion",
    "targets_for_pose",
    "targets_from_path",
    "TOOL_Y_ALONG_CELL_Y",
    "TOOL_Z_ALONG_CELL_Y",
]


class Target(BaseModel):
    """One robot target in the cell frame (SPEC section 6).

    Attributes
    ----------
    name : str
        RAPID-safe name, e.g. ``H1_P3``.
    x_mm, y_mm, z_mm : float
        Tool centre point, cell frame, mm.
    quat : tuple of 4 floats
        Tool orientation, unit quaternion, scalar first, ``q1 >= 0``.
    hinge : int
        1-based hinge number in the recipe.
    kind : str
        ``approach``, ``corner`` (stop with ``fine``), ``edge`` (pass with ``z0``) or ``retract``.
    """

    model_config = ConfigDict(frozen=True)

    name: str
    x_mm: float
    y_mm: float
    z_mm: float
    quat: tuple[float, float, float, float]
    hinge: int
    kind: PointKind = "corner"


def tool_quaternion(yaw_deg: float, base_orientation: Quat = TOOL_Y_ALONG_CELL_Y) -> Quat:
    """Tool orientation for a door at ``yaw_deg``: ``[cos(yaw/2), 0, -sin(yaw/2), 0] * base_orientation``.

    Unit, scalar first, ``q1 >= 0``. With the default base only q1 and q3 are non-constant.

    Examples
    --------
    >>> [round(q, 7) for q in tool_quaternion(2.0)]
    [0.9998477, 0.0, -0.0174524, 0.0]
    """
    turn = Rotation.from_euler("y", -yaw_deg, degrees=True)
    if base_orientation != TOOL_Y_ALONG_CELL_Y:
        turn = turn * Rotation.from_quat(base_orientation, scalar_first=True)
    w, x, y, z = turn.as_quat(canonical=True, scalar_first=True).tolist()
    return (w, x, y, z)


def targets_from_path(
    path: list[PathPoint], pose: DoorPose, face_y_mm: float, *, base_orientation: Quat = TOOL_Y_ALONG_CELL_Y
) -> list[Target]:
    """Move door-frame path points into the cell frame (``door_to_cell``) and attach the tool orientation."""
    if not path:
        return []
    cell = door_to_cell(np.array([p.point_door for p in path], dtype=float), pose, face_y_mm)
    q = tool_quaternion(pose.yaw_deg, base_orientation)
    return [
        Target(
            name=p.name,
            x_mm=float(c[0]),
            y_mm=float(c[1]),
            z_mm=float(c[2]),
            quat=q,
            hinge=p.hinge,
            kind=p.kind,
        )
        for p, c in zip(path, cell, strict=True)
    ]


def targets_for_pose(
    recipe: DoorRecipe,
    pose: DoorPose,
    face_y_mm: float,
    *,
    clearance_mm: float = DEFAULT_CLEARANCE_MM,
    base_orientation: Quat = TOOL_Y_ALONG_CELL_Y,
) -> list[Target]:
    """All hinge targets of a recipe for a door measured at ``pose``.

    Parameters
    ----------
    recipe : DoorRecipe
    pose : DoorPose
        Measured pose (x_mm, z_mm, yaw_deg) of the door's reference corner.
    face_y_mm : float
        Hinge-face depth for this door, cell Y, mm: ``cell.face_y(recipe.door_size())``.
    clearance_mm : float
        Distance of approach/retract points in front of the face, mm.
    base_orientation : 4 floats
        Tool orientation at yaw 0 (scalar first); default: tool axes = cell axes, spindle = tool +Y.

    Returns
    -------
    list of Target
        Per hinge: ``APP``, ``P1..Pn``, ``RET``; cell frame, mm.
    """
    return targets_from_path(
        recipe_path(recipe, clearance_mm=clearance_mm), pose, face_y_mm, base_orientation=base_orientation
    )
