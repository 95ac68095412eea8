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

from doorloc.cell import Cell, DoorSize
from doorloc.vision import quality as q
from doorloc.vision.coarse import line_through_steps
from doorloc.vision.coarse_refusals import (
    face_refusal,
    faint_face,
    looks_like_pattern_here,
    no_door_reason,
)
from doorloc.vision.config import LocateConfig
from doorloc.vision.face_end import (
    face_continues,
    face_end_line,
    face_texture_line,
    far_line_held,
    parallel_far_line,
)
from doorloc.vision.gate import PATTERN
from doorloc.vision.lines import ImageLine, fit_rectangle_edges, ransac_line
from doorloc.vision.luminance import LuminancePlane
from doorloc.vision.metric import MetricPose, pose_from_fit
from doorloc.vision.region import HUMAN, Band, EdgeLayout, SearchRegion
from doorloc.vision.sampling import Axis, oriented
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
#: grain lines of the hinge face that the far arris's search may pass over (:func:`doorloc.vision.face_end.face_texture_line`)
FACE_TEXTURE_SKIPS = 12


@dataclass(frozen=True)
class StepQuery:
    """One coarse step search that :func:`doorloc.vision.locate.locate_steps` needs: the arguments of
    :func:`doorloc.vision.coarse.coarse_edges` (``plane`` the luminance, the rest keyword arguments)."""

    plane: np.ndarray
    kwargs: dict[str, Any]

    @classmethod
    def in_band(
        cls,
        plane: np.ndarray,
        axis: Axis,
        band: Band,
        polarity: int,
        half: int,
        prefer: np.ndarray | None,
        prefer_fraction: float,
    ) -> StepQuery:
        """The strongest step of ``polarity`` (0: either) on every other scan line of ``band``, of halves
        ``half`` px; where ``prefer`` (px, per scan line) is given, the step nearest it of at least
        ``prefer_fraction`` of the strongest."""
        kwargs = dict(axis=axis, scan=band.scan, lo=band.lo, hi=band.hi, polarity=polarity, half=half)
        return cls(plane, kwargs | dict(prefer=prefer, prefer_fraction=prefer_fraction, stride=2))


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
        edges = yield from _coarse_edges(lum, region, door, cfg, bands)
    except Refused as e:
        better = face_refusal(e.refusal.code, plane, s8, region, cell, cfg)
        if better is not None:
            raise Refused(better) from None
        raise
    clock.lap("coarse")
    pose = _coarse_pose(edges, plane, s8, region, cell, door, cfg)
    clock.lap("coarse_pose")
    return Coarse(edges, pose)


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
        along, strength = yield StepQuery.in_band(
            plane, layout.axis, band, layout.polarity, half, prefer, 0.5
        )
        line = line_through_steps(band.scan, along, strength, thr, min_points, min_fraction)
        if line is not None:
            return line
    return None


def _nearer_reference(
    s: _Search, band: Band, ref_line: ImageLine
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
    plane, layout, xdir, thr = s.plane, s.region.layouts["reference"], s.xdir, s.thr
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
    along, strength = yield StepQuery.in_band(
        plane, layout.axis, Band(scan, lo, hi), layout.polarity, 2, outer, 0.5
    )
    line = line_through_steps(scan, along, strength, thr, 10, 0.4 * len(band.scan) / len(scan))
    if line is None:
        return ref_line
    inner = line.at(scan)
    gap_mm = float(np.median((at - inner) * xdir)) * s.sc
    if not (s.cfg.min_thickness_mm <= gap_mm <= s.door.thickness_mm + s.cfg.thickness_search_mm):
        return ref_line
    # the level between the two lines (inset by the tolerance) against the level just outside the nearer one
    step = _step_into_door(P, scan, inner, at, xdir, tol, door_sign)
    if not np.any(np.isfinite(step)) or float(np.nanmedian(step)) < 0.5 * thr:
        return ref_line
    return line


def _step_into_door(
    P: np.ndarray,
    scan: np.ndarray,
    inner: np.ndarray,
    outer: np.ndarray,
    xdir: int,
    tol: float,
    door_sign: int,
) -> np.ndarray:
    """On each scan line (``P`` oriented ``[along, scan]``), the median level between the lines at ``inner``
    and ``outer`` (each inset by ``tol`` px; ``xdir`` the along-direction of door +X) less the median over 8 px just
    outside ``inner``, in the door's polarity (``door_sign``); NaN where either reaches past the image."""
    n_along = P.shape[0]
    step = np.empty(scan.size)
    for k, (col, a, b) in enumerate(zip(scan, inner, outer, strict=True)):
        i0, i1 = sorted((int(round(a + xdir * tol)), int(round(b - xdir * tol))))
        o0, o1 = sorted((int(round(a - xdir * tol)), int(round(a - xdir * (tol + 8)))))
        if i1 - i0 < 2 or o0 < 0 or o1 >= n_along or i0 < 0 or i1 >= n_along:
            step[k] = np.nan
            continue
        inside = float(np.median(P[i0 : i1 + 1, col]))
        outside = float(np.median(P[o0 : o1 + 1, col]))
        step[k] = (inside - outside) * door_sign
    return step


@dataclass(frozen=True)
class _Search:
    """What every coarse search in one image reads: the luminance ``plane`` and its 8-bit scale ``s8``, the
    region, the door and the settings, and what follows from them."""

    plane: np.ndarray
    s8: float
    region: SearchRegion
    door: DoorSize
    cfg: LocateConfig
    #: the contrast threshold, plane units
    thr: float
    #: the along-direction of door +X on the arrises' scan lines
    xdir: int
    #: the region's nominal scale, mm/px
    sc: float
    #: the step detector's half width that spans an arris strip (:func:`_strip_half`; None without an arris)
    strip_half: int | None


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
    lum: LuminancePlane, region: SearchRegion, door: DoorSize, cfg: LocateConfig, bands: dict[str, Band]
) -> Generator[StepQuery, tuple[np.ndarray, np.ndarray], CoarseEdges]:
    """Find the three edges to a pixel or two in the search region (strided step finder + RANSAC), each band
    given to ``bands`` as it is chosen.

    A coroutine: each step search is yielded as a :class:`StepQuery` (see
    :func:`doorloc.vision.locate.locate_steps`)."""
    plane, s8 = lum.plane, lum.scale_to_8bit
    thr = cfg.min_contrast / s8
    # -- search region: coarse steps ------------------------------------------------------------
    ref_lay = region.layouts["reference"]
    band_ref = region.arris_band(step=4, height_mm=45.0)
    bands["reference"] = band_ref
    P = oriented(plane, ref_lay.axis)
    sub = P[band_ref.lo.min() : band_ref.hi.max() + 1 : 3, band_ref.scan[::4]]
    # (white: the top levels, or the clip the cell's camera model states)
    clipped = lum.clipped_from
    white = q.SATURATED_GREY if clipped is None else min(q.SATURATED_GREY, clipped)
    r = q.check_exposure(sub, cfg.min_contrast, cfg.max_saturated_fraction, s8, white)
    if r:
        raise Refused(r)

    # The reference arris is the first step into the door coming from -X (a visible far face can make
    # a stronger step of the same polarity further on).
    xdir = ref_lay.door_side(cfg.door_brighter)  # along-direction of door +X
    sc = region.nominal_scale
    strip_half = _strip_half(door, sc) if door.arris_mm > 0 else None
    search = _Search(plane, s8, region, door, cfg, thr, xdir, sc, strip_half)
    band_ref, ref_line = yield from _reference_line(search, band_ref)
    bands["reference"] = band_ref

    band_far = _far_band(search, band_ref, ref_line)
    bands["far"] = band_far
    far_line = yield from _far_line(search, band_far, ref_line)
    n_far = len(band_far.scan)
    if not door.arris_mm > 0 and (far_line is None or not far_line_held(far_line, n_far)):
        P_far = oriented(plane, region.layouts["far"].axis)
        far_line = face_end_line(P_far, band_far, ref_line, xdir, thr) or far_line
    if far_line is None or not far_line_held(far_line, n_far):
        raise Refused(
            _faint_face(search, band_ref, ref_line)
            or q.Refusal(
                "edge_missing",
                f"the {HUMAN['far']} was not found within {door.thickness_mm + cfg.thickness_search_mm:.0f} mm of "
                f"the reference arris; check that the door is {door.thickness_mm:g} mm thick and that "
                "nothing covers its far edge",
            )
        )

    band_bot = _bottom_band(search, ref_line, far_line)
    bands["bottom"] = band_bot
    bot_line = yield from _coarse_line(plane, band_bot, region.layouts["bottom"], thr, 5, 0.3, strip_half)
    if bot_line is None:
        raise Refused(
            _faint_face(search, band_ref, ref_line)
            or q.Refusal(
                "edge_missing",
                f"the {HUMAN['bottom']} was not found between the arrises; check that "
                "the door's bottom end is in view and nothing covers it",
            )
        )

    return CoarseEdges(ref_line, far_line, bot_line, band_ref, band_far, band_bot)


def _reference_line(
    s: _Search, first: Band
) -> Generator[StepQuery, tuple[np.ndarray, np.ndarray], tuple[Band, ImageLine]]:
    """The reference arris's coarse line and the band it was found in (``first``, or one higher up)."""
    ref_lay = s.region.layouts["reference"]
    # A shadow across the door low down (a clamp, the fixture) can take the arris's step below the
    # threshold over the whole first band: look higher up before saying there is no door (bench_surfaces
    # --seed 500, hard_014: a shadow band over 30-70 mm, refused as no door). (Both bands are memoised
    # with the region, built once per cell and door.)
    ref_line = None
    band_ref = first
    for band_ref in (first, s.region.arris_band(step=4, height_mm=90.0, start_mm=45.0)):
        outer = (band_ref.lo if s.xdir > 0 else band_ref.hi).astype(float)
        ref_line = yield from _coarse_line(
            s.plane, band_ref, ref_lay, s.thr, 10, 0.4, s.strip_half, prefer=outer
        )
        if ref_line is not None:
            break
    if ref_line is None:
        raise Refused(no_door_reason(s.plane, first, ref_lay, s.cfg, s.s8))
    ref_line = yield from _nearer_reference(s, band_ref, ref_line)
    return band_ref, ref_line


def _far_band(s: _Search, band_ref: Band, ref_line: ImageLine) -> Band:
    """Where the far arris is looked for: from the thinnest door the settings allow to the recipe's
    thickness and its search margin, beyond the reference arris."""
    ref_at = ref_line.at(band_ref.scan)
    a1 = ref_at + s.xdir * s.cfg.min_thickness_mm / s.sc
    a2 = ref_at + s.xdir * (s.door.thickness_mm + s.cfg.thickness_search_mm) / s.sc
    n_along = s.plane.shape[0] if s.region.layouts["far"].axis == "col" else s.plane.shape[1]
    band_far = Band(
        band_ref.scan,
        np.clip(np.floor(np.minimum(a1, a2)), 2, n_along - 3).astype(int),
        np.clip(np.ceil(np.maximum(a1, a2)), 2, n_along - 3).astype(int),
    )
    keep = band_far.hi - band_far.lo >= 4
    return Band(band_far.scan[keep], band_far.lo[keep], band_far.hi[keep])


def _far_line(
    s: _Search, band_far: Band, ref_line: ImageLine
) -> Generator[StepQuery, tuple[np.ndarray, np.ndarray], ImageLine | None]:
    """The far arris's coarse line in ``band_far``, past the hinge face's grain lines (None where none)."""
    tol = 3.0
    xdir = s.xdir
    # The far arris is the first clear step beyond the reference arris: the hinge face ends there, and
    # what follows (background, or the far face of a thin door shifted towards -X, brighter or darker
    # than the hinge face) does not matter. Taking the first step, not the one nearest the expected
    # thickness, measures the door that is there (a 12 mm panel where a 50 mm door was expected). A step
    # that the hinge face's own grain makes is passed over: beyond it the face's level comes back.
    P_far = oriented(s.plane, s.region.layouts["far"].axis)
    search = band_far
    for _skip in range(FACE_TEXTURE_SKIPS + 1):
        far_line = yield from _first_far_line(s, search, tol, ref_line.b)
        if far_line is None:
            break
        # (only a door thinner than the recipe's needs the look: a grain line lies inside the face; an
        # arris strip's inner border, a strip's width in, is the far arris's, which the fine stage places)
        mid = search.scan[search.scan.size // 2 : search.scan.size // 2 + 1]
        thickness = float((far_line.at(mid) - ref_line.at(mid))[0]) * xdir * s.sc
        thinner = thickness < s.door.thickness_mm - 2.0 * (s.cfg.thickness_tolerance_mm + s.door.arris_mm)
        if not thinner or not (
            face_texture_line(P_far, search.scan, far_line, ref_line, xdir, s.thr)
            or face_continues(P_far, search.scan, far_line, ref_line, xdir, s.door.thickness_mm / s.sc, s.thr)
        ):
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
    return far_line


def _bottom_band(s: _Search, ref_line: ImageLine, far_line: ImageLine) -> Band:
    """Where the bottom end is looked for: scan lines between the two arrises, at the nominal corner height."""
    corner0 = s.region.nominal_corner_px
    s_corner = corner0[1] if s.region.layouts["reference"].axis == "row" else corner0[0]
    u_ref, u_far = ref_line.at(s_corner), far_line.at(s_corner)
    u_exp = u_ref + s.xdir * s.door.thickness_mm / s.sc
    if (
        abs(u_far - u_exp) * s.sc > 3.0
    ):  # far arris doubtful here: span the bottom end by the door's thickness
        u_far = u_exp if abs(u_exp - u_ref) < abs(u_far - u_ref) else u_far
    lo_s, hi_s = sorted((u_ref, u_far))
    inset = 0.15 * (hi_s - lo_s) + 6.0
    scans_b = np.arange(int(math.ceil(lo_s + inset)), int(math.floor(hi_s - inset)) + 1, 3)
    return s.region.bottom_band(scans_b)


def _coarse_pose(
    c: CoarseEdges, plane, s8: float, region: SearchRegion, cell: Cell, door: DoorSize, cfg: LocateConfig
) -> MetricPose:
    """Pose from the coarse lines; refuses at once what is plainly not a door in place."""
    pose = _pose_from_lines(c, region, door)
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
        if looks_like_pattern_here(plane, s8, c.ref_band, region.layouts["reference"].axis, cfg):
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


def _pose_from_lines(c: CoarseEdges, region: SearchRegion, door: DoorSize) -> MetricPose:
    """The pose from the coarse lines mapped to the hinge-face plane; refuses (``no_door``) where they form
    no door's corner."""
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
    return pose


def _faint_face(s: _Search, band: Band, ref_line: ImageLine) -> q.Refusal | None:
    """:func:`doorloc.vision.coarse_refusals.faint_face` beside the reference arris ``ref_line`` in ``band``."""
    strip_px = s.door.arris_mm / s.sc
    return faint_face(s.plane, s.s8, band, s.region.layouts["reference"], ref_line, s.xdir, strip_px, s.cfg)


def _strip_half(door: DoorSize, scale_mm_per_px: float) -> int:
    """Half width (strided samples of 2 px) of a coarse step detector whose halves span an arris strip."""
    return 2 + int(math.ceil(0.5 * door.arris_mm / scale_mm_per_px))


def _first_far_line(
    s: _Search, band: Band, tol: float, ref_slope: float
) -> Generator[StepQuery, tuple[np.ndarray, np.ndarray], ImageLine | None]:
    """The far arris's coarse line: the first clear step on each scan line of ``band`` coming from the
    reference arris, RANSAC over them (tolerance ``tol`` px); on a door without an arris about parallel to
    the reference arris (its slope ``ref_slope``: :func:`doorloc.vision.face_end.parallel_far_line`)."""
    plane, layout, thr, xdir, door, sc = s.plane, s.region.layouts["far"], s.thr, s.xdir, s.door, s.sc
    near = (band.lo if xdir > 0 else band.hi).astype(float)
    # an arris strip makes a weak first step (face -> strip): skip it
    skip_weak = 0.3 if door.arris_mm > 0 else 0.1
    along_f, strength_f = yield StepQuery.in_band(plane, layout.axis, band, 0, 2, near, skip_weak)
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
    if far_line is not None and not door.arris_mm > 0:  # (a strip's two borders are two such parallels)
        far_line = parallel_far_line(
            band.scan[strong_f], along_f[strong_f], far_line, ref_slope, tol, xdir, len(band.scan)
        )
    if far_line is not None and not far_line_held(far_line, len(band.scan)):
        # Grain stripes of the hinge face that wander along it can make the first clear step on most scan
        # lines, each at another place, and leave the arris's line too few of them (bench_surfaces --sets
        # grain --n 40 --seed 19100, grain_020: 9.7 % grain of a 6.4 mm period, its far arris a 30 grey-level
        # step, the first on 11 of 56 scan lines; refused edge_missing). The step nearest that line is
        # looked for again on every scan line: where the arris is, it is there on nearly all.
        along_n, strength_n = yield StepQuery.in_band(
            plane, layout.axis, band, 0, 2, far_line.at(band.scan), skip_weak
        )
        strong_n = np.isfinite(along_n) & (strength_n >= thr)
        again = ransac_line(band.scan[strong_n], along_n[strong_n], tol) if strong_n.sum() >= 10 else None
        if again is not None and again.inliers.sum() > far_line.inliers.sum():
            far_line = again
    return far_line
