"""Where the hinge face ends beyond the reference arris: the coarse stage's tests of a far-arris line.

The coarse stage (:mod:`doorloc.vision.coarse_stage`) takes the far arris as the first clear step beyond the
reference arris on each scan line. Grain stripes of the hinge face run along the edge as the arrises do and
make steps too: :func:`face_texture_line` and :func:`face_continues` tell such a line from the face's end
(beyond a stripe the face's level comes back), :func:`parallel_far_line` keeps a door's far arris parallel
to its reference arris where a shadow splits the steps, and :func:`face_end_line` reads the face's end on
the scan lines' mean profile where their single steps make no line at all.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import map_coordinates

from doorloc.vision.lines import ImageLine, fit_image_line
from doorloc.vision.region import Band

__all__ = [
    "FAR_SUPPORT_SHARE",
    "face_continues",
    "face_end_line",
    "face_texture_line",
    "far_line_held",
    "parallel_far_line",
]

#: the share of the far arris's scan lines whose step its coarse line must hold
FAR_SUPPORT_SHARE = 0.3
#: px beside a candidate far-arris line where its wide levels start, and how many are read on each side
_TEXTURE_GAP_PX = 3
_TEXTURE_WIDE_PX = 15
#: half width of :func:`face_end_line`'s step on the mean profile, px, and how far past the band it reads
_MEAN_STEP_HALF_PX = 3
_MEAN_BEYOND_PX = 8


def parallel_far_line(
    scan: np.ndarray, along: np.ndarray, line: ImageLine, ref_slope: float, tol: float, xdir: int, n: int
) -> ImageLine:
    """``line`` (through the steps ``along`` on the scan lines ``scan``), or where its direction departs
    from the parallel reference arris's (slope ``ref_slope``) by more than moves it ``tol`` px over the
    steps, the line through the steps within ``tol`` of the parallel nearest the reference arris that holds
    ``FAR_SUPPORT_SHARE`` of the ``n`` scan lines (the far arris is the first clear step); ``line`` where none
    does. (A shadow across a thin door's face, bench_surfaces.py --sets thin --n 40 --seed 58100, door 23,
    made the far face's back edge the first step on its scan lines; RANSAC's line ran through both, 2.7 deg
    off, and the door at yaw 1.86 deg was refused as lying at 3.08: outside the envelope.)"""
    if scan.size < 2 or abs(line.b - ref_slope) * float(np.ptp(scan)) <= tol:
        return line
    offsets = (along - ref_slope * scan) * xdir  # (increasing away from the reference arris)
    for o in np.sort(offsets):
        held = np.abs(offsets - o) <= tol
        if held.sum() >= FAR_SUPPORT_SHARE * n:  # (then the steps about their median)
            centre = float(np.median(offsets[held]))
            held = np.abs(offsets - centre) <= tol
            fitted = fit_image_line(scan[held], along[held])
            return ImageLine(fitted.a, fitted.b, held)
    return line


def face_continues(
    P, scan: np.ndarray, line: ImageLine, ref_line: ImageLine, xdir: int, expected_px: float, thr: float
) -> bool:
    """Whether the hinge face goes on beyond a step line found short of the recipe's thickness: a grain
    stripe wider than :func:`face_texture_line`'s look (grain of 22 % contrast and a 7.7 mm period, its
    bands 15-20 px wide: a 49.5 mm door read 29.8 mm thick and refused as the wrong door,
    ``bench_surfaces.py --sets grain_strong``, seed 17, door 27).

    On every fourth scan line, the mean levels of the face (from the reference arris to the line), of what
    lies between the line and the recipe's far arris (``expected_px`` from the reference arris along the
    scan line, about: the coarse scale), and beyond that. The face goes on where, over the scan lines
    whose face and beyond differ by at least ``thr``, what lies between is nearer the face than what lies
    beyond by a factor two (median). A door that is there thinner (a panel) has background between, as
    beyond; the test is then false.
    """
    n_along = P.shape[0]
    s = scan[::4].astype(np.int64)
    if s.size < 5:
        return False
    g = _TEXTURE_GAP_PX
    ref, at = ref_line.at(s), line.at(s)
    # along-offsets from the reference arris, px (door +X positive), per scan line
    near = np.floor((at - ref) * xdir).astype(np.int64)
    far = int(math.floor(expected_px))
    if far - g - (int(near.max()) + g) < 4 or int(near.min()) - 2 * g < 4:
        return False

    def mean_between(a0: np.ndarray, a1: np.ndarray) -> np.ndarray:
        # the mean level over along-offsets a0..a1 (from the reference arris) on each scan line, NaN outside
        out = np.full(s.size, np.nan)
        for i in range(s.size):
            idx = np.rint(ref[i] + xdir * np.arange(a0[i], a1[i] + 1)).astype(np.int64)
            if idx.size >= 4 and idx.min() >= 0 and idx.max() < n_along:
                out[i] = float(P[idx, s[i]].astype(np.float64).mean())
        return out

    ones = np.ones(s.size, np.int64)
    face = mean_between(g * ones, near - g)
    between = mean_between(near + g, (far - g) * ones)
    beyond = mean_between((far + g) * ones, (far + g + _TEXTURE_WIDE_PX) * ones)
    clear = np.isfinite(face) & np.isfinite(between) & np.isfinite(beyond) & (np.abs(face - beyond) >= thr)
    if int(clear.sum()) < 5:
        return False
    return float(np.median(np.abs(between[clear] - face[clear]))) < 0.5 * float(
        np.median(np.abs(between[clear] - beyond[clear]))
    )


def face_texture_line(
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


def far_line_held(line: ImageLine, n_scan: int) -> bool:
    """Whether a far-arris line holds ``FAR_SUPPORT_SHARE`` of the band's ``n_scan`` scan lines."""
    return int(line.inliers.sum()) >= FAR_SUPPORT_SHARE * n_scan


def face_end_line(P, band: Band, ref_line: ImageLine, xdir: int, thr: float) -> ImageLine | None:
    """The far arris's coarse line where the hinge face ends, read on the scan lines' mean profile; None
    where no step there ends the face.

    For a door without an arris whose single scan lines make no line of first clear steps: a face a few
    grey levels above its background under grain of half that (``bench_surfaces.py --sets thin --n 40
    --seed 63100``, thin_020: a 37 mm door 6.5 grey levels above the background under 9.6 % grain, whose
    stripes made steps of 5-8 grey levels across the face; its far arris was the first step on 11 of 51
    scan lines and the door was refused ``edge_missing``). Each scan line of ``band`` (``P`` the plane
    oriented ``[along, scan]``, ``xdir`` the along-direction of door +X) is read outwards from the reference
    arris, at whole pixels from it (linear interpolation along the scan line), to ``_MEAN_BEYOND_PX`` past
    the band, and the profiles are averaged: the noise averages out, the grain stripes (along the edge, as
    the arrises) stay. The far arris is the first step of the mean profile within the band (a local maximum
    of the step between ``_MEAN_STEP_HALF_PX`` px halves, at least ``thr / 2``, plane units) that leaves the
    face's level (its median between the reference arris and the step) by ``thr`` or more over the next
    ``2 _MEAN_STEP_HALF_PX`` px past the step's halves, and beyond which the level never comes back within
    ``thr / 2`` of it: a grain stripe's does. (The step itself is read smaller than the levels' difference:
    the arrises' 2 px of coarse parallelism smear it over the scan lines.) The line is the reference
    arris's moved there (the two are parallel within the coarse stage's 2 px on a door without an arris);
    every scan line its inlier.
    """
    n_along = P.shape[0]
    h = _MEAN_STEP_HALF_PX
    ref = ref_line.at(band.scan)
    edge = (band.hi if xdir > 0 else band.lo).astype(float)
    start = (band.lo if xdir > 0 else band.hi).astype(float)
    d_end = int(math.ceil(float(np.max((edge - ref) * xdir)))) + _MEAN_BEYOND_PX
    d_band = float(np.min((start - ref) * xdir))
    if d_end < 4 * h:
        return None
    at = ref[:, None] + xdir * np.arange(d_end + 1, dtype=np.float64)[None, :]  # (scan lines, samples)
    whole = (at.min(axis=1) >= 0) & (at.max(axis=1) <= n_along - 1)
    if int(whole.sum()) < 10:
        return None
    scan = np.broadcast_to(band.scan[whole, None].astype(np.float64), at[whole].shape)
    # (linear along each scan line: the scan coordinates are whole pixels)
    mean = map_coordinates(P, [at[whole], scan], output=np.float64, order=1).mean(axis=0)
    c = np.concatenate([[0.0], np.cumsum(mean)])
    j = np.arange(h - 1, mean.size - h)  # the step between samples j and j + 1
    step = np.abs((c[j + 1 + h] - c[j + 1]) - (c[j + 1] - c[j + 1 - h])) / h
    peak = np.r_[False, (step[1:-1] >= step[:-2]) & (step[1:-1] > step[2:]), False]
    for k in np.flatnonzero(peak & (step >= 0.5 * thr) & (j + 0.5 >= d_band)):
        at_px = int(j[k])
        inside, beyond = mean[h : at_px + 1 - h], mean[at_px + 1 :]
        if inside.size < 4 or beyond.size < 3 * h:
            continue
        face = float(np.median(inside))
        # (every level past the step, its own half window too: a grain stripe's flank a few px short of the
        # face's end has the stripe's level there, within thr / 2 of the face's)
        if abs(float(np.median(beyond[h : 3 * h])) - face) >= thr and np.all(
            np.abs(beyond - face) >= 0.5 * thr
        ):
            moved = xdir * (at_px + 0.5)
            return ImageLine(ref_line.a + moved, ref_line.b, np.ones(band.scan.size, dtype=bool))
    return None
