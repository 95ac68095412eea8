"""Edges whose bright square the camera clipped: placed from their unclipped samples.

A sensor (or its tone curve) that saturates stores every light beyond its clip level at that level, so an
overexposed square's plateau is the clip and not its light. The area estimator takes the plateau for the
square's level: the step it balances is too small on the bright side and it moves the edge towards the dark
side, the more the further the true level lies beyond the clip. No table undoes that (the light beyond the
clip is gone), so such an edge is placed by a censored fit instead: the scan line's samples below ``cut`` of
the way from its dark plateau to its clipped one are fitted with the edge spread of the camera's blur,

    light = dark + A E(d - x0),     A >= clipped plateau - dark,

``x0`` (px along the normal, + towards bright) the edge, ``A`` the true step (free, at least the clipped
one). The blur is measured on the photograph's edges whose bright plateau stays below the cut's band under
the clip (their profiles, :func:`doorloc.photometric.profiles.fit_profiles`); never on the offsets. A line counts as clipped where its
bright plateau reaches the clip level (within a grey level's rounding).

Written by hand: a censored step fit with a known spread is a few closed forms, vectorised over scan lines
(``A`` solved per line for each ``x0``, ``x0`` by a grid refined by parabolas); no library offers it.
"""

from __future__ import annotations

import numpy as np

from doorloc.photometric.board_edges import BoardEdges, per_edge_median
from doorloc.photometric.model import PhotometricModel
from doorloc.photometric.profiles import edge_spread

__all__ = [
    "CUT",
    "clipped_lines",
    "near_clip_edges",
    "unclipped_blur_px",
    "censored_offsets_px",
    "clip_candidates",
]

#: samples above this fraction of the way from the dark plateau to the clipped one are left out of the fit
#: (the last levels before a clip often bend: demosaicking and compression spread the clip over them)
CUT = 0.85
#: a plateau this many grey levels under the clip level still counts as clipped (8-bit rounding)
CLIP_TOLERANCE_GREY = 1.0
#: the edge's position is searched on this grid (px from the true edge), then refined
_X0_GRID = np.linspace(-2.5, 2.5, 21)


def clipped_lines(edges: BoardEdges, clip_level: float) -> np.ndarray:
    """Scan lines (N,) whose bright plateau reaches ``clip_level`` (fraction of full scale)."""
    return np.isfinite(edges.bright) & (edges.bright >= 255.0 * clip_level - CLIP_TOLERANCE_GREY)


def near_clip_edges(edges: BoardEdges, clip_level: float, cut: float = CUT) -> np.ndarray:
    """Edges (E,) whose median bright plateau lies above ``cut`` of the way from their dark plateau to
    ``clip_level``: in the band where the levels before a clip bend, so their profile does not give the
    camera's blur."""
    b = per_edge_median(edges.windows.edge, edges.bright, edges.n_edges)
    d = per_edge_median(edges.windows.edge, edges.dark, edges.n_edges)
    return ~(np.isfinite(b) & np.isfinite(d)) | (b - d >= cut * (255.0 * clip_level - d))


#: fewest edges not clipped the blur is read from; with fewer, it is read from the clipped edges' fits
MIN_UNCLIPPED_EDGES = 5


def unclipped_blur_px(edge_blur_px: np.ndarray, clipped: np.ndarray) -> float:
    """The camera's blur (Gaussian sigma of the optics, px): the median of the edges' profile blurs over the
    edges not clipped; NaN where fewer than :data:`MIN_UNCLIPPED_EDGES` are not."""
    b = np.asarray(edge_blur_px, float)
    ok = np.isfinite(b) & ~clipped
    return float(np.median(b[ok])) if ok.sum() >= MIN_UNCLIPPED_EDGES else float("nan")


def _sse_and_amp(
    d: np.ndarray,
    y: np.ndarray,
    w: np.ndarray,
    x0: np.ndarray,
    blur: float,
    model: PhotometricModel,
    floor: np.ndarray,
) -> np.ndarray:
    E = edge_spread(d - x0[:, None], blur, model)
    amp = np.maximum((w * y * E).sum(1) / np.maximum((w * E * E).sum(1), 1e-12), floor)
    return (w * (y - amp[:, None] * E) ** 2).sum(1)


def _censored_fit(
    edges: BoardEdges, lines: np.ndarray, blur_px: float, model: PhotometricModel, cut: float
) -> tuple[np.ndarray, np.ndarray]:
    """Each line's edge (px) and the fit's squared misfit (light^2) by the censored fit (module docstring)."""
    win = edges.windows
    g = win.grey[lines] / 255.0
    read = (lambda v: np.asarray(v, float)) if model.linear_response else model.light_from_grey
    dark = read(edges.dark[lines] / 255.0)
    top = read(edges.bright[lines] / 255.0)
    y = read(g) - dark[:, None]
    floor = top - dark
    w = (y < cut * floor[:, None]).astype(float)
    d = win.distance_px()[lines]
    sse = np.stack(
        [_sse_and_amp(d, y, w, np.full(lines.size, x), blur_px, model, floor) for x in _X0_GRID], 1
    )
    k = np.clip(np.argmin(sse, 1), 1, _X0_GRID.size - 2)
    x0 = _X0_GRID[k]
    # two parabola steps: the grid's spacing, then a twentieth of it
    for h in (_X0_GRID[1] - _X0_GRID[0], 0.05 * (_X0_GRID[1] - _X0_GRID[0])):
        s0, s1, s2 = (_sse_and_amp(d, y, w, x0 + t, blur_px, model, floor) for t in (-h, 0.0, h))
        with np.errstate(divide="ignore", invalid="ignore"):
            step = 0.5 * (s0 - s2) / (s0 - 2 * s1 + s2)
        x0 = x0 + h * np.where(np.isfinite(step) & (s0 - 2 * s1 + s2 > 0), np.clip(step, -1.0, 1.0), 0.0)
    enough = w.sum(1) >= 3
    return np.where(enough, x0, np.nan), np.where(
        enough, _sse_and_amp(d, y, w, x0, blur_px, model, floor), 0.0
    )


def censored_offsets_px(
    edges: BoardEdges, lines: np.ndarray, blur_px: float, model: PhotometricModel, cut: float = CUT
) -> np.ndarray:
    """Offset (px, + towards bright) of each scan line in ``lines`` (indices) by the censored fit (module
    docstring), in the linear light of ``model``'s response; NaN where fewer than three samples are below the
    cut."""
    lines = np.asarray(lines, int)
    if lines.size == 0:
        return np.zeros(0)
    return _censored_fit(edges, lines, blur_px, model, cut)[0]


def clip_candidates(brights: np.ndarray) -> np.ndarray:
    """Clip levels (fraction of full scale) worth trying for plateaus ``brights`` (grey): from the median
    plateau up to the highest ones, where a clip piles the plateaus."""
    b = np.asarray(brights, float)
    b = b[np.isfinite(b)]
    if b.size == 0:
        return np.array([1.0])
    q = np.percentile(b, [50, 65, 75, 85, 90, 95, 98, 99.5]) / 255.0
    return np.unique(np.clip(np.round(q * 255.0) / 255.0, 0.2, 1.0))
