"""The coarse stage of locate: the three edges to a pixel or two, and the pose from them.

In the search region a strided step finder (:func:`doorloc.vision.coarse.coarse_edges`) and RANSAC find
the reference arris (the first step into the door coming from door -X), the far arris (the first clear
step beyond it, passing over the hinge face's own grain) and the bottom end between them; their lines,
mapped to the hinge-face plane, give a first pose (:class:`Coarse`), which refuses at once what is
plainly not a door in place (outside the envelope, of quite another thickness, a calibration pattern).

The stage is a coroutine: each step search is yielded as a :class:`StepQuery` and answered with
``(along, strength)`` (:func:`doorloc.vision.locate.locate_steps`), so that a batch of images can have
their searches answered together (:mod:`doorloc.vision.batched`). A refusal is raised as
:class:`~doorloc.vision.state.Refused`.
"""

from __future__ import annotations

import math
from collections.abc import Generator
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy.ndimage import uniform_filter1d

from doorloc.cell import Cell, DoorSize
from doorloc.vision import quality as q
from doorloc.vision.coarse import coarse_edges
from doorloc.vision.config import LocateConfig
from doorloc.vision.gate import PATTERN
from doorloc.vision.lines import ImageLine, fit_rectangle_edges, ransac_line
from doorloc.vision.luminance import LuminancePlane
from doorloc.vision.metric import MetricPose, pose_from_fit
from doorloc.vision.region import HUMAN, Band, EdgeLayout, SearchRegion
from doorloc.vision.sampling import oriented
from doorloc.vision.state import Refused, StageClock

__all__ = ["Coarse", "CoarseEdges", "StepQuery", "find_coarse"]

#: how far the coarse stage's thickness may lie from the recipe's before a far face's back edge is taken for
#: the far arris, and how near that reading must then come, mm (2-px coarse steps: ~0.4 mm each)
COARSE_THICKNESS_MM = 1.0
#: largest angle between the two arrises' coarse lines (image) that their 2-px steps explain, deg; beyond it
#: the far arris's line straddles its strip's two borders (:func:`_coarse_pose`)
COARSE_ARRIS_SKEW_DEG = 0.5
#: how far beyond the coarse reference line's tolerance a nearer reference arris is looked for, px: the
#: stronger step's flank (blur up to ~3 px) stays out of the 2 x 2-px step detector (:func:`_nearer_reference`)
NEARER_REFERENCE_CLEAR_PX = 13.0


@dataclass(frozen=True)
class StepQuery:
    """One coarse step search that :func:`doorloc.vision.locate.locate_steps` needs: the arguments of
    :func:`doorloc.vision.coarse.coarse_edges` (``plane`` the luminance, the rest keyword arguments)."""

    plane: np.ndarray
    kwargs: dict[str, Any]


def _coarse_line(
    plane,
    band: Band,
    layout: EdgeLayout,
    thr: float,
    min_points: int,
    min_fraction: float,
    strip_half: int | None = None,
    prefer=None,
):
    """A coarse line through the strongest steps of the layout's polarity in ``band`` (strided step finder and
    RANSAC, 3 px tolerance), or None without ``min_points`` steps or ``min_fraction`` of the scan lines on it.

    With ``strip_half`` (an arris door: :func:`_strip_half`) a missed line is looked for again with halves that
    span the strip: a strip between the face's and the background's levels splits a low-contrast step in two,
    each below the threshold in the detector's 4-px halves (arris bench seed 1539: a 1.2 mm rounding, 12 grey
    levels, refused no_door).
    """
    for half in (2, strip_half):
        if half is None:
            break
        along, strength = yield StepQuery(
            plane,
            dict(
                axis=layout.axis,
                scan=band.scan,
                lo=band.lo,
                hi=band.hi,
                polarity=layout.polarity,
                half=half,
                prefer=prefer,
                prefer_fraction=0.5,
                stride=2,
            ),
        )
        line = _line_through_steps(band.scan, along, strength, thr, min_points, min_fraction)
        if line is not None:
            return line
    return None


def _nearer_reference(
    plane,
    band: Band,
    layout: EdgeLayout,
    ref_line: ImageLine,
    xdir: int,
    thr: float,
    door: DoorSize,
    scale_mm_per_px: float,
    cfg: LocateConfig,
) -> Generator[StepQuery, tuple[np.ndarray, np.ndarray], ImageLine]:
    """The reference arris where a stronger step of its polarity lies a door's thickness further in.

    The coarse reference search takes the outermost step of at least half the strongest on each scan line. A
    far face lit far brighter than a dim hinge face (or a rounding's shading beside the far arris) makes a step
    two or three times the reference arris's: the search then took the far side for the reference arris and
    found no far arris beyond it (bench_surfaces --sets combined --seed 500, images 13 and 23: a 13 grey-level
    hinge face beside a far face of 50). Between the outer end of the band and that line, a line of steps of the
    same polarity and at least the contrast threshold is the reference arris when the door's thickness puts
    the stronger line where the far side is looked for, and the level between the two stays the door's
    (above the level outside it by half the threshold, in the door's polarity): a shadow's or a fixture's
    edge outside the door is followed by background, not by a face up to the stronger line. The search is made
    only where the level just outside the line differs from the background's at the band's outer end.
    """
    tol = 3.0
    at = ref_line.at(band.scan)
    # (clear of the stronger step's blurred flank, which the 2 x 2-px detector reads up to ~12 px away)
    clear = tol + NEARER_REFERENCE_CLEAR_PX
    if xdir > 0:
        lo, hi = band.lo, np.floor(at - clear).astype(int)
    else:
        lo, hi = np.ceil(at + clear).astype(int), band.hi
    keep = hi - lo >= 8
    if np.count_nonzero(keep) < 10:
        return ref_line
    P = oriented(plane, layout.axis)
    n_along = P.shape[0]
    door_sign = xdir * layout.polarity  # +1: the door is the brighter
    # Only where the level just outside the line is the door's, not the background's at the band's outer end,
    # can a face lie outside it (the usual frame: background all the way, and no second search)
    sub = np.flatnonzero(keep)[::4]
    offs = np.arange(5)
    just_out = np.round(at[sub] - xdir * clear).astype(int)[:, None] - xdir * offs
    far_out = (lo if xdir > 0 else hi)[sub][:, None] + xdir * offs

    def level(a: np.ndarray) -> np.ndarray:
        return P[np.clip(a, 0, n_along - 1), band.scan[sub][:, None]].mean(axis=1)

    if float(np.median((level(just_out) - level(far_out)) * door_sign)) < 0.5 * thr:
        return ref_line
    scan, lo, hi, at = band.scan[keep], lo[keep], hi[keep], at[keep]
    outer = (lo if xdir > 0 else hi).astype(float)
    along, strength = yield StepQuery(
        plane,
        dict(
            axis=layout.axis,
            scan=scan,
            lo=lo,
            hi=hi,
            polarity=layout.polarity,
            half=2,
            prefer=outer,
            prefer_fraction=0.5,
            stride=2,
        ),
    )
    line = _line_through_steps(scan, along, strength, thr, 10, 0.4 * len(band.scan) / len(scan))
    if line is None:
        return ref_line
    inner = line.at(scan)
    gap_mm = float(np.median((at - inner) * xdir)) * scale_mm_per_px
    if not (cfg.min_thickness_mm <= gap_mm <= door.thickness_mm + cfg.thickness_search_mm):
        return ref_line
    # the level between the two lines (inset by the tolerance) against the level just outside the nearer one
    step = np.empty(scan.size)
    for k, (s, a, b) in enumerate(zip(scan, inner, at, strict=True)):
        i0, i1 = sorted((int(round(a + xdir * tol)), int(round(b - xdir * tol))))
        o0, o1 = sorted((int(round(a - xdir * tol)), int(round(a - xdir * (tol + 8)))))
        if i1 - i0 < 2 or o0 < 0 or o1 >= n_along or i0 < 0 or i1 >= n_along:
            step[k] = np.nan
            continue
        inside = float(np.median(P[i0 : i1 + 1, s]))
        outside = float(np.median(P[o0 : o1 + 1, s]))
        step[k] = (inside - outside) * door_sign
    if not np.any(np.isfinite(step)) or float(np.nanmedian(step)) < 0.5 * thr:
        return ref_line
    return line


def _line_through_steps(
    scan: np.ndarray,
    along: np.ndarray,
    strength: np.ndarray,
    thr: float,
    min_points: int,
    min_fraction: float,
) -> ImageLine | None:
    """The RANSAC line (3 px tolerance) through the scan lines' steps of at least ``thr``, or None without
    ``min_points`` such steps or ``min_fraction`` of the scan lines on it."""
    strong = np.isfinite(along) & (strength >= thr)
    line = ransac_line(scan[strong], along[strong], 3.0) if strong.sum() >= min_points else None
    if line is not None and line.inliers.sum() >= min_fraction * max(len(scan), 1):
        return line
    return None


@dataclass(frozen=True)
class CoarseEdges:
    """Pixel-accurate lines of the three edges and the bands they were found in."""

    ref: ImageLine
    far: ImageLine
    bottom: ImageLine
    ref_band: Band
    far_band: Band
    bottom_band: Band


def _coarse_edges(
    plane, s8: float, region: SearchRegion, door: DoorSize, cfg: LocateConfig, bands: dict[str, Band]
) -> Generator[StepQuery, tuple[np.ndarray, np.ndarray], CoarseEdges]:
    """Find the three edges to a pixel or two in the search region (strided step finder + RANSAC).

    A coroutine: each step search is yielded as a :class:`StepQuery` (see :func:`doorloc.vision.locate.locate_steps`)."""
    thr = cfg.min_contrast / s8
    # -- search region: coarse steps ------------------------------------------------------------
    ref_lay, far_lay, bot_lay = (region.layouts[k] for k in ("reference", "far", "bottom"))
    band_ref = region.arris_band(step=4, height_mm=45.0)
    bands["reference"] = band_ref
    P = oriented(plane, ref_lay.axis)
    sub = P[band_ref.lo.min() : band_ref.hi.max() + 1 : 3, band_ref.scan[::4]]
    r = q.check_exposure(sub, cfg.min_contrast, cfg.max_saturated_fraction, s8)
    if r:
        raise Refused(r)

    # The reference arris is the first step into the door coming from -X (a visible far face can make
    # a stronger step of the same polarity further on).
    xdir = ref_lay.polarity * (1 if cfg.door_brighter else -1)  # along-direction of door +X
    sc = region.nominal_scale
    strip_half = _strip_half(door, sc) if door.arris_mm > 0 else None
    # A shadow across the door low down (a clamp, the fixture) can take the arris's step below the
    # threshold over the whole first band: look higher up before saying there is no door (bench_surfaces
    # --seed 500, hard_014: a shadow band over 30-70 mm, refused as no door). (Both bands are memoised
    # with the region, built once per cell and door.)
    first = band_ref
    ref_line = None
    for band_ref in (first, region.arris_band(step=4, height_mm=90.0, start_mm=45.0)):
        outer = (band_ref.lo if xdir > 0 else band_ref.hi).astype(float)
        ref_line = yield from _coarse_line(plane, band_ref, ref_lay, thr, 10, 0.4, strip_half, prefer=outer)
        if ref_line is not None:
            break
    if ref_line is None:
        raise Refused(_no_door_reason(plane, first, ref_lay, cfg, s8))
    ref_line = yield from _nearer_reference(plane, band_ref, ref_lay, ref_line, xdir, thr, door, sc, cfg)
    bands["reference"] = band_ref
    tol = 3.0

    ref_at = ref_line.at(band_ref.scan)
    a1 = ref_at + xdir * cfg.min_thickness_mm / sc
    a2 = ref_at + xdir * (door.thickness_mm + cfg.thickness_search_mm) / sc
    n_along = plane.shape[0] if far_lay.axis == "col" else plane.shape[1]
    band_far = Band(
        band_ref.scan,
        np.clip(np.floor(np.minimum(a1, a2)), 2, n_along - 3).astype(int),
        np.clip(np.ceil(np.maximum(a1, a2)), 2, n_along - 3).astype(int),
    )
    keep = band_far.hi - band_far.lo >= 4
    band_far = Band(band_far.scan[keep], band_far.lo[keep], band_far.hi[keep])
    bands["far"] = band_far
    # The far arris is the first clear step beyond the reference arris: the hinge face ends there, and
    # what follows (background, or the far face of a thin door shifted towards -X, brighter or darker
    # than the hinge face) does not matter. Taking the first step, not the one nearest the expected
    # thickness, measures the door that is there (a 12 mm panel where a 50 mm door was expected). A step
    # that the hinge face's own grain makes is passed over: beyond it the face's level comes back.
    P_far = oriented(plane, far_lay.axis)
    search = band_far
    for _skip in range(FACE_TEXTURE_SKIPS + 1):
        far_line = yield from _first_far_line(plane, search, far_lay, thr, tol, xdir, door, sc)
        if far_line is None:
            break
        # (only a door thinner than the recipe's needs the look: a grain line lies inside the face; an
        # arris strip's inner border, a strip's width in, is the far arris's, which the fine stage places)
        mid = search.scan[search.scan.size // 2 : search.scan.size // 2 + 1]
        thickness = float((far_line.at(mid) - ref_line.at(mid))[0]) * xdir * sc
        thinner = thickness < door.thickness_mm - 2.0 * (cfg.thickness_tolerance_mm + door.arris_mm)
        if not thinner or not _face_texture_line(P_far, search.scan, far_line, ref_line, xdir, thr):
            break
        # A grain line of the hinge face, parallel to the arrises, made the first clear step (the face's
        # level comes back beyond it): look again beyond it (bench_surfaces --seed 9100, thin_028: a
        # 36 mm door under 9 % grain with a 2.9 mm period, taken as 7 mm thick and refused as having no
        # bottom end).
        beyond = far_line.at(search.scan) + 3.0 * xdir
        lo = np.maximum(search.lo, np.ceil(beyond)).astype(int) if xdir > 0 else search.lo
        hi = search.hi if xdir > 0 else np.minimum(search.hi, np.floor(beyond)).astype(int)
        keep = hi - lo >= 4
        search = Band(search.scan[keep], lo[keep], hi[keep])
        far_line = None
        if search.scan.size < 0.3 * len(band_far.scan):
            break
    if far_line is None or far_line.inliers.sum() < 0.3 * len(band_far.scan):
        faint = _faint_face(plane, band_ref, ref_lay, ref_line, xdir, door.arris_mm / sc, thr, cfg, s8)
        raise Refused(
            faint
            or q.Refusal(
                "edge_missing",
                f"the {HUMAN['far']} was not found within {door.thickness_mm + cfg.thickness_search_mm:.0f} mm of "
                f"the reference arris; check that the door is {door.thickness_mm:g} mm thick and that "
                "nothing covers its far edge",
            )
        )

    # bottom end: scan lines between the two arrises, at the nominal corner height
    corner0 = region.nominal_corner_px
    s_corner = corner0[1] if ref_lay.axis == "row" else corner0[0]
    u_ref, u_far = ref_line.at(s_corner), far_line.at(s_corner)
    u_exp = u_ref + xdir * door.thickness_mm / sc
    if abs(u_far - u_exp) * sc > 3.0:  # far arris doubtful here: span the bottom end by the door's thickness
        u_far = u_exp if abs(u_exp - u_ref) < abs(u_far - u_ref) else u_far
    lo_s, hi_s = sorted((u_ref, u_far))
    inset = 0.15 * (hi_s - lo_s) + 6.0
    scans_b = np.arange(int(math.ceil(lo_s + inset)), int(math.floor(hi_s - inset)) + 1, 3)
    band_bot = region.bottom_band(scans_b)
    bands["bottom"] = band_bot
    bot_line = yield from _coarse_line(plane, band_bot, bot_lay, thr, 5, 0.3, strip_half)
    if bot_line is None:
        faint = _faint_face(plane, band_ref, ref_lay, ref_line, xdir, door.arris_mm / sc, thr, cfg, s8)
        raise Refused(
            faint
            or q.Refusal(
                "edge_missing",
                f"the {HUMAN['bottom']} was not found between the arrises; check that "
                "the door's bottom end is in view and nothing covers it",
            )
        )

    return CoarseEdges(ref_line, far_line, bot_line, band_ref, band_far, band_bot)


def _coarse_pose(
    c: CoarseEdges, plane, s8: float, region: SearchRegion, cell: Cell, door: DoorSize, cfg: LocateConfig
) -> MetricPose:
    """Pose from the coarse lines; refuses at once what is plainly not a door in place."""
    ref_lay, far_lay, bot_lay = (region.layouts[k] for k in ("reference", "far", "bottom"))

    def uvs(line, band, axis):
        s = band.scan[:: max(len(band.scan) // 40, 1)].astype(float)
        a = line.at(s)
        return np.stack([s, a], 1) if axis == "col" else np.stack([a, s], 1)

    uv = [
        uvs(c.bottom, c.bottom_band, bot_lay.axis),
        uvs(c.ref, c.ref_band, ref_lay.axis),
        uvs(c.far, c.far_band, far_lay.axis),
    ]
    xz = np.split(region.plane_points(np.concatenate(uv)), np.cumsum([len(u) for u in uv])[:2])
    coarse_groups = {"bottom": (xz[0], True), "reference": (xz[1], False), "far": (xz[2], False)}
    # Across an arris strip the far arris's coarse steps (either polarity: beyond it may lie a far face) can
    # be the strip's inner border on some scan lines and its outer one on others; a line within the
    # search's tolerance of both then tilts (arris bench seed 7048, a 0.75 mm chamfer brighter than the
    # face: 1.8 deg against the reference arris's 0.4, the first pass's windows off by up to 5 px at their
    # ends, the far arris lost). Where the two arrises' coarse lines disagree by more than their coarse
    # steps allow, the direction is the reference arris's and the bottom end's.
    tilted = (
        door.arris_mm > 0
        and abs(math.degrees(math.atan(c.far.b) - math.atan(c.ref.b))) > COARSE_ARRIS_SKEW_DEG
    )
    fit0 = fit_rectangle_edges(
        coarse_groups, scale_floor=0.05, n_iter=3, offset_only=("far",) if tilted else ()
    )
    pose = pose_from_fit(fit0, region.face_map)
    if not (abs(pose.yaw_deg) < 20 and 0 < pose.thickness_mm < 3 * door.thickness_mm + 50):
        raise Refused(
            q.Refusal(
                "no_door",
                "the edges found do not form a door's corner; check that a door lies in "
                "the fixture and that the camera has not moved",
            )
        )
    # A far face in view as bright as the hinge face hides the far arris's step: the first clear step is
    # then the far face's back edge, which measures the band's width more (bench_surfaces --seed 500,
    # hard_006: 38.35 mm of a 35.13 mm door, refused as the wrong door). Where the back edge of a door of
    # the recipe's thickness lies there, that is what was found; the fine stage fits the band beside the
    # arris and measures the thickness again.
    # (fixed limits, not the cell's tolerance: the model check relocates with the tolerances lifted and
    # must see the same poses)
    if abs(pose.thickness_mm - door.thickness_mm) > COARSE_THICKNESS_MM:
        behind = region.thickness_behind_far_face(pose.corner, math.radians(pose.yaw_deg), pose.thickness_mm)
        if behind is not None and abs(behind - door.thickness_mm) <= COARSE_THICKNESS_MM:
            pose = replace(pose, thickness_mm=behind)
    # A door far outside the envelope, or of quite another thickness (a panel where the recipe says a
    # door), is clear already here. The coarse lines take the strongest step across each arris strip,
    # which may be its inner border (a strip about as dark as the background): each edge then lies up
    # to the arris's size inside the door, and the thickness up to twice that short (a 2.1 mm rounding
    # in shadow measured 46.15 mm of a 50 mm door here, a valid door refused). The limits allow for it.
    arris_slack = door.arris_mm
    r = q.check_envelope(
        pose.x_mm,
        pose.z_mm,
        pose.yaw_deg,
        cell.envelope,
        cfg.envelope_margin_mm + 3.0 + arris_slack,
        cfg.envelope_margin_deg + 0.5,
    )
    if r:
        if _looks_like_pattern_here(plane, s8, c.ref_band, ref_lay.axis, cfg):
            r = PATTERN
        raise Refused(
            r,
            diagnostics={
                "measured": {"x_mm": pose.x_mm, "z_mm": pose.z_mm, "yaw_deg": pose.yaw_deg, "coarse": True}
            },
        )
    r = q.check_thickness(
        pose.thickness_mm,
        door.thickness_mm,
        cfg.thickness_tolerance_mm + 2.0 + 2.0 * arris_slack,
        cfg.thickness_tolerance_mm,
    )
    if r:
        raise Refused(r, diagnostics={"measured": {"thickness_mm": pose.thickness_mm, "coarse": True}})
    return pose


def _looks_like_pattern_here(plane, s8: float, band: Band, axis, cfg: LocateConfig) -> bool:
    P = oriented(plane, axis)
    rows = P[band.lo.min() : band.hi.max() + 1, band.scan[::8]].T.astype(np.float32) * s8
    return q.looks_like_pattern(rows, 4 * cfg.min_contrast)


_REVERSED = {
    True: "the hinge face looks darker than the background here, and the cell says the door is the brighter "
    "(locate.door_brighter: true); if this cell's doors are darker, set locate.door_brighter: false in the "
    "cell file, else check the lighting",
    False: "the hinge face looks brighter than the background here, and the cell says the door is the darker "
    "(locate.door_brighter: false); if this cell's doors are brighter, set locate.door_brighter: true in the "
    "cell file, else check the lighting",
}


def _brightness_reversed(plane, s8: float, region: SearchRegion, cell: Cell, cfg: LocateConfig) -> bool:
    """Whether the hinge face is clearly on the other side of the background's brightness than the cell's
    ``locate.door_brighter`` says, where it must lie whatever the door's placement in the envelope: used to
    name the cause when no edge of the expected polarity was found.

    Read on the hinge face's centre line (half the thickness in from the reference arris) and beyond the
    reference arris by the search region's reach, 20-80 mm up from the bottom end: medians of 13 pixels each
    (the door lies in the cell's envelope: on a door no thicker than twice the envelope's x, plus its yaw's
    reach, no point is surely on the face, and nothing is said).
    """
    zs = np.linspace(20.0, 80.0, 13)
    x_face, x_back = 0.5 * region.door.thickness_mm, -(region.x_range_mm + 8.0)
    if x_face <= cell.envelope.x_mm + 3.0:  # (+3 mm: the envelope's yaw over 80 mm)
        return False
    h, w = plane.shape
    levels = []
    for x in (x_face, x_back):
        uv = np.round(region.image_points(np.stack([np.full_like(zs, x), zs], axis=1))).astype(int)
        inside = (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
        if inside.sum() < 7:
            return False
        levels.append(float(np.median(plane[uv[inside, 1], uv[inside, 0]])) * s8)
    d = levels[0] - levels[1]
    return abs(d) >= cfg.min_contrast and (d < 0) == cfg.door_brighter


def _strip_half(door: DoorSize, scale_mm_per_px: float) -> int:
    """Half width (strided samples of 2 px) of a coarse step detector whose halves span an arris strip."""
    return 2 + int(math.ceil(0.5 * door.arris_mm / scale_mm_per_px))


def _first_far_line(
    plane, band: Band, layout: EdgeLayout, thr: float, tol: float, xdir: int, door: DoorSize, sc: float
) -> Generator[StepQuery, tuple[np.ndarray, np.ndarray], ImageLine | None]:
    """The far arris's coarse line: the first clear step on each scan line of ``band`` coming from the
    reference arris (``xdir``: the along-direction of door +X), RANSAC over them (tolerance ``tol`` px)."""
    near = (band.lo if xdir > 0 else band.hi).astype(float)
    along_f, strength_f = yield StepQuery(
        plane,
        dict(
            axis=layout.axis,
            scan=band.scan,
            lo=band.lo,
            hi=band.hi,
            polarity=0,
            half=2,
            prefer=near,
            stride=2,
            # an arris strip makes a weak first step (face -> strip): skip it
            prefer_fraction=0.3 if door.arris_mm > 0 else 0.1,
        ),
    )
    strong_f = np.isfinite(along_f) & (strength_f >= thr)
    far_line = ransac_line(band.scan[strong_f], along_f[strong_f], tol) if strong_f.sum() >= 10 else None
    if far_line is not None:
        # Beside a wide far face a faint arris step (hinge face -> far face) may win on only part of the
        # scan lines, and the far face's stronger back edge on the rest: a line of steps nearer to the
        # reference arris with enough support is the arris (unless it is only an arris strip's inner edge).
        nearer = strong_f & ((far_line.at(band.scan) - along_f) * xdir > tol)
        near_line = ransac_line(band.scan[nearer], along_f[nearer], tol) if nearer.sum() >= 10 else None
        strip_px = door.arris_mm / sc + 3.0
        if (
            near_line is not None
            and near_line.inliers.sum() >= 0.3 * len(band.scan)
            and np.median((far_line.at(band.scan) - near_line.at(band.scan)) * xdir) > strip_px
        ):
            far_line = near_line
    return far_line


#: grain lines of the hinge face that the far arris's search may pass over (:func:`_face_texture_line`)
FACE_TEXTURE_SKIPS = 12
#: px beside a candidate far-arris line where its wide levels start, and how many are read on each side
_TEXTURE_GAP_PX = 3
_TEXTURE_WIDE_PX = 15


def _face_texture_line(
    P, scan: np.ndarray, line: ImageLine, ref_line: ImageLine, xdir: int, thr: float
) -> bool:
    """Whether a step line found beyond the reference arris is the hinge face's own texture (a grain line
    running along the edge), not the face's end.

    ``P``: the plane, oriented ``[along, scan]``; ``xdir``: the along-direction of door +X. On every fourth
    scan line: the step's size right at the line (the means of 4 px on either side) and the difference of
    the mean levels over ``_TEXTURE_WIDE_PX`` px on either side, ``_TEXTURE_GAP_PX`` px away from it
    (inside, towards the reference arris, at most what lies between the two). Beyond the face's end the
    level stays off the face's (background, a far face, an arris strip: the wide difference is about the
    step); beyond a grain line it comes back (a stripe a few px wide, then face again: the wide difference is
    a fraction of the step). Texture where, over the scan lines with a step of at least ``thr`` at the
    line, the median of the wide difference over the step is less than a half.
    """
    n_along = P.shape[0]
    s = scan[::4].astype(np.int64)
    at = line.at(s)
    room = np.floor((at - ref_line.at(s)) * xdir).astype(np.int64) - 2 * _TEXTURE_GAP_PX
    if s.size < 5:
        return False
    width = int(min(_TEXTURE_WIDE_PX, room.min()))
    if width < 4:
        return False
    # the columns: 4 px outside the line, the wide ones outside, 4 px inside, the wide ones inside
    offsets = np.concatenate([np.arange(1, 5), _TEXTURE_GAP_PX + np.arange(width)])
    offsets = np.concatenate([offsets, -offsets])
    idx = np.rint(at).astype(np.int64)[:, None] + xdir * offsets[None, :]
    ok = ((idx >= 0) & (idx < n_along)).all(axis=1)
    if int(ok.sum()) < 5:
        return False
    v = P[idx[ok], s[ok][:, None]].astype(np.float64)  # (lines, offsets)
    half = 4 + width
    step = np.abs(v[:, :4].mean(axis=1) - v[:, half : half + 4].mean(axis=1))
    off = np.abs(v[:, 4:half].mean(axis=1) - v[:, half + 4 :].mean(axis=1))
    clear = step >= thr  # the scan lines where the line lies on a step (its RANSAC inliers, about)
    if int(clear.sum()) < 5:
        return False
    return float(np.median(off[clear] / step[clear])) < 0.5


def _no_door_reason(plane, band: Band, layout: EdgeLayout, cfg: LocateConfig, s8: float) -> q.Refusal:
    if _looks_like_pattern_here(plane, s8, band, layout.axis, cfg):
        return PATTERN
    faint = _faint_edge(plane, band, layout, cfg.min_contrast / s8)
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


def _faint_face(
    plane,
    band: Band,
    layout: EdgeLayout,
    ref_line: ImageLine,
    xdir: int,
    strip_px: float,
    thr: float,
    cfg: LocateConfig,
    s8: float,
) -> q.Refusal | None:
    """``low_contrast`` where the hinge face beside the found reference arris is less than the contrast
    threshold ``thr`` (plane units) brighter than the background outside it (darker, for a dark door), else
    None: the reason a far arris or a bottom end was not found is then the lighting, not the door.

    Seen on bench_surfaces --sets combined --seed 500, image 8: a hinge face 1 grey level from its
    background, whose arrises show only as a rounding's faint lines, was refused "the far arris was not found
    ... check that the door is 30.83 mm thick", which sent the operator to the door. The levels are medians
    over 10 px on each side of the line, clear of it by 4 px and twice the arris strip's width
    (``strip_px``). Where the coarse line is not the reference arris (image 24: a face darker than the
    background in a shadow band, whose far arris took the reference search) the levels read another edge's
    sides and the old reason stays.
    """
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


#: pixels (each side) along the edge over which :func:`_faint_edge` averages each scan line
FAINT_EDGE_AVERAGE_PX = 8


def _faint_edge(plane, band: Band, layout: EdgeLayout, thr: float) -> tuple[float, int, int] | None:
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
    line = _line_through_steps(band.scan, along, strength, 0.5 * thr, 10, 0.6)
    if line is None:
        return None
    on = strength[np.isfinite(along) & (strength >= 0.5 * thr)][line.inliers]
    return float(np.median(on)), int(line.inliers.sum()), len(band.scan)


@dataclass(frozen=True)
class Coarse:
    """What the coarse stage hands the refine stage: the three edges' lines and the pose from them."""

    edges: CoarseEdges
    pose: MetricPose


def find_coarse(
    lum: LuminancePlane,
    region: SearchRegion,
    cell: Cell,
    door: DoorSize,
    cfg: LocateConfig,
    clock: StageClock,
    bands: dict[str, Band],
) -> Generator[StepQuery, tuple[np.ndarray, np.ndarray], Coarse]:
    """The coarse stage: the three edges in the search region, then the pose from them (laps ``coarse`` and
    ``coarse_pose`` on ``clock``).

    ``bands``: the trace's, given each band as it is chosen (a refusal's overlay shows where the stage
    looked). Refuses (:class:`~doorloc.vision.state.Refused`) where no door is found, naming a hinge face
    on the other side of the background's brightness than the cell says where that is the cause.
    """
    plane, s8 = lum.plane, lum.scale_to_8bit
    try:
        edges = yield from _coarse_edges(plane, s8, region, door, cfg, bands)
    except Refused as e:
        if e.refusal.code in ("no_door", "edge_missing") and _brightness_reversed(
            plane, s8, region, cell, cfg
        ):
            raise Refused(q.Refusal(e.refusal.code, _REVERSED[cfg.door_brighter])) from None
        raise
    clock.lap("coarse")
    pose = _coarse_pose(edges, plane, s8, region, cell, door, cfg)
    clock.lap("coarse_pose")
    return Coarse(edges, pose)
