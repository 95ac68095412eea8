"""Why the coarse stage found no door: the reasons its refusals give, read off the image.

Where no reference arris, far arris or bottom end was found, the stage says why as a person can act on it:
a calibration pattern in view (:func:`looks_like_pattern_here`), a hinge face on the other side of the
background's brightness than the cell says, one the lighting hides against it or one without an edge to be
found (:func:`face_refusal`), an edge or a face too faint for the noise (:func:`faint_edge`,
:func:`faint_face`), or no door (:func:`no_door_reason`).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import uniform_filter1d

from doorloc.cell import Cell
from doorloc.vision import quality as q
from doorloc.vision.coarse import coarse_edges, line_through_steps
from doorloc.vision.config import LocateConfig
from doorloc.vision.gate import PATTERN
from doorloc.vision.lines import ImageLine
from doorloc.vision.region import Band, EdgeLayout, SearchRegion
from doorloc.vision.sampling import median_with_error, oriented

__all__ = [
    "FAINT_EDGE_AVERAGE_PX",
    "EDGELESS_FACE_SIGMAS",
    "REVERSED_BRIGHTNESS",
    "edgeless_face",
    "face_minus_background",
    "face_refusal",
    "faint_edge",
    "faint_face",
    "indistinct_face",
    "looks_like_pattern_here",
    "no_door_reason",
]


def looks_like_pattern_here(plane, s8: float, band: Band, axis, cfg: LocateConfig) -> bool:
    """Whether ``band`` (its rows along ``axis``) holds a regular pattern such as a calibration board."""
    P = oriented(plane, axis)
    rows = P[band.lo.min() : band.hi.max() + 1, band.scan[::8]].T.astype(np.float32) * s8
    return q.looks_like_pattern(rows, 4 * cfg.min_contrast)


#: the reason given where no edge of the cell's polarity was found and the hinge face looks the other way
#: (by ``locate.door_brighter``)
REVERSED_BRIGHTNESS = {
    True: "the hinge face looks darker than the background here, and the cell says the door is the brighter "
    "(locate.door_brighter: true); if this cell's doors are darker, set locate.door_brighter: false in the "
    "cell file, else check the lighting",
    False: "the hinge face looks brighter than the background here, and the cell says the door is the darker "
    "(locate.door_brighter: false); if this cell's doors are brighter, set locate.door_brighter: true in the "
    "cell file, else check the lighting",
}


def face_minus_background(plane, s8: float, region: SearchRegion, cell: Cell) -> tuple[float, float] | None:
    """The hinge face's grey level less the background's (0-255 scale), read where each must lie whatever
    the door's placement in the envelope, and that difference's standard error from the pixels' spread;
    None where no point is surely on the face.

    Read on the hinge face's centre line (half the thickness in from the reference arris) and beyond the
    reference arris by the search region's reach, 20-80 mm up from the bottom end: medians of 13 pixels each
    (the door lies in the cell's envelope: on a door no thicker than twice the envelope's x, plus its yaw's
    reach, no point is surely on the face, and nothing is said), each with its error from its pixels' spread
    (:func:`~doorloc.vision.sampling.median_with_error`).
    """
    zs = np.linspace(20.0, 80.0, 13)
    x_face, x_back = 0.5 * region.door.thickness_mm, -(region.x_range_mm + 8.0)
    if x_face <= cell.envelope.x_mm + 3.0:  # (+3 mm: the envelope's yaw over 80 mm)
        return None
    h, w = plane.shape
    levels, errors = [], []
    for x in (x_face, x_back):
        uv = np.round(region.image_points(np.stack([np.full_like(zs, x), zs], axis=1))).astype(int)
        inside = (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
        if inside.sum() < 7:
            return None
        level, error = median_with_error(plane[uv[inside, 1], uv[inside, 0]].astype(float) * s8)
        levels.append(level)
        errors.append(error)
    return levels[0] - levels[1], math.hypot(*errors)


def face_refusal(
    code: str, plane, s8: float, region: SearchRegion, cell: Cell, cfg: LocateConfig
) -> q.Refusal | None:
    """A better reason for the coarse stage's refusal ``code`` (``no_door`` or ``edge_missing``) read off the
    hinge face's level against the background's (:func:`face_minus_background`, read once), or None: a face
    clearly on the other side of the background's brightness than the cell's ``locate.door_brighter`` says
    (:data:`REVERSED_BRIGHTNESS`, either code), or, where no door edge was found, a face within the contrast
    threshold of the background (:func:`indistinct_face`) or one that stands out from it without an edge to
    be found (:func:`edgeless_face`)."""
    if code not in ("no_door", "edge_missing"):
        return None
    read = face_minus_background(plane, s8, region, cell)
    if read is None:
        return None
    d, d_sigma = read
    if abs(d) >= cfg.min_contrast and (d < 0) == cfg.door_brighter:
        return q.Refusal(code, REVERSED_BRIGHTNESS[cfg.door_brighter])
    if code == "no_door" and abs(d) < cfg.min_contrast:
        return q.Refusal(code, indistinct_face(d, cfg))
    if code == "no_door" and abs(d) > EDGELESS_FACE_SIGMAS * d_sigma:
        # (an image of noise alone reads a difference, not a face: uniform noise 36 +- 32 grey levels; the
        # face of hard set seed 13's image 46, below, 9.0 +- 0.7)
        return q.Refusal(code, edgeless_face(d, cfg))
    return None


def indistinct_face(d: float, cfg: LocateConfig) -> str:
    """The reason, in the operator's words, where no door edge was found and the image where the hinge face must
    lie is ``d`` grey levels from the background behind the door, within the contrast threshold (an empty
    fixture or a door the lighting hides: both are said).

    Seen on ``bench_surfaces.py --sets combined --seed 400``, images 30 and 34: doors 4 grey levels darker
    than their background in a cell whose doors are the brighter, refused "no door edge was found ...
    check that a door lies in the fixture", which sent the operator to a fixture that held a door.
    """
    level = (
        "at the level of the background behind the door"
        if abs(d) < 2.0  # (a median of 13 pixels wanders by a grey level or so on a noisy background)
        else f"only {abs(d):.0f} grey levels {'darker' if d < 0 else 'brighter'} than the background behind the door"
    )
    return (
        f"no door edge was found in the search region, and where the hinge face should be the image is {level} "
        f"(locate.min_contrast is {cfg.min_contrast:g}): if a door lies in the fixture, the lighting or the "
        "background hides it; improve them. Else place a door, and check that the camera has not moved"
    )


#: how many of its standard errors the face's difference from the background must reach for
#: :func:`edgeless_face` to speak of a face
EDGELESS_FACE_SIGMAS = 4.0


def edgeless_face(d: float, cfg: LocateConfig) -> str:
    """The reason, in the operator's words, where no door edge was found though the image where the hinge face
    must lie stands ``d`` grey levels out from the background behind the door, as the cell says a door does:
    a door whose edge lies outside the search region (out of its place, or the camera moved), one whose edge
    is fainter than its face's mean step or hidden in the texture beside it, or an empty fixture whose
    background is shaded (all are said).

    Seen on ``bench_surfaces.py --sets hard`` (set seed 13, image 46): a face 9 grey levels above its
    background on average, whose step at the reference arris a gradient and vignetting bring to 3-6 grey
    levels among grain stripes as strong, refused "no door edge was found ... check that a door lies in the
    fixture", which sends the operator to a fixture that holds a door. An image upside down (the parity
    set's ``derived/flip_ud``) reads 168 grey levels: there the edge is out of place, not faint.
    """
    side = "brighter" if d > 0 else "darker"
    return (
        f"no door edge was found in the search region, though where the hinge face should be the image is "
        f"{abs(d):.0f} grey levels {side} than the background behind the door: either the door's edge lies "
        "outside the search region (check that the door lies against the fixture's stops and that the camera "
        f"has not moved), or it stands out less than locate.min_contrast ({cfg.min_contrast:g} grey levels) "
        "from the background or the texture beside it (improve the lighting or the background behind the "
        "door); if the fixture is empty, place a door"
    )


def no_door_reason(plane, band: Band, layout: EdgeLayout, cfg: LocateConfig, s8: float) -> q.Refusal:
    if looks_like_pattern_here(plane, s8, band, layout.axis, cfg):
        return PATTERN
    faint = faint_edge(plane, band, layout, cfg.min_contrast / s8)
    if faint is not None:
        steps, found, lines = faint
        return q.Refusal(
            "low_contrast",
            f"a faint edge lies where the door's reference arris should be ({steps * s8:.1f} grey levels "
            f"averaged along it, on {found} of {lines} scan lines; locate.min_contrast is "
            f"{cfg.min_contrast:g}): too faint against the image noise to measure; improve the lighting or "
            "the background behind the door",
        )
    return q.Refusal(
        "no_door",
        "no door edge was found in the search region; check that a door lies in the fixture, "
        "that the lighting is on and that the camera has not moved",
    )


def faint_face(
    plane,
    s8: float,
    band: Band,
    layout: EdgeLayout,
    ref_line: ImageLine,
    xdir: int,
    strip_px: float,
    cfg: LocateConfig,
) -> q.Refusal | None:
    """``low_contrast`` where the hinge face beside the found reference arris (``ref_line`` in ``band``,
    ``xdir`` the along-direction of door +X) is less than the contrast threshold brighter than the background outside it (darker, for a dark door), else
    None: the reason a far arris or a bottom end was not found is then the lighting, not the door.

    Seen on bench_surfaces --sets combined --seed 500, image 8: a hinge face 1 grey level from its
    background, whose arrises show only as a rounding's faint lines, was refused "the far arris was not found
    ... check that the door is 30.83 mm thick", which sent the operator to the door. The levels are medians
    over 10 px on each side of the line, clear of it by 4 px and twice the arris strip's width
    (``strip_px``). Where the coarse line is not the reference arris (image 24: a face darker than the
    background in a shadow band, whose far arris took the reference search) the levels read another edge's
    sides and the old reason stays.
    """
    thr = cfg.min_contrast / s8
    P = oriented(plane, layout.axis)
    n_along = P.shape[0]
    at = np.round(ref_line.at(band.scan)).astype(int)[:, None]
    # (clear of the arris strip on both sides by its width twice: the coarse line may hold either of its
    # borders, and a rounding's shading reaches beyond them)
    offs = np.arange(4, 14)[None, :] + 2 * int(math.ceil(strip_px))
    inside = np.clip(at + xdir * offs, 0, n_along - 1)
    outside = np.clip(at - xdir * offs, 0, n_along - 1)
    scan = band.scan[:, None]
    face = float(np.median(P[inside, scan]))
    background = float(np.median(P[outside, scan]))
    contrast = (face - background) * xdir * layout.polarity  # positive: the door as bright as the cell says
    if contrast >= thr:
        return None
    return q.Refusal(
        "low_contrast",
        f"the hinge face beside the reference arris is {contrast * s8:.1f} grey levels from the background "
        f"(locate.min_contrast is {cfg.min_contrast:g}): the door's other edges cannot be told from the "
        "background; improve the lighting or the background behind the door",
    )


#: pixels (each side) along the edge over which :func:`faint_edge` averages each scan line
FAINT_EDGE_AVERAGE_PX = 8


def faint_edge(plane, band: Band, layout: EdgeLayout, thr: float) -> tuple[float, int, int] | None:
    """A door edge too faint for the coarse search: the steps of ``band`` averaged over the
    ``2 FAINT_EDGE_AVERAGE_PX + 1`` px along the edge around each scan line (noise averages down, the
    edge does not; a door within the envelope's 2 deg drifts 0.6 px over them) make a line of steps of
    at least half the threshold ``thr`` through 60 % of the scan lines.

    Only for the refusal's reason: doors 5.3 and 3.6 grey levels above their background under ~3 grey
    levels of noise, whose strongest single-line steps (noise peaks of 7-10) put only 17 and 11 of 56
    lines on one line, were refused as no door (bench_surfaces --n 40 --seed 500, hard_023 and
    thin_003; averaged, 54 and 38 of 56). Returns the averaged steps' median on the line (plane
    units), the line's count of lines and the band's; None where no such line is.
    """
    P = oriented(plane, layout.axis)
    k = FAINT_EDGE_AVERAGE_PX
    r0, r1 = int(band.lo.min()), int(band.hi.max()) + 1
    c0, c1 = max(int(band.scan.min()) - k, 0), min(int(band.scan.max()) + k + 1, P.shape[1])
    sub = uniform_filter1d(np.asarray(P[r0:r1, c0:c1], np.float32), 2 * k + 1, axis=1, mode="nearest")
    along, strength = coarse_edges(
        sub, "col", band.scan - c0, band.lo - r0, band.hi - r0, layout.polarity, half=2, stride=2
    )
    line = line_through_steps(band.scan, along, strength, 0.5 * thr, 10, 0.6)
    if line is None:
        return None
    on = strength[np.isfinite(along) & (strength >= 0.5 * thr)][line.inliers]
    return float(np.median(on)), int(line.inliers.sum()), len(band.scan)
