"""Edges whose bright square the camera clipped: placed from their unclipped samples, the clipped ones as
lower bounds.

A sensor (or its tone curve) that saturates stores every light beyond its clip level at that level, so an
overexposed square's plateau is the clip and not its light. The area estimator takes the plateau for the
square's level: the step it balances is too small on the bright side and it moves the edge towards the dark
side, the more the further the true level lies beyond the clip. No table undoes that (the light beyond the
clip is gone), so such an edge is placed by a censored fit instead (a Tobit model in the limit of small
noise): on each scan line, in linear light above the dark plateau,

    light = A E(d - x0),

``E`` the edge spread of the camera's blur, ``x0`` (px along the normal, + towards bright) the edge. Samples
below ``cut`` of the way from the dark plateau to the clipped one are fitted by least squares; the others
(at the clip, or in the band just under it where demosaicking and compression spread the clip) are lower
bounds on the light, which count only where the model falls below them.

The true step ``A`` is not left free: a step seen only below the clip trades its height against its
position (a taller step further towards the bright side fits the same foot), and a height bounded below by
the clipped plateau moves even unclipped edges towards the bright side. It is read instead from what the
clip leaves: the board's light squares reflect a fixed multiple of its dark squares' light under the same
illumination, so ``A = (ratio - 1) x dark``, with the dark plateau of the edge itself (never clipped) and
the ratio of the light squares' to the dark squares' light measured on the photograph's edges whose bright
plateau stays below the cut's band under the clip (:func:`unclipped_contrast`; where a photograph has too
few, on the other photographs of the camera), at least the clipped step. The blur is measured on the same
edges (their profiles, :func:`doorloc.photometric.profiles.fit_profiles`); where too few, on the clipped
lines themselves, whose foot gives the blur once the step is known (:func:`censored_blur_px`). Neither is
ever read from the offsets. A line counts as clipped where its bright plateau reaches the clip
level (within a grey level's rounding) and its edge's bright plateau is flat (a clip stores one level; light
below it carries the sensor's noise).

Written by hand: a censored step fit with a known spread and height is a one-parameter search, vectorised
over scan lines (a grid refined by parabolas; the blur by scipy's bounded scalar search around it); no
library offers it.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.optimize import minimize_scalar

from doorloc.photometric.board_edges import BoardEdges
from doorloc.photometric.model import PhotometricModel
from doorloc.photometric.profiles import edge_spread, parabola_vertex_step

__all__ = [
    "CUT",
    "clipped_lines",
    "flat_topped_edges",
    "near_clip_edges",
    "unclipped_blur_px",
    "unclipped_contrast",
    "censored_offsets_px",
    "censored_blur_px",
    "clip_candidates",
    "white_starts",
]

#: samples above this fraction of the way from the dark plateau to the clipped one are lower bounds only
#: (the last levels before a clip often bend: demosaicking and compression spread the clip over them)
CUT = 0.85
#: a plateau this many grey levels under the clip level still counts as clipped (8-bit rounding)
CLIP_TOLERANCE_GREY = 1.0
#: the edge's position is searched on this grid (px from the true edge), then refined
_X0_GRID = np.linspace(-2.5, 2.5, 21)


#: a scan line's bright plateau is flat where its mean lies this close (grey) to the window's brightest sample
#: (on an 8-bit scale: every plateau sample at that level)
FLAT_GREY = 0.25
#: an edge is flat-topped where at least this fraction of its scan lines, and at least this many, are flat
FLAT_FRACTION = 0.8
FLAT_LINES = 5


def flat_topped_edges(edges: BoardEdges) -> np.ndarray:
    """Edges (E,) whose bright plateau is flat on nearly every scan line: every plateau sample at the window's
    brightest level, as a clip stores it, where an unclipped plateau carries the sensor's noise."""
    win = edges.windows
    flat = np.isfinite(edges.bright) & (win.grey.max(1) - edges.bright <= FLAT_GREY)
    n = np.bincount(win.edge, minlength=edges.n_edges)
    k = np.bincount(win.edge, flat, minlength=edges.n_edges)
    return (k >= FLAT_LINES) & (k >= FLAT_FRACTION * n)


def clipped_lines(edges: BoardEdges, clip_level: float) -> np.ndarray:
    """Scan lines (N,) of a flat-topped edge (:func:`flat_topped_edges`) whose bright plateau reaches
    ``clip_level`` (fraction of full scale): a plateau that is high but noisy is light the sensor stored."""
    high = np.isfinite(edges.bright) & (edges.bright >= 255.0 * clip_level - CLIP_TOLERANCE_GREY)
    return high & flat_topped_edges(edges)[edges.windows.edge]


def near_clip_edges(edges: BoardEdges, clip_level: float, cut: float = CUT) -> np.ndarray:
    """Edges (E,) whose median bright plateau lies above ``cut`` of the way from their dark plateau to
    ``clip_level``: in the band where the levels before a clip bend, so neither their profile nor their
    levels give the camera's blur or the board's contrast."""
    b, d = edges.bright_by_edge, edges.dark_by_edge
    return ~(np.isfinite(b) & np.isfinite(d)) | (b - d >= cut * (255.0 * clip_level - d))


#: fewest edges not clipped the blur and contrast are read from; with fewer, they are read from the set's
MIN_UNCLIPPED_EDGES = 5


def unclipped_blur_px(edge_blur_px: np.ndarray, clipped: np.ndarray) -> float:
    """The camera's blur (Gaussian sigma of the optics, px): the median of the edges' profile blurs over the
    edges not clipped; NaN where fewer than :data:`MIN_UNCLIPPED_EDGES` are not."""
    b = np.asarray(edge_blur_px, float)
    ok = np.isfinite(b) & ~clipped
    return float(np.median(b[ok])) if ok.sum() >= MIN_UNCLIPPED_EDGES else float("nan")


def _reader(model: PhotometricModel) -> Callable[[np.ndarray], np.ndarray]:
    return (lambda v: np.asarray(v, float)) if model.linear_response else model.light_from_grey


def unclipped_contrast(edges: BoardEdges, model: PhotometricModel, clipped: np.ndarray) -> float:
    """The board's contrast in the photograph: the median over the edges not ``clipped`` (E,) of their light
    square's light over their dark square's (plateaus, linear light of ``model``'s response); NaN where fewer
    than :data:`MIN_UNCLIPPED_EDGES` edges are not clipped and have a dark square above zero light."""
    read = _reader(model)
    b = read(edges.bright_by_edge / 255.0)
    d = read(edges.dark_by_edge / 255.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = b / d
    ok = ~clipped & np.isfinite(r) & (d > 0) & (r > 1)
    return float(np.median(r[ok])) if ok.sum() >= MIN_UNCLIPPED_EDGES else float("nan")


def _tobit_sse(
    d: np.ndarray,
    y: np.ndarray,
    exact: np.ndarray,
    x0: np.ndarray,
    blur: float,
    amp: np.ndarray,
    model: PhotometricModel,
) -> np.ndarray:
    """Each line's censored misfit (light^2) with its edge at each of ``x0`` (lines, k): (lines, k)."""
    r = y[:, None, :] - amp[:, None, None] * edge_spread(d[:, None, :] - x0[:, :, None], blur, model)
    # exact samples count both ways; lower bounds only where the model stays under them
    return np.where(exact[:, None, :], r * r, np.maximum(r, 0.0) ** 2).sum(2)


def _censored_problem(
    edges: BoardEdges, lines: np.ndarray, contrast: float, model: PhotometricModel, cut: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each line's samples (distance px, light above its dark plateau), which are exact, and its step."""
    win = edges.windows
    read = _reader(model)
    dark = read(edges.dark[lines] / 255.0)
    top = read(edges.bright[lines] / 255.0)
    edge_dark = read(edges.dark_by_edge / 255.0)[win.edge[lines]]
    y = read(win.grey[lines] / 255.0) - dark[:, None]
    floor = top - dark
    amp = np.maximum((contrast - 1.0) * edge_dark, floor) if np.isfinite(contrast) else floor
    return win.distance_px()[lines], y, y < cut * floor[:, None], amp


def _best_x0(
    d: np.ndarray, y: np.ndarray, exact: np.ndarray, blur: float, amp: np.ndarray, model: PhotometricModel
) -> tuple[np.ndarray, np.ndarray]:
    """Each line's edge (px) with the least censored misfit, and that misfit (light^2)."""

    def sse(x0: np.ndarray) -> np.ndarray:
        return _tobit_sse(d, y, exact, x0, blur, amp, model)

    def parabola_step(x0: np.ndarray, s0: np.ndarray, s1: np.ndarray, s2: np.ndarray, h: float) -> np.ndarray:
        # the vertex of the parabola through the misfits at x0 - h, x0, x0 + h, at most h away
        return x0 + h * parabola_vertex_step(s0, s1, s2)

    rows = np.arange(y.shape[0])
    grid = sse(np.broadcast_to(_X0_GRID, (y.shape[0], _X0_GRID.size)))
    k = np.clip(np.argmin(grid, 1), 1, _X0_GRID.size - 2)
    # two parabola steps: the grid's spacing (on the grid's own misfits), then a twentieth of it
    h = _X0_GRID[1] - _X0_GRID[0]
    x0 = parabola_step(_X0_GRID[k], grid[rows, k - 1], grid[rows, k], grid[rows, k + 1], h)
    fine = 0.05 * h
    s0, s1, s2 = sse(np.stack([x0 - fine, x0, x0 + fine], 1)).T
    x0 = parabola_step(x0, s0, s1, s2, fine)
    return x0, sse(x0[:, None])[:, 0]


#: the range a photograph's clipped edges' blur is searched in (Gaussian sigma of the optics, px), and the most
#: scan lines it is read from (evenly spread over the photograph's clipped lines)
CENSORED_BLUR_RANGE_PX = (0.3, 3.0)
CENSORED_BLUR_LINES = 300


def censored_blur_px(
    edges: BoardEdges, lines: np.ndarray, contrast: float, model: PhotometricModel, cut: float = CUT
) -> float:
    """The camera's blur (Gaussian sigma of the optics, px) read from a photograph's clipped scan lines
    ``lines`` with their true step known (the board's ``contrast``): the blur whose censored fits (module
    docstring) leave the least misfit summed over the lines, each line's edge free. With the step fixed, the
    foot's width gives the blur; with it free, a wider blur and a taller step fit the same foot. NaN without
    a contrast or with fewer than ten lines of three samples below the cut."""
    lines = np.asarray(lines, int)
    if not np.isfinite(contrast) or lines.size < 10:
        return float("nan")
    pick = lines[np.unique(np.linspace(0, lines.size - 1, min(lines.size, CENSORED_BLUR_LINES)).astype(int))]
    d, y, exact, amp = _censored_problem(edges, pick, contrast, model, cut)
    ok = exact.sum(1) >= 3
    if ok.sum() < 10:
        return float("nan")
    d, y, exact, amp = d[ok], y[ok], exact[ok], amp[ok]
    res = minimize_scalar(
        lambda b: float(_best_x0(d, y, exact, float(b), amp, model)[1].sum()),
        bounds=CENSORED_BLUR_RANGE_PX,
        method="bounded",
        options={"xatol": 0.003},
    )
    return float(res.x)


def censored_offsets_px(
    edges: BoardEdges,
    lines: np.ndarray,
    blur_px: float,
    contrast: float,
    model: PhotometricModel,
    cut: float = CUT,
) -> np.ndarray:
    """Offset (px, + towards bright) of each scan line in ``lines`` (indices) by the censored fit (module
    docstring) with the camera's blur ``blur_px`` and the board's ``contrast`` (light over dark square; NaN:
    the clipped step), in the linear light of ``model``'s response; NaN where fewer than three samples are
    below the cut."""
    lines = np.asarray(lines, int)
    if lines.size == 0:
        return np.zeros(0)
    d, y, exact, amp = _censored_problem(edges, lines, contrast, model, cut)
    x0 = _best_x0(d, y, exact, blur_px, amp, model)[0]
    return np.where(exact.sum(1) >= 3, x0, np.nan)


def clip_candidates(brights: np.ndarray) -> np.ndarray:
    """Clip levels (fraction of full scale) worth trying for plateaus ``brights`` (grey): from the median
    plateau up to the highest ones, where a clip piles the plateaus."""
    b = np.asarray(brights, float)
    b = b[np.isfinite(b)]
    if b.size == 0:
        return np.array([1.0])
    q = np.percentile(b, [50, 65, 75, 85, 90, 95, 98, 99.5]) / 255.0
    return np.unique(np.clip(np.round(q * 255.0) / 255.0, 0.2, 1.0))


def white_starts(brights: np.ndarray) -> list[tuple[float, float]]:
    """``(shoulder, white_level)`` pairs (fraction of full scale) worth starting a soft saturation's fit from,
    for plateaus ``brights`` (grey): white levels just above the highest plateaus, knees from 0.1 to 0.35
    below them, so that the shoulder reaches the brighter edges."""
    b = np.asarray(brights, float)
    b = b[np.isfinite(b)]
    top = float(np.percentile(b, 99.5)) / 255.0 if b.size else 1.0
    return [
        (w - span, w)
        for w in sorted({min(1.0, top + d) for d in (0.005, 0.02, 0.05)})
        for span in (0.1, 0.2, 0.35)
    ]
