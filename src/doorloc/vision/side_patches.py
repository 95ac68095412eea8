"""Flat patches of the image beside each edge line, where the noise of the door's two sides is read: by the
gate (a camera that sharpens, a clip below white) and by the response check (whether the noise dithers the
grey levels' rounding enough to read the camera response), whose reading the doubts take up
(:mod:`doorloc.vision.quantisation`)."""

from __future__ import annotations

import functools
import math

import numpy as np

from doorloc.vision.edge_samples import EdgeSamples
from doorloc.vision.region import EDGE_NAMES
from doorloc.vision.sampling import oriented

__all__ = [
    "NOISE_PATCH_GAP_PX",
    "NOISE_PATCH_PX",
    "NOISE_READ_PX",
    "NOISE_STEP_MAX_DN",
    "plateau_noise_dn",
    "side_patches",
]

#: the flat patches :func:`side_patches` reads beside each line: their length along the edge and depth
#: across it, and their distance from the edge's points (beyond a 3 mm arris strip and the blur), px
NOISE_PATCH_PX = (128, 48)
NOISE_PATCH_GAP_PX = 24


def side_patches(
    plane, samples: dict[str, EdgeSamples], weights: dict[str, np.ndarray]
) -> dict[bool, dict[str, np.ndarray]]:
    """Flat patches beside the middle of each line's edge points (raw grey levels; the points of ``samples``
    whose fit ``weights`` are positive), per side of the door's edges (``False`` the dark side, ``True`` the
    bright one) and line."""
    sides: dict[bool, dict[str, np.ndarray]] = {False: {}, True: {}}
    length, depth = NOISE_PATCH_PX
    for k in EDGE_NAMES:
        s = samples[k]
        ok = (weights[k] > 0) & np.isfinite(s.along)
        scan, along = s.scan[ok], s.along[ok]
        if scan.size < 8:
            continue
        centre = 0.5 * (float(scan.min()) + float(scan.max()))
        mid = np.abs(scan - centre) <= length / 2
        if not mid.any():
            continue
        P = oriented(plane, s.axis)
        s0, s1 = int(scan[mid].min()), int(scan[mid].max()) + 1
        lo, hi = int(math.floor(along[mid].min())), int(math.ceil(along[mid].max()))
        step = s.step[ok]
        bright_after = float(step.sum(where=np.isfinite(step))) > 0  # the bright side at larger ``along``
        for after in (False, True):
            a0 = hi + NOISE_PATCH_GAP_PX if after else lo - NOISE_PATCH_GAP_PX - depth
            if 0 <= a0 and a0 + depth <= P.shape[0] and 0 <= s0 and s1 <= P.shape[1]:
                sides[after == bright_after][k] = P[a0 : a0 + depth, s0:s1]
    return sides


#: the centre of a patch whose noise :func:`plateau_noise_dn` reads, across and along the edge, px: 512 pixels
#: read a noise to about 3 %
NOISE_READ_PX = (16, 32)
#: pixels further than this (0-255 scale) from the plane through their patch are a stray edge, not its noise
#: (here and in :func:`doorloc.vision.quality.side_noise`)
NOISE_STEP_MAX_DN = 8.0


def plateau_noise_dn(sides: dict[bool, dict[str, np.ndarray]], s8: float) -> float:
    """The image's plateau noise (1-sigma, 0-255 scale; 0 without a patch): the most that the centre of any
    side patch (``NOISE_READ_PX``) shows, as what a plane through it leaves less the rounding itself
    (Sheppard's correction, a twelfth of a level squared). Each patch reads low where its level sits near a
    whole grey level and the noise is under about half a level (its pixels then round alike: 0.2 grey of
    read noise read 0 to 0.3 over the six patches of one door), so the most of them is the noise.

    Not :func:`doorloc.vision.quality.side_noise`, which reads the same noise: it also counts the patches'
    levels for the gate's checks, and its generic plane fit cost 0.15 ms a patch, 1 ms a frame here."""
    sigmas = [_plane_noise(_centre(p), s8) for side in sides.values() for p in side.values()]
    return max((x for x in sigmas if math.isfinite(x)), default=0.0)


def _centre(patch: np.ndarray) -> np.ndarray:
    """The middle ``NOISE_READ_PX`` of a side patch (all of it where it is smaller)."""
    across, along = NOISE_READ_PX
    r0 = max(0, (patch.shape[0] - across) // 2)
    c0 = max(0, (patch.shape[1] - along) // 2)
    return patch[r0 : r0 + across, c0 : c0 + along]


def _plane_noise(patch: np.ndarray, s8: float) -> float:
    """The 1-sigma (0-255 scale) a plane through ``patch`` leaves, less the rounding; NaN under 2 x 2."""
    if patch.shape[0] < 2 or patch.shape[1] < 2:
        return math.nan
    g = patch.astype(np.float64).ravel() * s8
    design, solve = _plane_design(patch.shape)
    residual = g - design @ (solve @ g)
    residual = residual[np.abs(residual) <= NOISE_STEP_MAX_DN]
    if not residual.size:
        return math.nan
    return math.sqrt(max(float(np.var(residual)) - s8 * s8 / 12.0, 0.0))


@functools.cache
def _plane_design(shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """The plane's design matrix over a patch of ``shape`` (rows: pixels; columns: 1, row, column) and its
    pseudo-inverse (made once per shape: every frame reads patches of the same few)."""
    rows, cols = np.mgrid[0 : shape[0], 0 : shape[1]]
    design = np.stack([np.ones(rows.size), rows.ravel(), cols.ravel()], 1)
    solve = np.linalg.pinv(design)
    design.flags.writeable = solve.flags.writeable = False
    return design, solve
