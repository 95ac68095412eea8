"""Independent check of the renderer's geometric exactness: where is a rendered straight edge?

A straight 3-D edge between a bright and a dark region is rendered, and its position in each image
column is measured by the *area method*: for a box-filtered image, the sum over a column window of the
normalised intensity ``(I - I_dark) / (I_bright - I_dark)`` equals the length of the window on the bright
side, i.e. the edge's mean position over that column's width. That is compared with the analytic
projection of the 3-D edge through the camera model (distortion included), averaged over the same
column width. Used by tests and by ``bench/bench_render_edges.py``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from doorloc.calib.camera import CameraModel
from doorloc.sim.raster import GridTexture, Surface, render_radiance

__all__ = ["EdgeCheck", "edge_agreement", "measure_edge"]

BRIGHT, DARK = 0.8, 0.1


@dataclass(frozen=True)
class EdgeCheck:
    """Result of :func:`edge_agreement`: per-column residuals (measured - analytic), px."""

    angle_deg: float
    kind: str
    residuals_px: np.ndarray

    @property
    def rms_px(self) -> float:
        return float(np.sqrt(np.mean(self.residuals_px**2)))


def _plane_point(origin, normal, q):
    """Intersect the rays of ideal points q (n, 2) with a plane (camera frame)."""
    rays = np.concatenate([q, np.ones((len(q), 1))], axis=1)
    lam = (origin @ normal) / (rays @ normal)
    return rays * lam[:, None]


def edge_agreement(
    camera: CameraModel,
    angle_deg: float,
    *,
    kind: str = "outline",
    v_at_centre: float | None = None,
    tilt_deg: float = 20.0,
    margin_cols: int = 20,
) -> EdgeCheck:
    """Render one straight edge at ``angle_deg`` to the image rows and measure it column by column.

    Parameters
    ----------
    camera : CameraModel
        The camera (with or without distortion).
    angle_deg : float
        Angle of the edge to the pixel rows in the ideal image, degrees (|angle| < 45).
    kind : str
        ``"outline"``: the edge is a polygon edge of a bright face over a dark background (a door
        silhouette); ``"texture"``: the edge is a texture line inside one face (a shadow or paint edge).
    v_at_centre : float or None
        Row where the edge crosses the image's middle column (default: 3/4 of the height, away from the
        principal point so that distortion bends the edge).
    tilt_deg : float
        Tilt of the plane carrying the edge about the camera x axis.
    margin_cols : int
        Columns skipped at each side of the image.
    """
    w, h = camera.image_size
    v_mid = 0.75 * h if v_at_centre is None else v_at_centre
    # the edge is straight in the ideal image: through the ideal point of (w/2, v_mid), at angle_deg
    q_a = camera.undistort(np.array([[w / 2, v_mid]]))[0]
    a = math.radians(angle_deg)
    d = np.array([math.cos(a), math.sin(a)])
    nrm = np.array([-d[1], d[0]])  # points to +v (down): the bright side
    span = 2.0 * np.max(np.abs(camera.pixel_to_normalized_distorted(camera.image_corners_px())))
    tilt = math.radians(tilt_deg)
    p_normal = np.array([0.0, math.sin(tilt), -math.cos(tilt)])
    p_origin = np.array([0.0, 0.0, 1000.0])
    A, B = _plane_point(p_origin, p_normal, np.array([q_a - span * d, q_a + span * d]))
    s_axis = (B - A) / np.linalg.norm(B - A)
    t_axis = np.cross(p_normal, s_axis)
    C = _plane_point(p_origin, p_normal, np.array([q_a + 0.01 * nrm]))[0]
    if (C - A) @ t_axis < 0:
        t_axis = -t_axis  # +t towards the bright side
    # the same far-away quad for both kinds, in (s, t) about A
    corners_q = np.array(
        [q_a - span * d, q_a + span * d, q_a + span * d + span * nrm, q_a - span * d + span * nrm]
    )
    P = _plane_point(p_origin, p_normal, corners_q)
    st = np.stack([(P - A) @ s_axis, (P - A) @ t_axis], axis=1)
    if kind == "outline":
        surface = Surface(A, s_axis, t_axis, st, GridTexture.uniform(BRIGHT), 1.0, None, "edge")
        bg = DARK
    elif kind == "texture":
        st_big = st.copy()
        Pm = _plane_point(p_origin, p_normal, corners_q - span * nrm)
        st_big[[0, 1]] = np.stack([(Pm[[0, 1]] - A) @ s_axis, (Pm[[0, 1]] - A) @ t_axis], axis=1)
        tex = GridTexture(np.empty(0), np.array([0.0]), np.array([[DARK, BRIGHT]]))
        surface = Surface(A, s_axis, t_axis, st_big, tex, 1.0, None, "edge")
        bg = 0.5
    else:
        raise ValueError(f"kind must be 'outline' or 'texture', got {kind!r}")
    img = render_radiance(camera, [surface], bg)

    # analytic curve: dense points of the 3-D edge projected through the full camera model
    lam = np.linspace(0.0, 1.0, 200001)
    curve = camera.project(A[None] + lam[:, None] * (B - A)[None])
    cols = np.arange(margin_cols, w - margin_cols)
    res = measure_edge(img, curve, cols, dark=DARK, bright=BRIGHT, along="columns", bright_after=True)
    return EdgeCheck(angle_deg, kind, res)


def measure_edge(
    image: np.ndarray,
    curve_px: np.ndarray,
    lines: np.ndarray,
    *,
    dark: float,
    bright: float,
    along: str = "columns",
    bright_after: bool = True,
    half_window: int = 6,
) -> np.ndarray:
    """Residuals (area-method measured - analytic) of one edge, per image column or row, px.

    Parameters
    ----------
    image : ndarray, shape (H, W), float
        Box-filtered radiance with exactly two levels near the edge.
    curve_px : ndarray, shape (n, 2)
        Dense samples (spacing << 1 px) of the analytic edge in pixel coordinates (u, v).
    lines : ndarray of int
        Columns (``along="columns"``: the edge is a graph v(u)) or rows (``"rows"``: u(v)) to measure.
    dark, bright : float
        Radiance on either side.
    bright_after : bool
        The bright side lies at larger v (columns) or larger u (rows).
    half_window : int
        Pixels of window beyond the edge on each side.

    Returns
    -------
    ndarray
        One residual per measured line (lines whose window leaves the image are skipped).
    """
    c = np.asarray(curve_px, float)
    c = c[np.all(np.isfinite(c), axis=1)]
    x, y = (c[:, 0], c[:, 1]) if along == "columns" else (c[:, 1], c[:, 0])
    order = np.argsort(x)
    x, y = x[order], y[order]
    img = image if along == "columns" else image.T
    n_across = img.shape[0]
    sub = (np.arange(64) + 0.5) / 64 - 0.5
    # the area method measures the mean edge position over the line's one-pixel width
    analytic = np.interp(lines[:, None] + sub[None, :], x, y).mean(axis=1)
    res = []
    for k, a in zip(lines, analytic, strict=True):
        c0, c1 = int(math.floor(a)) - half_window, int(math.ceil(a)) + half_window
        if c0 < 0 or c1 >= n_across:
            continue
        frac = (img[c0 : c1 + 1, k] - dark) / (bright - dark)
        measured = (c1 + 0.5) - frac.sum() if bright_after else (c0 - 0.5) + frac.sum()
        res.append(measured - a)
    return np.array(res)
