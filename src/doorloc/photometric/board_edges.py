"""The straight square edges of a chessboard photograph, placed by doorloc's edge estimator and by the board.

A chessboard's inner corners are X-junctions: point-symmetric, so neither an even blur nor any response
curve moves them. The edge between two neighbouring inner corners is a straight line on the board, so its
true image is the camera's distortion applied to the straight line between the two corners' undistorted
positions (not the chord between them: on a distorted view the chord misses the edge by up to a few
hundredths of a pixel). What an edge estimator reports against that curve is its offset.

Each edge is measured on integer scan lines across its middle part (a fraction ``middle`` of its length,
away from the corners' other edges): image columns for an edge nearer horizontal, rows otherwise, as
:func:`doorloc.vision.edges.subpixel_edges` works. The signed offset is measured along the edge's normal,
positive towards the brighter square. The raw window of grey levels on each scan line is kept with its
distance from the true edge for the profile model (:mod:`doorloc.photometric.profiles`).

Units: pixels in OpenCV's convention (origin at the centre of the top-left pixel); grey levels on the
0-255 scale; ``px_per_mm`` is the board's scale across the edge (pixels per board millimetre).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from doorloc.calib.camera import CameraModel
from doorloc.vision.edges import subpixel_edges

__all__ = [
    "EdgeWindows",
    "BoardEdges",
    "EdgeSettings",
    "board_edge_curves",
    "measure_board_edges",
    "per_edge_median",
    "darkest_plateau",
]


@dataclass(frozen=True)
class EdgeSettings:
    """How edges are placed: the area estimator's window half-width and plateau (px) and the middle part
    of each edge used (fraction of the corner-to-corner length)."""

    half: int = 4
    plateau: int = 3
    middle: float = 0.4

    @property
    def window(self) -> int:
        """Samples in one scan line's window (plateaus included)."""
        return 2 * (self.half + self.plateau) + 1


@dataclass(frozen=True)
class EdgeWindows:
    """The true edges of one photograph, sampled on scan lines (one row per scan line).

    Attributes
    ----------
    edge : ndarray (N,) int
        Which edge (index into the per-edge arrays of :class:`BoardEdges`).
    axis : ndarray (N,) bool
        True where the scan line is an image column (near-horizontal edge).
    scan : ndarray (N,) int
        Scan-line coordinate (u for a column, v for a row).
    true_along : ndarray (N,) float
        The true edge's position along the scan line, px.
    cos : ndarray (N,) float
        Cosine between the scan line and the edge's normal (along-scan px times it = normal px).
    bright_sign : ndarray (N,) float
        +1 where grey rises along the scan line, -1 where it falls.
    start : ndarray (N,) int
        Along-coordinate of the window's first sample.
    grey : ndarray (N, L) float
        The window's raw grey levels.
    """

    edge: np.ndarray
    axis: np.ndarray
    scan: np.ndarray
    true_along: np.ndarray
    cos: np.ndarray
    bright_sign: np.ndarray
    start: np.ndarray
    grey: np.ndarray

    def distance_px(self) -> np.ndarray:
        """Each window sample's signed distance from the true edge along its normal, px, + towards bright (N, L)."""
        k = np.arange(self.grey.shape[1])[None, :] + self.start[:, None]
        return (k - self.true_along[:, None]) * (self.cos * self.bright_sign)[:, None]

    def image_rows(self) -> np.ndarray:
        """Each window sample's image row (N, L): a column's window runs down the rows, a row's lies on one."""
        k = np.arange(self.grey.shape[1])[None, :]
        return np.where(self.axis[:, None], self.start[:, None] + k, self.scan[:, None] + 0 * k)

    def field_sign(self) -> np.ndarray:
        """Each window sample's interlaced field: +1 on an even image row (0, 2, ..), -1 on an odd one (N, L)."""
        return np.where(self.image_rows() % 2 == 0, 1.0, -1.0)

    def subset(self, mask: np.ndarray) -> EdgeWindows:
        return EdgeWindows(*(getattr(self, f)[mask] for f in self.__dataclass_fields__))


@dataclass(frozen=True)
class BoardEdges:
    """One photograph's square edges: per-edge geometry and per-scan-line estimates.

    Per edge (E,): ``mid_px`` (E, 2) the edge's middle in the image; ``normal`` (E, 2) its unit normal
    towards the bright square; ``px_per_mm`` the board's scale across it; ``length_px`` corner to corner.
    Per scan line (N, in ``windows``): ``offset_px`` the estimator's signed offset from the true edge along
    the normal, + towards bright (NaN where the estimator gave none); ``dark``, ``bright`` the plateau levels
    (grey); ``noise`` the plateau spread (grey). ``along_board_rows`` (E,): whether the edge joins two corners
    of one row of the board, so that it runs along the board's rows (None where not known).
    """

    image: str
    image_size: tuple[int, int]
    mid_px: np.ndarray
    normal: np.ndarray
    px_per_mm: np.ndarray
    length_px: np.ndarray
    windows: EdgeWindows
    offset_px: np.ndarray
    dark: np.ndarray
    bright: np.ndarray
    noise: np.ndarray
    along_board_rows: np.ndarray | None = None

    @property
    def n_edges(self) -> int:
        return int(self.mid_px.shape[0])

    @cached_property
    def bright_by_edge(self) -> np.ndarray:
        """Each edge's median bright plateau over its scan lines, grey (E,; NaN where none). Read-only: a
        model fit asks for it at every trial of its parameters."""
        return self._by_edge(self.bright)

    @cached_property
    def dark_by_edge(self) -> np.ndarray:
        """Each edge's median dark plateau over its scan lines, grey (E,; NaN where none). Read-only."""
        return self._by_edge(self.dark)

    def _by_edge(self, x: np.ndarray) -> np.ndarray:
        out = per_edge_median(self.windows.edge, x, self.n_edges)
        out.flags.writeable = False
        return out

    def board_turned(self) -> bool | None:
        """Whether the board lies turned by about a quarter turn in the image: most scan lines of the edges
        along the board's rows run along the image's rows (those edges stand near-vertical). None where the
        edges' board directions are not known or none of them was measured. A cause that acts on one
        direction of edges in the image (a camera's scan lines) and one that acts on one direction on the
        board (its print) are told apart only by photographs turned both ways."""
        if self.along_board_rows is None:
            return None
        on_rows = np.asarray(self.along_board_rows, bool)[self.windows.edge]
        if not on_rows.any():
            return None
        return bool(np.mean(~self.windows.axis[on_rows]) > 0.5)

    def median_offset_px(self) -> float:
        """The photograph's figure: the median signed offset over all its edges' scan lines, px."""
        ok = np.isfinite(self.offset_px)
        return float(np.median(self.offset_px[ok])) if ok.any() else float("nan")

    def edge_offsets_px(self) -> np.ndarray:
        """Median offset of each edge over its scan lines, px (E,)."""
        return per_edge_median(self.windows.edge, self.offset_px, self.n_edges)

    def plateau_spread_rms(self, plateau: int, keep: np.ndarray | None = None) -> float:
        """What a flat square's grey levels vary by, as an RMS over the windows (grey levels): each window's
        two plateau runs (``plateau`` samples at its ends) about their own means, with the degrees of freedom
        the means take counted (so pure noise of sigma s gives s). Sensor noise, the print's texture, JPEG's
        blocks: everything no edge model can draw. ``noise`` is the same spread per scan line, whose median
        the check quotes; an RMS of a heavy-tailed spread lies well above its median, and this is the figure a
        profile misfit (an RMS over the windows) compares with. ``keep`` (N,) selects scan lines; NaN where
        none is left or ``plateau`` < 2."""
        g = self.windows.grey if keep is None else self.windows.grey[np.asarray(keep)]
        if plateau < 2 or g.shape[0] == 0 or 2 * plateau > g.shape[1]:
            return float("nan")
        runs = (g[:, :plateau], g[:, -plateau:])
        sq = sum(float(((r - r.mean(axis=1, keepdims=True)) ** 2).sum()) for r in runs)
        return float(np.sqrt(sq / (2 * g.shape[0] * (plateau - 1))))


def per_edge_median(edge: np.ndarray, x: np.ndarray, n: int) -> np.ndarray:
    """Median of ``x`` over each edge's scan lines (``edge`` the edge of each, ``n`` edges; NaN where none)."""
    out = np.full(n, np.nan)
    ok = np.isfinite(x)
    e, v = np.asarray(edge)[ok], np.asarray(x, float)[ok]
    order = np.lexsort((v, e))  # by edge, then by value within each edge
    v = v[order]
    count = np.bincount(e, minlength=n)
    start = np.concatenate([[0], np.cumsum(count)[:-1]])
    has = count > 0
    lo = start[has] + (count[has] - 1) // 2
    hi = start[has] + count[has] // 2
    out[has] = 0.5 * (v[lo] + v[hi])
    return out


#: the share of a camera's edges whose dark plateau may lie below :func:`darkest_plateau` (one edge's level
#: in twenty: a few squares in shadow or a corner of the frame are not the camera's black)
DARKEST_PLATEAU_SHARE = 0.05
#: grey levels :func:`darkest_plateau` lies below that share's level (an edge's median plateau carries its
#: rounding and a level of the sensor's fixed pattern)
DARKEST_PLATEAU_MARGIN_GREY = 2.0


def darkest_plateau(edges: Sequence[BoardEdges]) -> float:
    """The darkest level (fraction of full scale) the photographs ``edges`` store on their dark squares:
    the :data:`DARKEST_PLATEAU_SHARE` quantile of their edges' dark plateaus less
    :data:`DARKEST_PLATEAU_MARGIN_GREY`; 0 where none is measured. A response may read levels below it as
    no light, not levels above."""
    d = np.concatenate([np.empty(0)] + [np.asarray(e.dark_by_edge, float) for e in edges])
    d = d[np.isfinite(d)]
    if not d.size:
        return 0.0
    return max(0.0, float(np.quantile(d, DARKEST_PLATEAU_SHARE)) - DARKEST_PLATEAU_MARGIN_GREY) / 255.0


def board_edge_curves(
    corners_px: np.ndarray, cols: int, rows: int, camera: CameraModel, t: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The true image of every square edge between neighbouring inner corners, at fractions ``t`` of its length.

    ``corners_px`` (cols*rows, 2) in the board's row-major order. The straight line between the two corners'
    undistorted (ideal pinhole) pixels is sampled at ``t`` and distorted back (a projective map keeps a line
    straight; sampling it evenly in the ideal image instead of on the board moves the points along the edge
    only, never off it). Returns ``(curves (E, T, 2) px, pairs (E, 2) corner indices)``, horizontal
    neighbours first.
    """
    idx = np.arange(cols * rows).reshape(rows, cols)
    pairs = np.concatenate(
        [
            np.stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()], 1),
            np.stack([idx[:-1, :].ravel(), idx[1:, :].ravel()], 1),
        ]
    )
    ideal = camera.undistort_pixels(np.asarray(corners_px, float))
    p, q = ideal[pairs[:, 0]], ideal[pairs[:, 1]]
    line = p[:, None, :] + (q - p)[:, None, :] * np.asarray(t, float)[None, :, None]
    return camera.distort_pixels(line.reshape(-1, 2)).reshape(line.shape), pairs


def measure_board_edges(
    gray: np.ndarray,
    corners_px: np.ndarray,
    cols: int,
    rows: int,
    square_mm: float,
    camera: CameraModel,
    *,
    image: str = "",
    settings: EdgeSettings = EdgeSettings(),
    lut: np.ndarray | None = None,
) -> BoardEdges:
    """Place every square edge of a chessboard photograph with the area estimator and measure its offset.

    Parameters
    ----------
    gray : ndarray (H, W) uint8
        The photograph in grey levels.
    corners_px : ndarray (cols*rows, 2)
        Its inner corners, row-major board order (the reference, never used to place an edge: they set the
        scan lines and the true line only).
    cols, rows, square_mm
        The board: inner corners per row, rows, square side (mm).
    camera : CameraModel
        The calibration (its distortion bends the true edges).
    lut : ndarray or None
        Grey level to linear light table (256 float32) the estimator reads the pixels through; None: linear.
    """
    s = settings
    n_t = 33
    t = 0.5 + s.middle * (np.linspace(0.0, 1.0, n_t) - 0.5)
    curves, pairs = board_edge_curves(corners_px, cols, rows, camera, t)
    c = np.asarray(corners_px, float)
    length = np.linalg.norm(c[pairs[:, 1]] - c[pairs[:, 0]], axis=1)
    n_edges = pairs.shape[0]
    h, w = gray.shape[:2]
    rows_e, rows_ax, rows_scan, rows_true, rows_cos = [], [], [], [], []
    for i in range(n_edges):
        if not (np.isfinite(length[i]) and s.half + s.plateau <= 0.3 * length[i]):
            # a window (plateaus included) longer than 0.3 of the square reaches the square's other edges
            # from the middle of this one (at 45 degrees): a square too small to read this edge on
            continue
        cu, cv = curves[i, :, 0], curves[i, :, 1]
        d = curves[i, -1] - curves[i, 0]
        col = abs(d[0]) >= abs(d[1])  # near-horizontal: profiles along image columns
        sc, al = (cu, cv) if col else (cv, cu)
        order = np.argsort(sc)
        sc, al = sc[order], al[order]
        scans = np.arange(int(np.ceil(sc[0])), int(np.floor(sc[-1])) + 1)
        if scans.size == 0:
            continue
        true_al = np.interp(scans, sc, al)
        slope = np.gradient(al, sc) if sc.size > 1 else np.zeros_like(sc)
        cosv = 1.0 / np.sqrt(1.0 + np.interp(scans, sc, slope) ** 2)
        rows_e.append(np.full(scans.size, i))
        rows_ax.append(np.full(scans.size, col))
        rows_scan.append(scans)
        rows_true.append(true_al)
        rows_cos.append(cosv)
    edge = np.concatenate(rows_e)
    axis = np.concatenate(rows_ax)
    scan = np.concatenate(rows_scan)
    true_along = np.concatenate(rows_true)
    cos = np.concatenate(rows_cos)
    n = edge.size
    offset = np.full(n, np.nan)
    dark = np.full(n, np.nan)
    bright = np.full(n, np.nan)
    noise = np.full(n, np.nan)
    sign = np.zeros(n)
    start = np.round(true_along).astype(int) - s.half - s.plateau
    img = np.ascontiguousarray(gray)
    for is_col in (True, False):
        sel = np.flatnonzero(axis == is_col)
        if sel.size == 0:
            continue
        es = subpixel_edges(
            img, "col" if is_col else "row", scan[sel], true_along[sel], s.half, s.plateau, lut=lut
        )
        sg = np.sign(es.step)
        sign[sel] = sg
        offset[sel] = np.where(es.valid, (es.along - true_along[sel]) * cos[sel] * sg, np.nan)
        dark[sel] = np.where(es.valid, es.bright - np.abs(es.step), np.nan)
        bright[sel] = np.where(es.valid, es.bright, np.nan)
        noise[sel] = es.noise
    # the raw windows (always the stored grey levels, whatever table placed the edges)
    k = np.arange(s.window)
    n_along = np.where(axis, int(h), int(w))
    n_scan = np.where(axis, int(w), int(h))
    along_idx = np.clip(start[:, None] + k[None, :], 0, (n_along - 1)[:, None])
    scan_idx = np.clip(scan, 0, n_scan - 1)[:, None]
    r = np.where(axis[:, None], along_idx, scan_idx)
    cc = np.where(axis[:, None], scan_idx, along_idx)
    grey = img[r, cc].astype(float)
    inside = (
        (start >= 0)
        & (start + s.window <= np.where(axis, h, w))
        & (scan >= 0)
        & (scan < np.where(axis, w, h))
    )
    ok = inside & (sign != 0)
    offset[~ok] = np.nan
    windows = EdgeWindows(edge, axis, scan, true_along, cos, np.where(sign == 0, 1.0, sign), start, grey)
    mid = curves[:, n_t // 2, :]
    tangent = curves[:, -1] - curves[:, 0]
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-12)
    normal = np.stack([-tangent[:, 1], tangent[:, 0]], 1)
    # orient each normal towards the bright side: along the scan line bright is +sign
    edge_sign = np.zeros(n_edges)
    np.add.at(edge_sign, edge, sign)
    along_dir = np.where(
        np.abs(tangent[:, 0]) >= np.abs(tangent[:, 1]), normal[:, 1], normal[:, 0]
    )  # the normal's component along its edge's scan axis
    flip = np.sign(edge_sign) * np.sign(along_dir)
    normal = normal * np.where(flip == 0, 1.0, flip)[:, None]
    return BoardEdges(
        image,
        (int(w), int(h)),
        mid,
        normal,
        length / float(square_mm),
        length,
        windows.subset(ok),
        offset[ok],
        dark[ok],
        bright[ok],
        noise[ok],
        pairs[:, 1] - pairs[:, 0] == 1,  # two neighbours in one row of the board's row-major corners
    )
