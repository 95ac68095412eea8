"""The first coarse step finder, kept as the reference that :func:`doorloc.vision.coarse.coarse_edges`
(the faster one locate uses) must match bit for bit (tests/vision/test_coarse.py)."""

from __future__ import annotations

import numpy as np

from doorloc.vision.sampling import Axis, gather_profiles, oriented


def coarse_edges(
    plane: np.ndarray,
    axis: Axis,
    scan: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    polarity: int,
    half: int = 3,
    prefer: np.ndarray | None = None,
    prefer_fraction: float = 0.3,
    stride: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """Strongest step of the given polarity on each scan line between ``lo`` and ``hi``.

    The step response at ``k`` is the mean of ``half`` pixels after ``k`` minus the mean of ``half``
    pixels before it, which finds blurred edges and ignores single noisy pixels.

    Parameters
    ----------
    plane : ndarray (H, W)
        Luminance.
    axis : "col" or "row"
    scan : ndarray (N,) int
        Scan-line coordinates (in the image).
    lo, hi : ndarray (N,) int
        Search interval on each scan line (inclusive), px.
    polarity : +1, -1 or 0
        +1: the edge goes dark to bright with increasing ``along``; 0: either way.
    half : int
        Half-width of the step detector, px.
    prefer : ndarray (N,) float, optional
        Expected edge position per scan line: instead of the strongest step, take the local maximum
        nearest to it among those at least ``prefer_fraction`` of the strongest (e.g. the far arris,
        next to which a visible far face makes a second, stronger step).
    stride : int
        Look at every ``stride``-th pixel along the scan line only (a coarse answer, ``stride`` px
        resolution, for a fraction of the work); ``half`` counts strided samples.

    Returns
    -------
    along : ndarray (N,) float
        Edge position (pixel boundary between the two halves, i.e. ``k - 0.5``), NaN if none.
    strength : ndarray (N,) float
        Step response there, grey levels of the plane (signed by polarity, so >0 is the right way).
    """
    P = oriented(plane, axis)
    scan = np.asarray(scan, int)
    lo = np.asarray(lo, int) - half * stride
    hi = np.asarray(hi, int) + half * stride
    length = int(np.max(hi - lo)) // stride + 1 if scan.size else 0
    if scan.size == 0 or length <= 2 * half + 1:
        return np.full(scan.size, np.nan), np.zeros(scan.size)
    vals, inside = gather_profiles(P, scan, lo, length, stride)
    inside &= np.arange(length)[None, :] * stride <= (hi - lo)[:, None]
    c = np.concatenate(
        [np.zeros((len(scan), 1), np.float32), np.cumsum(vals, axis=1, dtype=np.float32)], axis=1
    )
    k = np.arange(half, length - half + 1)
    resp = (c[:, k + half] - c[:, k]) - (c[:, k] - c[:, k - half])
    resp = (polarity * resp if polarity else np.abs(resp)) / half
    ok = inside[:, k - half] & inside[:, np.minimum(k + half - 1, length - 1)]
    resp = np.where(ok, resp, -np.inf)
    best = np.argmax(resp, axis=1)
    if prefer is not None:
        top = resp[np.arange(len(scan)), best]
        peak = np.zeros_like(ok)
        peak[:, 1:-1] = (resp[:, 1:-1] >= resp[:, :-2]) & (resp[:, 1:-1] > resp[:, 2:])
        # Noise floor of the detector on each scan line (most of a band is flat): a candidate must
        # stand clear of it, not only reach a fraction of the strongest step.
        floor = 1.4826 * np.median(np.abs(np.where(ok, resp, 0.0)), axis=1)
        cand = peak & (resp >= np.maximum(prefer_fraction * top, 5.0 * floor)[:, None]) & (resp > 0)
        pos = lo[:, None] + stride * k[None, :] - 0.5 * stride
        dist = np.where(cand, np.abs(pos - np.asarray(prefer, float)[:, None]), np.inf)
        near = np.argmin(dist, axis=1)
        best = np.where(np.isfinite(dist[np.arange(len(scan)), near]), near, best)
    strength = resp[np.arange(len(scan)), best]
    along = lo + stride * k[best] - 0.5 * stride
    along = np.where(np.isfinite(strength), along, np.nan)
    return along.astype(float), np.where(np.isfinite(strength), strength, 0.0)
