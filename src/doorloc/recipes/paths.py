"""Hinge pocket tool paths in the door frame: the 6-point and the 9-point path (thesis figure 3.24).

Both paths are for the **tool centre point** at the bottom of the pocket (door-frame ``Y = depth_mm``)
and run counter-clockwise as seen from the camera (X right, Z up; climb milling for a right-hand
spindle). A path is ``APP`` (above the plunge point, ``clearance_mm`` in front of the face, ``Y < 0``),
the pocket points ``P1..Pn``, and ``RET`` (in front of the last point). docs/hinge_paths.md draws them.

With the pocket ``[x, x+w] x [z, z+L]``, tool radius ``rt`` and corner radius ``r`` (``rt <= r``):

- **6 points** ("simple fillet", figure 3.24b): P1 mid bottom edge, P2..P5 the corners of the
  tool-centre rectangle inset by ``rt`` (bottom-right, top-right, top-left, bottom-left), P6 = P1.
  The tool's own radius rounds the corners: exact when ``tool_diameter == 2 * corner_radius``,
  otherwise the corners are cut with radius ``rt`` (squarer than drawn).
- **9 points** (figure 3.24a): P1..P8 the tangent points of the four corner arcs of the tool-centre
  path (radius ``r - rt``), two per corner, starting at the bottom edge's left end; P9 = P1.
  Each arc is cut as its chord, leaving at most ``(r - rt) * (1 - cos 45 deg)`` of material.

Force-displacement corrections (one per pocket point) are added here, in the door frame, before any
pose moves the points into the cell (thesis eq. 3.46, the PC term).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from doorloc.recipes.models import DoorRecipe, Hinge

__all__ = ["PathPoint", "PointKind", "hinge_path", "recipe_path", "pocket_points_xz", "DEFAULT_CLEARANCE_MM"]

#: how far in front of the hinge face (door Y < 0) the approach and retract points lie, mm
DEFAULT_CLEARANCE_MM = 10.0

#: ``approach``/``retract`` in the air; ``corner`` points are reached with ``fine`` (the tool stops);
#: ``edge`` points are passed through (``z0``)
PointKind = Literal["approach", "corner", "edge", "retract"]


@dataclass(frozen=True)
class PathPoint:
    """One tool-centre point of a hinge path, door frame, mm.

    Attributes
    ----------
    name : str
        RAPID-safe name, ``H<hinge>_APP``, ``H<hinge>_P<k>`` or ``H<hinge>_RET``.
    point_door : tuple of float
        ``(px, py, pz)`` in the door frame (``py`` = depth into the face), correction included.
    kind : PointKind
    hinge : int
        1-based hinge number in the recipe.
    """

    name: str
    point_door: tuple[float, float, float]
    kind: PointKind
    hinge: int


def pocket_points_xz(hinge: Hinge, tool_diameter_mm: float) -> tuple[np.ndarray, list[PointKind]]:
    """The pocket points P1..Pn of one hinge in the door's X-Z plane.

    Returns
    -------
    xz : ndarray, shape (n, 2)
        ``(px, pz)`` of P1..Pn, mm; n = ``hinge.path_points``.
    kinds : list of PointKind
        ``corner`` or ``edge`` per point.
    """
    rt = tool_diameter_mm / 2.0
    x0, x1 = hinge.x_mm, hinge.x_mm + hinge.width_mm
    z0, z1 = hinge.z_mm, hinge.z_mm + hinge.length_mm
    xa, xb, za, zb = x0 + rt, x1 - rt, z0 + rt, z1 - rt  # tool-centre rectangle
    if hinge.path_points == 6:
        xm = 0.5 * (xa + xb)
        xz = [(xm, za), (xb, za), (xb, zb), (xa, zb), (xa, za), (xm, za)]
        kinds: list[PointKind] = ["edge", "corner", "corner", "corner", "corner", "edge"]
    else:
        r = max(hinge.corner_radius_mm, rt)
        cl, cr, cb, ct = x0 + r, x1 - r, z0 + r, z1 - r  # arc centres' coordinates
        xz = [(cl, za), (cr, za), (xb, cb), (xb, ct), (cr, zb), (cl, zb), (xa, ct), (xa, cb), (cl, za)]
        kinds = ["corner"] * 9
    return np.asarray(xz, dtype=float), kinds


def hinge_path(
    hinge: Hinge,
    tool_diameter_mm: float,
    hinge_number: int = 1,
    *,
    clearance_mm: float = DEFAULT_CLEARANCE_MM,
) -> list[PathPoint]:
    """Approach, pocket points (with their force-displacement corrections) and retract of one hinge.

    Examples
    --------
    >>> h = Hinge(z_mm=200, length_mm=100, width_mm=30, x_mm=10, depth_mm=3, corner_radius_mm=8)
    >>> [p.name for p in hinge_path(h, 16.0, 2)][:3]
    ['H2_APP', 'H2_P1', 'H2_P2']
    >>> hinge_path(h, 16.0)[1].point_door
    (25.0, 3.0, 208.0)
    """
    xz, kinds = pocket_points_xz(hinge, tool_diameter_mm)
    pts = np.column_stack([xz[:, 0], np.full(len(xz), hinge.depth_mm), xz[:, 1]])
    if hinge.corrections:
        pts = pts + np.array([[c.dx_mm, c.dy_mm, c.dz_mm] for c in hinge.corrections])
    h = f"H{hinge_number}"
    out = [PathPoint(f"{h}_APP", (float(xz[0, 0]), -clearance_mm, float(xz[0, 1])), "approach", hinge_number)]
    out += [
        PathPoint(f"{h}_P{k + 1}", (float(p[0]), float(p[1]), float(p[2])), kinds[k], hinge_number)
        for k, p in enumerate(pts)
    ]
    out.append(
        PathPoint(f"{h}_RET", (float(pts[-1, 0]), -clearance_mm, float(pts[-1, 2])), "retract", hinge_number)
    )
    return out


def recipe_path(recipe: DoorRecipe, *, clearance_mm: float = DEFAULT_CLEARANCE_MM) -> list[PathPoint]:
    """All hinges' paths of a recipe, in recipe order, door frame."""
    out: list[PathPoint] = []
    for i, h in enumerate(recipe.hinges):
        out += hinge_path(h, recipe.tool_diameter_mm, i + 1, clearance_mm=clearance_mm)
    return out
