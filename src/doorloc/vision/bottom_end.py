"""Which of a far face's two readings the door's bottom end shows (:func:`bottom_end_level`,
:func:`settled_by_bottom_end`).

A far face whose band looks like the background or like the hinge face leaves one step beside the far arris,
which reads two ways a band's width apart (:attr:`FarFaceFit.other_reading_px`): the arris, with the far
face beyond it as dark as the background (the thicker reading), or the far face's back edge, with the far
face as bright as the hinge face (the thinner reading). Along the door's height the two make the same image.
At its bottom end they do not: the far face's bottom edge runs away from the camera, towards the view's
vanishing point, so under the thinner reading it cuts the bright region's corner beside the far arris. The
triangle between the thinner reading's arris and the step, at the bottom end, under the far face's bottom
edge, shows what lies below the door under the thinner reading and the hinge face under the thicker one.
On bench_surfaces' thin and hard sets (16 doors, valid and wrong, the far face as bright as the hinge face
or as dark as the background) its level lay within 0.05 of one side's, the right one, on every door whose
triangle held more than 6 pixels (`bench_surfaces.py --sets thin --n 40 --seed 2611 --wrong-thickness -2.5`,
doors 13 and 32: 0.95 and 1.02; the same set's valid doors 3, 4, 20, 27: -0.05 to 0.01).

Pixels: ``(u, v)``, v down; levels in the plane's units and, for the contrast, 8-bit grey levels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from doorloc.calib.camera import PosedCamera
from doorloc.pose import DoorPose, door_to_cell

__all__ = [
    "BORDER_PX",
    "DECISIVE_LEVEL",
    "MIN_PIXELS",
    "BottomEndLevel",
    "DoorInView",
    "bottom_end_level",
    "settled_by_bottom_end",
]

#: pixels left out along every border of the regions read (the blur, the lines' placement)
BORDER_PX = 2
#: the fewest pixels the triangle (its borders left out) needs to tell the readings apart
MIN_PIXELS = 30
#: the triangle's level (0 the hinge face's, 1 the background's below the door) settles the readings
#: where it lies within this of one side's
DECISIVE_LEVEL = 0.25
#: the background is read below the door's bottom end to at most this depth, px (a local level)
BELOW_DEPTH_PX = 24


@dataclass(frozen=True)
class DoorInView:
    """Where the door stands for the camera: the camera in the cell, the hinge face's depth ``face_y`` (cell
    Y, mm), the door's pose and its width (mm), SPEC section 1."""

    camera: PosedCamera
    face_y: float
    pose: DoorPose
    width_mm: float

    def project(self, points_door: np.ndarray) -> np.ndarray:
        """Door-frame points ``(N, 3)``, mm -> pixels ``(N, 2)``."""
        return self.camera.project_cell(door_to_cell(points_door, self.pose, self.face_y))


@dataclass(frozen=True)
class BottomEndLevel:
    """The triangle's level between the hinge face's (0) and the background's below the door (1), its pixel
    count, and the contrast between those two, 8-bit grey levels."""

    level: float
    pixels: int
    contrast: float

    def reading(self, min_contrast: float) -> str | None:
        """``"thicker"`` (the hinge face reaches the bottom end there), ``"thinner"`` (the far face's bottom
        edge cuts the corner), or None where the triangle cannot tell (too small, too little contrast, or a
        level between the two sides)."""
        if self.pixels < MIN_PIXELS or not self.contrast >= min_contrast:
            return None
        if self.level <= DECISIVE_LEVEL:
            return "thicker"
        if self.level >= 1.0 - DECISIVE_LEVEL:
            return "thinner"
        return None


def _mask(shape: tuple[int, int], polygon: np.ndarray, border_px: int) -> np.ndarray:
    """The pixels inside ``polygon`` (px, sub-pixel corners) at least ``border_px`` from its border."""
    m = np.zeros(shape, np.uint8)
    cv2.fillPoly(m, [np.round(polygon * 16).astype(np.int32)], 1, lineType=cv2.LINE_8, shift=4)
    if not border_px:
        return m.astype(bool)
    return np.asarray(cv2.erode(m, np.ones((2 * border_px + 1, 2 * border_px + 1), np.uint8)), dtype=bool)


def bottom_end_level(
    plane: np.ndarray, scale_to_8bit: float, door: DoorInView, thicknesses_mm: tuple[float, float]
) -> BottomEndLevel | None:
    """The level, at the door's bottom end, of the triangle that tells a far face's two readings apart.

    ``thicknesses_mm``: the thinner and the thicker reading of ``door``'s thickness. The triangle's corners
    are the two readings' far arrises on the bottom end (the thicker one's is the step) and the thinner
    reading's far face's back edge on the bottom end (sharp edges: a door with arrises is read beside a
    strip, not here). The hinge face's level is read beside it, inwards by the readings' distance, the
    background's below the bottom end. None where a region leaves the image or holds no pixel, the hinge
    face's runs past the reference arris, or the camera does not look down on the bottom end (the far face's
    bottom edge would not cut the corner).
    """
    t_thin, t_thick = thicknesses_mm
    door_pts = np.array(
        [
            [t_thin, 0.0, 0.0],
            [t_thick, 0.0, 0.0],
            [t_thin, door.width_mm, 0.0],
            [0.0, 0.0, 0.0],
            [t_thin, 0.0, 50.0],
        ]
    )
    uv = door.project(door_pts)
    if not np.all(np.isfinite(uv)):
        return None
    p1, p2, p3, ref, up = uv
    step, up = p2 - p1, up - p1
    # the hinge face's region: the triangle moved inwards by the readings' distance, clear of the reference
    # arris
    if np.hypot(*(p1 - step - ref)) <= BORDER_PX + 1 or float(np.dot(p1 - step - ref, step)) <= 0:
        return None
    if p3[1] >= p1[1]:  # the far face's bottom edge runs down the image: a camera below the bottom end
        return None
    below = np.array([0.0, BORDER_PX])
    depth = np.array([0.0, BELOW_DEPTH_PX])
    regions = {
        "triangle": np.array([p1, p2, p3]),
        "hinge": np.array([p1, p2, p3]) - step,
        "below": np.array([p1 + below, p2 + below, p2 + depth, p1 + depth]),
    }
    h, w = plane.shape[:2]
    corners = np.concatenate(list(regions.values()))
    lo, hi = np.floor(corners.min(axis=0)).astype(int) - 1, np.ceil(corners.max(axis=0)).astype(int) + 2
    if lo[0] < 0 or lo[1] < 0 or hi[0] > w or hi[1] > h:
        return None
    crop = np.asarray(plane[lo[1] : hi[1], lo[0] : hi[0]], dtype=np.float64)
    means, counts = {}, {}
    # each region stays on the hinge face's side of its arris line, up the door (the thicker reading's step
    # for the triangle, the thinner reading's arris for the hinge face), whatever the far face's width
    rows, cols = np.mgrid[lo[1] : hi[1], lo[0] : hi[0]]
    for name, poly in regions.items():
        m = _mask(crop.shape, poly - lo, 0 if name == "below" else BORDER_PX)
        if name != "below":
            at = p2 if name == "triangle" else p1
            across = (cols - at[0]) * up[1] - (rows - at[1]) * up[0]
            inward = (ref[0] - at[0]) * up[1] - (ref[1] - at[1]) * up[0]
            m &= across * np.sign(inward) >= BORDER_PX * float(np.hypot(*up))
        counts[name] = int(m.sum())
        means[name] = float(crop[m].mean()) if counts[name] else math.nan
    if not (counts["hinge"] and counts["below"]):
        return None
    contrast = (means["below"] - means["hinge"]) * scale_to_8bit
    level = (means["triangle"] - means["hinge"]) / (means["below"] - means["hinge"]) if contrast else math.nan
    return BottomEndLevel(float(level), counts["triangle"], abs(contrast))


def settled_by_bottom_end(
    plane: np.ndarray,
    scale_to_8bit: float,
    door: DoorInView,
    fitted_mm: float,
    other_mm: float,
    min_contrast: float,
) -> tuple[bool, BottomEndLevel | None]:
    """Whether the bottom end shows the fitted reading ``fitted_mm`` of the thickness and not the far face's
    other reading ``other_mm`` (:func:`bottom_end_level`; ``min_contrast`` in 8-bit grey levels), and the
    level read (None where it could not be)."""
    pair = (min(fitted_mm, other_mm), max(fitted_mm, other_mm))
    seen = bottom_end_level(plane, scale_to_8bit, door, pair)
    if seen is None:
        return False, None
    fitted_is = "thicker" if fitted_mm >= other_mm else "thinner"
    return seen.reading(min_contrast) == fitted_is, seen
