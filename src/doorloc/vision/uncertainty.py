"""The 1-sigma standard uncertainty of a located pose: fit noise + edge model + calibrations.

Every ``ok`` answer carries ``uncertainty: {x_mm, z_mm, yaw_deg}``, the quadrature sum of independent
terms (each also reported in ``diagnostics["uncertainty_terms"]``):

``fit``
    The joint line fit's standard errors from the residual scatter (image noise). The corner lies away
    from the centroid of the points that fix each line, so the angle's error moves it too: x and z take
    ``angle_sigma * lever`` in quadrature with the line's offset error.
``edge_model``
    What averaging over many scan lines does not remove, because it is the same on every scan line: the
    difference between the edge model and the real edge. Per line, the quadrature sum of

    - ``EDGE_MODEL_FLOOR_PX``: the area estimator's own residual bias on a clean, sharp step (sampled
      pixel phases, quantisation; the committed noise-free grid fixtures show 0.0004 mm RMS = 0.002 px);
    - ``BLUR_MODEL_FRACTION`` of the measured optical blur (Gaussian sigma, px): on blurred, noise-free
      rendered steps the edge sits 0.005-0.01 px outwards per px of blur (0.001-0.0035 mm at blur
      0.5-1.8 px), the same before and after the plateaus moved next to the window; a real lens's
      blur is not Gaussian nor the same across the edge, so this is kept as a doubt, not corrected;
    - the texture term, :func:`doorloc.vision.edges.texture_bias` (wood grain along the edge, measured
      on the texture beside the window);
    - ``JPEG_EDGE_DOUBT_PX`` where the image shows JPEG block artifacts
      (:func:`doorloc.vision.edges.block_artifact_ratio` above ``JPEG_BLOCK_RATIO``): the block
      quantization moves an edge that runs along a block row or column the same way on every scan line
      (0.01-0.07 px measured on nearly noise-free quality-88 renders, where no other term sees it), and
      an edge at a small angle to the blocks by an amount that drifts along it: its tilt
      (:func:`jpeg_tilt_sigma`) joins the line's texture tilt in the yaw;
    - any term that an edge model reports for itself in :attr:`EdgeModelTerms.extra_px` (the far-face
      fit today; an arris-offset or camera-response correction adds its doubt there, px across the
      edge, keyed by line name: ``"bottom"``, ``"reference"`` or ``"far"``).

    The line's total is reported as ``lines[i].model_sigma_mm``.
``calibration``
    The camera calibration's own uncertainty, propagated to x, z, yaw at the located corner through the
    projection's Jacobian (rotation-aligned, as ``doorloc calibrate`` reports it: the cell check's camera
    placement takes up what a rotation explains) and the back-projection's
    (:class:`doorloc.vision.metric.PlaneMap`), with the intrinsics' covariance saved in the calibration
    file (``intrinsics_covariance``). A cell whose
    camera carries no covariance (an inline camera matrix, an older calibration file) gets the default
    floor ``LocateConfig.calibration_sigma_px``: an isotropic projection error of that 1-sigma at the
    corner, and for the yaw a smooth error field that changes by ``sqrt(2)`` times it over half the
    image diagonal. Set it to 0 only for a camera known exactly (rendered images).
``cell``
    The camera's placement in the cell (the extrinsics, from the cell check): ``LocateConfig.cell_sigma_mm``
    and ``cell_sigma_deg``, as that check measured them (0 by default: a cell file says what its check found).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from doorloc.calib.calibrate import Candidate, free_param_names, projection_jacobian
from doorloc.calib.camera import CameraModel, PosedCamera
from doorloc.vision.metric import PlaneMap

__all__ = [
    "BLUR_MODEL_FRACTION",
    "EDGE_MODEL_FLOOR_PX",
    "JPEG_BLOCK_RATIO",
    "JPEG_EDGE_DOUBT_PX",
    "EdgeModelTerms",
    "calibration_pose_sigma",
    "combine",
    "corner_fit_sigma",
    "jpeg_tilt_sigma",
]

#: the area estimator's residual bias on a clean step, px across the edge (module docstring)
EDGE_MODEL_FLOOR_PX = 0.002

#: JPEG block artifacts: the ratio above which an image counts as JPEG-compressed, and the doubt then (px)
JPEG_BLOCK_RATIO = 1.3
JPEG_EDGE_DOUBT_PX = 0.03

#: edge-model doubt per px of optical blur (module docstring)
BLUR_MODEL_FRACTION = 0.01

#: OpenCV's order of the distortion coefficients (calibration covariance names)
_DIST_INDEX = {
    "k1": 0,
    "k2": 1,
    "p1": 2,
    "p2": 3,
    "k3": 4,
    "k4": 5,
    "k5": 6,
    "k6": 7,
    "s1": 8,
    "s2": 9,
    "s3": 10,
    "s4": 11,
}


@dataclass
class EdgeModelTerms:
    """Edge-model doubts per line, px across the edge (the ``edge_model`` term of the module docstring).

    Attributes
    ----------
    texture_px : dict[str, float]
        Texture bias 1-sigma per line (:func:`doorloc.vision.edges.texture_bias`).
    tilt : dict[str, float]
        Texture bias 1-sigma of each line's direction, px per px along the line.
    blur_px : float
        Optical blur (Gaussian sigma, px) measured on the image, for the blur term.
    extra_px : dict[str, dict[str, float]]
        Further named terms per line, px, filled by whatever edge model or correction knows its own
        doubt (e.g. ``extra_px["far"]["far_face"]``, ``extra_px["reference"]["arris"]``).
    """

    texture_px: dict[str, float] = field(default_factory=dict)
    tilt: dict[str, float] = field(default_factory=dict)
    blur_px: float = 0.0
    extra_px: dict[str, dict[str, float]] = field(default_factory=dict)

    def add_tilt(self, name: str, tilt: float) -> None:
        """Add an independent tilt doubt (px per px) to line ``name``'s, in quadrature (a non-finite one, or
        a non-finite tilt already there, counts as 0)."""
        t0 = self.tilt.get(name, 0.0)
        self.tilt[name] = math.hypot(t0 if math.isfinite(t0) else 0.0, tilt if math.isfinite(tilt) else 0.0)

    def line_sigma_px(self, name: str, without: tuple[str, ...] = ()) -> float:
        """Total edge-model 1-sigma of one line's offset, px (floor, texture and extra terms in quadrature),
        the extra terms named in ``without`` left out (a caller that combines them otherwise)."""
        t = self.texture_px.get(name, 0.0)
        blur = BLUR_MODEL_FRACTION * self.blur_px if math.isfinite(self.blur_px) else 0.0
        terms = [
            EDGE_MODEL_FLOOR_PX,
            blur,
            t if math.isfinite(t) else 0.0,
            *(v for k, v in self.extra_px.get(name, {}).items() if k not in without),
        ]
        return math.sqrt(sum(v * v for v in terms if math.isfinite(v)))


def jpeg_tilt_sigma(slope: float, scan_px: np.ndarray, doubt_px: float = JPEG_EDGE_DOUBT_PX) -> float:
    """1-sigma of a line's tilt (px per px) that JPEG's block quantisation gives it.

    The block grid is 8 px; an edge at ``slope`` (px across per px along) to it crosses one block column
    every ``8 / |slope|`` px along, and the quantisation's edge error, ``doubt_px`` RMS, changes with the
    edge's phase in its block. Taken as a sinusoid of that period and any phase, sampled on the line's scan
    lines ``scan_px`` (N,), the RMS over the phase of its least-squares slope is
    ``doubt_px * |sum d exp(i k d)| / sum d^2`` (``d`` the scan lines from their mean, ``k = 2 pi |slope| / 8``):
    about ``doubt_px * k`` on a short or nearly aligned line (one phase, slowly drifting), largest where the
    line spans about half a period, small over many.

    Why: the offset doubt alone left the yaw of JPEG frames under-claimed; on plain rendered doors (blur
    0.6-1.8 px, noise 0-2 grey levels, quality 80-95) their yaw was within 2 sigma for 80-93 % and up to
    6.2 sigma off, the same doors as PNG 97-100 %.

    Examples
    --------
    >>> s = np.arange(600.0)
    >>> jpeg_tilt_sigma(0.0, s)
    0.0
    >>> bool(jpeg_tilt_sigma(0.01, s) > jpeg_tilt_sigma(0.5, s))
    True
    """
    d = np.asarray(scan_px, np.float64)
    if d.size < 3 or not math.isfinite(slope):
        return 0.0
    d = d - d.mean()
    dd = float(d @ d)
    k = 2.0 * math.pi * abs(slope) / 8.0
    if dd <= 0 or k == 0.0:
        return 0.0
    return doubt_px * math.hypot(float(d @ np.sin(k * d)), float(d @ np.cos(k * d))) / dd


def corner_fit_sigma(offset_sigma_mm: float, angle_sigma_rad: float, lever_mm: float) -> float:
    """Fit 1-sigma of the corner along one line's normal: the offset's error (at the points' centroid) and
    the angle's error times the distance from that centroid to the corner, in quadrature."""
    return math.hypot(offset_sigma_mm, angle_sigma_rad * lever_mm)


def _candidate(names: tuple[str, ...], camera: CameraModel) -> tuple[Candidate, list[int]] | None:
    """The calibration model whose free intrinsics are ``names``, and the permutation into its order."""
    fixed = "f" in names
    dist = sorted(_DIST_INDEX[n] for n in names if n in _DIST_INDEX)
    if any(i >= camera.dist_coeffs.size for i in dist):
        return None
    c = Candidate("from_file", 0, max(camera.dist_coeffs.size, 5), tuple(dist), fixed)
    order = free_param_names(c)
    if sorted(order) != sorted(names):
        return None
    return c, [list(names).index(n) for n in order]


def calibration_pose_sigma(
    posed: PosedCamera,
    depth_y: float,
    corner_px: np.ndarray,
    yaw_deg: float,
    covariance: np.ndarray | None,
    names: list[str] | tuple[str, ...],
    fallback_sigma_px: float,
    scale_mm_per_px: float,
) -> tuple[float, float, float]:
    """1-sigma of (x_mm, z_mm, yaw_deg) that the camera calibration's uncertainty gives the located pose.

    With a covariance of the intrinsics (``names`` in its order, as :mod:`doorloc.calib.calibrate` saves
    it): how the pixel of a fixed ray moves with each intrinsic, less what a small rotation of the camera
    takes up over the whole image (the cell check fits the camera's placement with the same intrinsics,
    which absorbs that part: :func:`doorloc.calib.calibrate.projection_jacobian` ``aligned=True``), is
    taken at the corner pixel and at a pixel 40 mm along door +X; the plane's local Jacobian (central
    differences through :class:`doorloc.vision.metric.PlaneMap`) turns it into x, z and yaw, and
    ``J C J^T`` gives their covariance. Without one (or with names that no calibration model has), the
    default floor of the module docstring.
    """
    names = tuple(names)
    cand = _candidate(names, posed.camera) if covariance is not None and names else None
    if cand is None or covariance is None:
        s = fallback_sigma_px
        w, h = posed.camera.image_size
        yaw = math.degrees(s * math.sqrt(2.0) / (0.5 * math.hypot(w, h)))
        return s * scale_mm_per_px, s * scale_mm_per_px, yaw
    c, perm = cand
    C = np.asarray(covariance, float)[np.ix_(perm, perm)]
    pm = PlaneMap(posed, depth_y)
    corner = pm.to_plane(np.asarray(corner_px, float).reshape(1, 2))[0]
    t = math.radians(yaw_deg)
    second = corner + 40.0 * np.array([math.cos(t), math.sin(t)])
    pix = pm.to_image(np.stack([corner, second]))
    w, h = posed.camera.image_size
    gu, gv = np.meshgrid(np.linspace(0, w - 1, 9), np.linspace(0, h - 1, 7))
    grid = np.stack([gu.ravel(), gv.ravel()], axis=1)
    Jp = projection_jacobian(posed.camera, c, np.concatenate([pix, grid]), aligned=True)[:2]  # (2, 2, n)
    if not np.all(np.isfinite(Jp)):
        return calibration_pose_sigma(
            posed, depth_y, corner_px, yaw_deg, None, (), fallback_sigma_px, scale_mm_per_px
        )
    # The ray seen at a fixed pixel moves by -J dp: the located plane point moves by -(dXZ/duv) J dp.
    G = []
    for p in pix:
        d = pm.to_plane(np.array([p + [0.5, 0], p - [0.5, 0], p + [0, 0.5], p - [0, 0.5]]))
        G.append(np.stack([d[0] - d[1], d[2] - d[3]], axis=1))  # (2 plane, 2 pixel)
    dA = -G[0] @ Jp[0]  # (2, n): corner X, Z per parameter
    dB = -G[1] @ Jp[1]
    # yaw = atan2(dZ, dX) of B - A, linearised about the nominal direction
    u = np.array([-math.sin(t), math.cos(t)]) / 40.0
    J = np.vstack([dA, np.degrees(u @ (dB - dA))[None, :]])
    cov = J @ C @ J.T
    sx, sz, sy = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return float(sx), float(sz), float(sy)


def combine(terms: dict[str, tuple[float, float, float]]) -> tuple[float, float, float]:
    """Quadrature sum of independent (x_mm, z_mm, yaw_deg) 1-sigma terms."""
    a = np.array([[v if math.isfinite(v) else 0.0 for v in t] for t in terms.values()], float)
    s = np.sqrt((a * a).sum(axis=0))
    return float(s[0]), float(s[1]), float(s[2])
