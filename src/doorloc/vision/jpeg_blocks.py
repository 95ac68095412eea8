"""The JPEG block artifacts near a point: :func:`block_artifact_ratio`."""

from __future__ import annotations

import math

import numpy as np

from doorloc.vision.jit import kernel, median_in_place
from doorloc.vision.sampling import median

__all__ = ["block_artifact_ratio"]


def _abs_step_sums_warm_up(k) -> None:
    for dtype in (np.uint8, np.uint16):
        for ax in (0, 1):
            k(np.zeros((40, 40), dtype)[2:30, 3:33], ax)


@kernel(_abs_step_sums_warm_up)
def _abs_step_sums(crop, ax):
    """``np.abs(np.diff(crop, axis=ax)).sum(axis=1 - ax)`` of an integer image, as int64 (exact), compiled."""
    h, w = crop.shape
    if ax == 1:
        out = np.zeros(w - 1, np.int64)
        for r in range(h):
            for c in range(w - 1):
                out[c] += abs(np.int64(crop[r, c + 1]) - np.int64(crop[r, c]))
    else:
        out = np.zeros(h - 1, np.int64)
        for r in range(h - 1):
            acc = 0
            for c in range(w):
                acc += abs(np.int64(crop[r + 1, c]) - np.int64(crop[r, c]))
            out[r] = acc
    return out


def _block_step_ratio_warm_up(k) -> None:
    for dtype in (np.uint8, np.uint16):
        k(np.zeros((40, 40), dtype)[2:36, 3:38], 5, 7, 1.0, 0.05)


@kernel(_block_step_ratio_warm_up)
def _block_step_ratio(crop, u0, v0, scale_to_8bit, min_excess):
    """:func:`block_artifact_ratio` of an integer ``crop`` (at most 256 px a side) whose first pixel is
    ``(u0, v0)``, compiled: the same float32 means (exact integer sums, :func:`_abs_step_sums`) and medians."""
    sc = np.float32(scale_to_8bit)
    out = 0.0
    for ax in (1, 0):
        s = _abs_step_sums(crop, ax)
        n = np.float32(crop.shape[1 - ax])
        o = u0 if ax == 1 else v0
        n_on = 0
        for i in range(s.size):
            n_on += (o + i) % 8 == 7
        on_d = np.empty(n_on, np.float32)
        off_d = np.empty(s.size - n_on, np.float32)
        a = b = 0
        for i in range(s.size):
            d = (np.float32(s[i]) / n) * sc
            if (o + i) % 8 == 7:
                on_d[a] = d
                a += 1
            else:
                off_d[b] = d
                b += 1
        on, off = median_in_place(on_d), median_in_place(off_d)
        out = max(out, on / max(off, 1e-3) if on - off >= min_excess else 1.0)
    return out


def block_artifact_ratio(
    plane: np.ndarray,
    centre_px: np.ndarray,
    half: int = 96,
    scale_to_8bit: float = 1.0,
    min_excess: float = 0.05,
) -> float:
    """How much stronger the grey-level steps between 8x8 pixel blocks are than those inside them, near a point.

    A JPEG round trip quantizes each 8x8 block on its own, which leaves steps at the block boundaries:
    the median over the boundary columns (rows) of the mean absolute difference to the next column (row),
    over the median of the same elsewhere, is about 1 for an image that never was a JPEG (1.0-1.2 on
    rendered ones at any noise) and 1.5 or (nearly noise-free) far more for JPEG quality 88. The larger
    of the two directions is returned; NaN when the window holds too few pixels. Where the boundary
    steps exceed the others by less than ``min_excess`` grey levels (0-255 scale; a noise-free image that
    never was a JPEG has all its medians near 0), the ratio is taken as 1.
    """
    cu, cv = float(centre_px[0]), float(centre_px[1])
    if not (math.isfinite(cu) and math.isfinite(cv)):
        return float("nan")
    u0, v0 = max(int(cu) - half, 0), max(int(cv) - half, 0)
    crop = plane[v0 : v0 + 2 * half, u0 : u0 + 2 * half]
    if min(crop.shape) < 32:
        return float("nan")
    if crop.dtype.kind in "ui" and crop.dtype.itemsize <= 2 and max(crop.shape) <= 256:
        # Integer differences summed exactly (compiled): the float32 mean's sums are integers below
        # 2**24 (exact), so this is the same mean for a fraction of the work (and no transposed copy).
        return float(_block_step_ratio(crop, u0, v0, scale_to_8bit, min_excess))
    out = []
    for ax, o in ((1, u0), (0, v0)):
        arr = crop if ax == 1 else crop.T
        d = np.abs(np.diff(arr.astype(np.float32), axis=1)).mean(axis=0) * scale_to_8bit
        boundary = (o + np.arange(d.size)) % 8 == 7
        on, off = median(d[boundary]), median(d[~boundary])
        out.append(on / max(off, 1e-3) if on - off >= min_excess else 1.0)
    return max(out)
