"""Door pose and the one rigid transform from the door frame to the cell frame.

Frames (shared/SPEC.md section 1), all lengths in millimetres:

- **cell frame**: origin at the nominal reference corner; +X across the door thickness (from the
  reference face into the door), +Y normal to the hinge-edge face pointing into the door (away from
  the camera), +Z up the door height.
- **door frame**: the same axes for a door lying exactly at its nominal place with its hinge face at
  ``Y = 0``; a door point has nominal coordinates ``(px, py, pz)`` with ``px in [0, T]``,
  ``py in [0, W]``, ``pz in [0, H]``.

The fixture leaves three degrees of freedom (thesis section 3.8): a shift ``x_mm`` along X, a shift
``z_mm`` along Z and an in-plane rotation ``yaw_deg`` of the hinge face about +Y::

    X = x + px*cos(yaw) - pz*sin(yaw)
    Y = py + face_y
    Z = z + px*sin(yaw) + pz*cos(yaw)

which is the thesis's eq. 3.46-3.50 with beta = alpha + yaw, and in 3-D a rotation by -yaw about +Y.
``face_y`` is the depth of the hinge face for this door's width (:meth:`doorloc.cell.Fixture.face_y`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = [
    "DoorPose",
    "door_to_cell",
    "cell_to_door",
    "direction_cell",
    "directions_across",
    "directions_apart_deg",
    "yaw_rotation_matrix",
]


@dataclass(frozen=True)
class DoorPose:
    """The 3 DOF the fixture leaves free.

    Attributes
    ----------
    x_mm : float
        Shift of the reference corner along cell +X (across the thickness), mm.
    z_mm : float
        Shift of the reference corner along cell +Z (up the door), mm.
    yaw_deg : float
        Rotation of the door in the hinge-face plane, degrees; positive turns door +X towards +Z.
    """

    x_mm: float = 0.0
    z_mm: float = 0.0
    yaw_deg: float = 0.0

    @property
    def yaw_rad(self) -> float:
        return math.radians(self.yaw_deg)


def yaw_rotation_matrix(yaw_deg: float) -> np.ndarray:
    """3x3 rotation taking door-frame directions to cell-frame directions.

    Shape ``(3, 3)``. It is a rotation by ``-yaw`` about +Y: door +X goes to
    ``(cos yaw, 0, sin yaw)`` and door +Z to ``(-sin yaw, 0, cos yaw)``.

    Examples
    --------
    >>> import numpy as np
    >>> R = yaw_rotation_matrix(90.0)
    >>> np.round(R @ [1.0, 0.0, 0.0], 12).tolist()
    [0.0, 0.0, 1.0]
    """
    return Rotation.from_euler("y", -yaw_deg, degrees=True).as_matrix()


def direction_cell(azimuth_deg: float, elevation_deg: float) -> np.ndarray:
    """The unit vector, cell frame, at ``azimuth_deg`` from -Y (out of the hinge face, towards the camera's
    side) turning towards +X, raised by ``elevation_deg`` towards +Z: ``(cos el sin az, -cos el cos az,
    sin el)``. The one convention for a light's direction (the renderer's and the cell's
    ``locate.light_direction_deg``).

    >>> [round(float(v), 3) for v in direction_cell(90.0, 0.0)]  # from +X
    [1.0, -0.0, 0.0]
    """
    az, el = math.radians(azimuth_deg), math.radians(elevation_deg)
    return np.array([math.cos(el) * math.sin(az), -math.cos(el) * math.cos(az), math.sin(el)])


def directions_across(direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors square to the unit vector ``direction`` (cell frame) and to each other: ``side``,
    horizontal (``direction x +Z``; +X for a direction straight up or down), and ``up`` (``side x
    direction``), the ways a direction is turned to say how far off it may be.

    >>> side, up = directions_across(direction_cell(0.0, 0.0))  # towards the camera's side, -Y
    >>> [round(float(v), 3) + 0.0 for v in side], [round(float(v), 3) + 0.0 for v in up]
    ([-1.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    """
    d = np.asarray(direction, float)
    side = np.cross(d, [0.0, 0.0, 1.0])
    if np.linalg.norm(side) < 1e-9:  # straight up or down: any horizontal side will do
        side = np.array([1.0, 0.0, 0.0])
    side = side / np.linalg.norm(side)
    return side, np.cross(side, d)


def directions_apart_deg(a: tuple[float, float], b: tuple[float, float]) -> float:
    """The angle between two directions given as ``[azimuth, elevation]`` (deg, as :func:`direction_cell`
    takes them), deg.

    >>> round(directions_apart_deg((-45.0, 0.0), (45.0, 0.0)), 6)
    90.0
    """
    c = float(direction_cell(*a) @ direction_cell(*b))
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


def door_to_cell(points_door: np.ndarray, pose: DoorPose, face_y: float = 0.0) -> np.ndarray:
    """Move door-frame points to the cell frame by the door pose.

    Parameters
    ----------
    points_door : array_like, shape (..., 3)
        Nominal door coordinates ``(px, py, pz)``, mm.
    pose : DoorPose
        Measured (or true) door pose.
    face_y : float
        Depth of the hinge face in the cell frame for this door, mm.

    Returns
    -------
    ndarray, shape (..., 3)
        Cell-frame coordinates, mm.

    Examples
    --------
    >>> door_to_cell([[0.0, 0.0, 100.0]], DoorPose(1.0, 2.0, 90.0), face_y=5.0).round(9).tolist()
    [[-99.0, 5.0, 2.0]]
    """
    p = np.asarray(points_door, dtype=float)
    return p @ yaw_rotation_matrix(pose.yaw_deg).T + _shift(pose, face_y)


def cell_to_door(points_cell: np.ndarray, pose: DoorPose, face_y: float = 0.0) -> np.ndarray:
    """Inverse of :func:`door_to_cell`. Shapes ``(..., 3) -> (..., 3)``, mm."""
    p = np.asarray(points_cell, dtype=float)
    return (p - _shift(pose, face_y)) @ yaw_rotation_matrix(pose.yaw_deg)


def _shift(pose: DoorPose, face_y: float) -> np.ndarray:
    """Where the door frame's origin lands in the cell frame, mm, shape (3,)."""
    return np.array([pose.x_mm, face_y, pose.z_mm])
