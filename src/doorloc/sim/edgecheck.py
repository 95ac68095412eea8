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

__all__ = ["EdgeCheck", "edge_agreement"]

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
    camera: CameraModel, angle_deg: float, *, kind: str = "outline", v_at_centre: float | None = None,
    tilt_deg: float = 20.0, margin_cols: int = 20,
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
    corners_q = np.array([q_a - span * d, q_a + span * d, q_a + span * d + span * nrm, q_a - span * d + span * nrm])
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
    curve = curve[np.all(np.isfinite(curve), axis=1)]
    order = np.argsort(curve[:, 0])
    cu, cv = curve[order, 0], curve[order, 1]
    cols = np.arange(margin_cols, w - margin_cols)
    sub = (np.arange(64) + 0.5) / 64 - 0.5
    analytic = np.interp(cols[:, None] + sub[None, :], cu, cv).mean(axis=1)
    # measured: area method over a window of rows around the edge in each column
    res = []
    for u, va in zip(cols, analytic, strict=True):
        v0, v1 = int(math.floor(va)) - 6, int(math.ceil(va)) + 6
        if v0 < 0 or v1 >= h:
            continue
        frac = (img[v0 : v1 + 1, u] - DARK) / (BRIGHT - DARK)
        measured = (v1 + 0.5) - frac.sum()
        res.append(measured - va)
    return EdgeCheck(angle_deg, kind, np.array(res))
