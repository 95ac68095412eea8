"""The camera's response measured on the calibration photographs' chessboard edges.

``doorloc calibrate`` stores it with the camera model: a camera's response once, where hundreds of plain
black-white edges at every pixel phase and angle are in view, so that doors whose edges cannot show it
(arrises, a sharp door square to the camera) need not doubt it by the full range of cameras' exponents.
Each board edge is read as :func:`doorloc.vision.response.fit_line_response` reads a door's plain edge (the
transition of a step blurred by an even spread is symmetric in linear light): :func:`fit_board_response`
pools one photograph's edges, :func:`board_response` the photographs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from doorloc.vision.edges import subpixel_edges
from doorloc.vision.response import RESPONSE_SKEW_BLOCKS, RESPONSE_WINDOW_BLURS, LineResponse
from doorloc.vision.response_asymmetry import (
    RESPONSE_GAMMA_RANGE,
    RESPONSE_PLATEAU_PX,
    RESPONSE_SIGMA_FLOOR,
    Transitions,
    dithered,
    exponent_with_scatter,
    transition_skew_px,
)
from doorloc.vision.sampling import Axis, gather_profiles, linearizing_lut, median_with_error, oriented

__all__ = ["BOARD_RESPONSE_MIN_IMAGES", "BoardResponse", "board_response", "fit_board_response"]


def fit_board_response(
    plane: np.ndarray,
    corners_px: np.ndarray,
    cols: int,
    rows: int,
    used_gamma: float = 1.0,
    blur_px: float = 1.5,
) -> LineResponse | None:
    """The camera response measured on a checkerboard's square edges (the calibration images).

    A printed board has hundreds of plain black-white edges at every pixel phase and angle: the same
    measurement as :func:`fit_line_response` on a door's plain edge (the transition of a step blurred by an
    even spread is symmetric in linear light), pooled over the board. Each edge between two neighbouring
    inner corners is read on the scan lines across its middle 40 % (the corners' X-junctions and the
    square's other edges stay out of the window), placed by the area estimator, and its raw profile turned
    to run dark to bright; the exponent's standard error is the scatter over blocks of whole edges.

    Parameters
    ----------
    plane : ndarray (H, W)
        The raw grey image (uint8 or uint16), as the camera wrote it.
    corners_px : ndarray (cols * rows, 2)
        Inner corners in grid order (row by row, ``cols`` per row), px.
    cols, rows : int
        Inner corners per row and per column.
    used_gamma : float
        The exponent the edges are placed with (its skew is reported).
    blur_px : float
        The largest optical blur expected (Gaussian sigma, px): sizes the window (3 sigmas and the plateaus
        each side); edges of squares too small for it are left out.

    Returns
    -------
    LineResponse or None
        None with too few usable edges (squares under about 30 px at 1.5 px of blur, or too few in view).
    """
    corners = np.asarray(corners_px, float).reshape(rows, cols, 2)
    top = 255.0 if plane.dtype == np.uint8 else 65535.0
    lut = linearizing_lut(plane.dtype, used_gamma)
    want = int(math.ceil(RESPONSE_WINDOW_BLURS * max(blur_px, 0.0) + 1.5))
    raws, offsets = [], []
    pairs = [(corners[r, c], corners[r, c + 1]) for r in range(rows) for c in range(cols - 1)] + [
        (corners[r, c], corners[r + 1, c]) for r in range(rows - 1) for c in range(cols)
    ]
    for p0, p1 in pairs:
        found_edge = _board_edge_profiles(plane, p0, p1, want, lut, top)
        if found_edge is None:
            continue
        raw, off = found_edge
        raws.append(raw)
        offsets.append(off)
    if len(raws) < 3 * RESPONSE_SKEW_BLOCKS:
        return None
    raw = np.concatenate(raws)
    t = Transitions(raw, np.concatenate(offsets), dithered=dithered(raw, top), top=top)
    # blocks of whole edges (neighbouring edges share the board's print and light, far ones need not)
    n_blocks = 2 * RESPONSE_SKEW_BLOCKS
    edge_block = np.array_split(np.arange(len(raws)), n_blocks)
    blocks = np.concatenate(
        [np.full(raws[i].shape[0], k) for k, idx in enumerate(edge_block) for i in idx]
    ).astype(np.int64)
    found = exponent_with_scatter(t, blocks, n_blocks)
    if found is None:
        return None
    g, se, alternatives = found
    lo, hi = (float(v) for v in np.median(t.raw[:, [0, -1]], axis=0))
    return LineResponse(
        g, se, lo, hi, transition_skew_px(t, slice(None), used_gamma), alternatives=alternatives
    )


def _board_edge_profiles(
    plane: np.ndarray, p0: np.ndarray, p1: np.ndarray, half: int, lut: np.ndarray | None, top: float
) -> tuple[np.ndarray, np.ndarray] | None:
    """The raw profiles across a board's edge between the inner corners ``p0`` and ``p1`` (image px), for
    :func:`fit_board_response`: ``(raw, off)``, each profile's grey levels over ``2 (half + plateau) + 1``
    pixels divided by ``top`` and turned to run dark to bright, and its first pixel's offset from the edge
    placed by the area estimator (``lut`` turns grey levels to light), px. None where the square is too
    small for the window or fewer than 4 profiles are usable."""
    d = p1 - p0
    length = float(np.hypot(*d))
    # Scan lines across the edge's middle 40 %: a profile there meets the square's other edges no nearer
    # than 0.42 of a square (at 45 deg; farther at other angles), so a window (plateaus included) of
    # 0.3 of a square each side stays clear of them and of their blur.
    if not (np.all(np.isfinite(d)) and half + RESPONSE_PLATEAU_PX <= 0.3 * length):
        return None  # squares too small for the transition and its plateaus
    axis: Axis = "col" if abs(d[0]) >= abs(d[1]) else "row"  # profiles across the edge
    i_s, i_a = (0, 1) if axis == "col" else (1, 0)
    s0, s1 = sorted((p0[i_s] + 0.3 * d[i_s], p0[i_s] + 0.7 * d[i_s]))
    scan = np.arange(int(math.ceil(s0)), int(math.floor(s1)) + 1)
    if scan.size < 4:
        return None
    centre = p0[i_a] + (scan - p0[i_s]) * (d[i_a] / d[i_s])
    smp = subpixel_edges(plane, axis, scan, centre, half, RESPONSE_PLATEAU_PX, lut=lut)
    ok = smp.valid & np.isfinite(smp.along) & (np.abs(smp.along - centre) < 2.0)
    if int(ok.sum()) < 4:
        return None
    H = half + RESPONSE_PLATEAU_PX
    e = smp.along[ok]
    c0 = np.round(e).astype(int)
    vals, inside = gather_profiles(oriented(plane, axis), scan[ok], c0 - H, 2 * H + 1)
    keep = inside.all(axis=1)
    raw = vals[keep].astype(np.float64) / top
    off = (c0 - H - e)[keep].astype(np.float64)
    if raw.shape[0] < 4:
        return None
    if raw[:, -RESPONSE_PLATEAU_PX:].mean() < raw[:, :RESPONSE_PLATEAU_PX].mean():
        raw, off = raw[:, ::-1], -off - 2 * H  # dark to bright, as every other edge
    return raw, off


#: fewest board images whose responses :func:`board_response` pools (their scatter is the doubt)
BOARD_RESPONSE_MIN_IMAGES = 5


@dataclass(frozen=True)
class BoardResponse:
    """The camera response measured on the calibration photographs (:func:`board_response`).

    Attributes
    ----------
    gamma, sigma : float
        The exponent (``grey = light ** (1 / gamma)``), the median of the images' own, and its 1-sigma from
        their scatter: on real photographs one image's own standard error understates it several times
        (JPEG, in-camera sharpening and print texture skew single edges: the OpenCV sample images scatter
        from 0.85 to 3.36), so the images are taken as independent measurements and nothing else.
    per_image : tuple of float
        Each usable image's exponent.
    """

    gamma: float
    sigma: float
    per_image: tuple[float, ...]

    @property
    def unmeasured_factor(self) -> float:
        """``locate.response_unmeasured_factor`` that this measurement allows (its 2-sigma range as a factor)."""
        from doorloc.cell import measured_response_factor  # (the cell file's rule, kept in one place)

        return measured_response_factor(self.gamma, self.sigma)


def board_response(
    views: list[tuple[np.ndarray, np.ndarray]], cols: int, rows: int, blur_px: float = 1.5
) -> BoardResponse | None:
    """The camera response from photographs of a checkerboard, pooled robustly over the images.

    ``views``: (raw grey image, all ``cols * rows`` inner corners in the board's row-major order) per
    photograph. Each image gives its exponent (:func:`fit_board_response`); the answer is their median and
    its standard error from their median absolute deviation (``1.2533 * 1.4826 * MAD / sqrt(n)``, the
    median's efficiency), at least the images' own standard error over ``sqrt(n)``. None with fewer than
    ``BOARD_RESPONSE_MIN_IMAGES`` usable images.
    """
    fits = [fit_board_response(img, c, cols, rows, blur_px=blur_px) for img, c in views]
    ok = [f for f in fits if f is not None and RESPONSE_GAMMA_RANGE[0] < f.gamma < RESPONSE_GAMMA_RANGE[1]]
    if len(ok) < BOARD_RESPONSE_MIN_IMAGES:
        return None
    g = np.array([f.gamma for f in ok])
    med, spread = median_with_error(g)
    own = float(np.median([f.sigma for f in ok])) / math.sqrt(g.size)
    return BoardResponse(med, max(spread, own, RESPONSE_SIGMA_FLOOR), tuple(float(x) for x in g))
