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
    - any term that an edge model reports for itself in :attr:`EdgeModelTerms.extra_px` (the far-face
      fit today; an arris-offset or camera-response correction adds its doubt there, px across the
      edge, keyed by line name: ``"bottom"``, ``"reference"`` or ``"far"``).

    The line's total is reported as ``lines[i].model_sigma_mm``.
``calibration``
    The camera calibration's own uncertainty, propagated to x, z, yaw at the located corner by central
    differences through the back-projection (:class:`doorloc.vision.metric.PlaneMap`) with the
    intrinsics' covariance saved in the calibration file (``intrinsics_covariance``). A cell whose
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

from doorloc.calib.camera import CameraModel, PosedCamera
from doorloc.vision.metric import PlaneMap

__all__ = ["BLUR_MODEL_FRACTION", "EDGE_MODEL_FLOOR_PX", "EdgeModelTerms", "calibration_pose_sigma", "combine", "corner_fit_sigma"]

#: the area estimator's residual bias on a clean step, px across the edge (module docstring)
EDGE_MODEL_FLOOR_PX = 0.002

#: edge-model doubt per px of optical blur (module docstring)
BLUR_MODEL_FRACTION = 0.01

#: OpenCV's order of the distortion coefficients (calibration covariance names)
_DIST_INDEX = {"k1": 0, "k2": 1, "p1": 2, "p2": 3, "k3": 4, "k4": 5, "k5": 6, "k6": 7,
               "s1": 8, "s2": 9, "s3": 10, "s4": 11}


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

    def line_sigma_px(self, name: str) -> float:
        """Total edge-model 1-sigma of one line's offset, px (floor, texture and extra terms in quadrature)."""
        t = self.texture_px.get(name, 0.0)
        blur = BLUR_MODEL_FRACTION * self.blur_px if math.isfinite(self.blur_px) else 0.0
        terms = [EDGE_MODEL_FLOOR_PX, blur, t if math.isfinite(t) else 0.0, *self.extra_px.get(name, {}).values()]
        return math.sqrt(sum(v * v for v in terms if math.isfinite(v)))


def corner_fit_sigma(offset_sigma_mm: float, angle_sigma_rad: float, lever_mm: float) -> float:
    """Fit 1-sigma of the corner along one line's normal: the offset's error (at the points' centroid) and
    the angle's error times the distance from that centroid to the corner, in quadrature."""
    return math.hypot(offset_sigma_mm, angle_sigma_rad * lever_mm)


def _perturbed(camera: CameraModel, name: str, delta: float) -> CameraModel:
    K = camera.camera_matrix.copy()
    d = np.zeros(12)
    d[: camera.dist_coeffs.size] = camera.dist_coeffs
    if name == "f":  # fixed aspect ratio: fx and fy change together (delta on fy, as calibrate names it)
        K[0, 0] *= 1.0 + delta / K[1, 1]
        K[1, 1] += delta
    elif name in ("fx", "fy", "cx", "cy"):
        i, j = {"fx": (0, 0), "fy": (1, 1), "cx": (0, 2), "cy": (1, 2)}[name]
        K[i, j] += delta
    else:
        d[_DIST_INDEX[name]] += delta
    n = max(camera.dist_coeffs.size, _DIST_INDEX.get(name, -1) + 1)
    n = next(k for k in (0, 4, 5, 8, 12) if k >= n)
    return CameraModel.from_values(K, d[:n], camera.image_size, camera.observed_radius_px)


def calibration_pose_sigma(posed: PosedCamera, depth_y: float, corner_px: np.ndarray, yaw_deg: float,
                           covariance: np.ndarray | None, names: list[str] | tuple[str, ...],
                           fallback_sigma_px: float, scale_mm_per_px: float) -> tuple[float, float, float]:
    """1-sigma of (x_mm, z_mm, yaw_deg) that the camera calibration's uncertainty gives the located pose.

    With a covariance of the intrinsics (``names`` in its order, as :mod:`doorloc.calib.calibrate` saves
    it), the corner pixel and a second pixel 40 mm along door +X are back-projected onto the plane
    ``Y = depth_y`` through cameras moved by +-1 sigma along each parameter (central differences), and
    ``J C J^T`` gives the pose covariance; the image measurement is held fixed. Without one, the
    default floor of the module docstring.
    """
    if covariance is None or len(names) == 0:
        s = fallback_sigma_px
        w, h = posed.camera.image_size
        yaw = math.degrees(s * math.sqrt(2.0) / (0.5 * math.hypot(w, h)))
        return s * scale_mm_per_px, s * scale_mm_per_px, yaw
    base = PlaneMap(posed, depth_y)
    corner = base.to_plane(np.asarray(corner_px, float).reshape(1, 2))[0]
    t = math.radians(yaw_deg)
    second = corner + 40.0 * np.array([math.cos(t), math.sin(t)])
    pix = base.to_image(np.stack([corner, second]))

    def pose_with(camera: CameraModel) -> np.ndarray:
        pm = PlaneMap(PosedCamera(camera, posed.extrinsics), depth_y)
        a, b = pm.to_plane(pix)
        return np.array([a[0], a[1], math.degrees(math.atan2(b[1] - a[1], b[0] - a[0]))])

    C = np.asarray(covariance, float)
    J = np.zeros((3, len(names)))
    for k, name in enumerate(names):
        step = math.sqrt(max(float(C[k, k]), 0.0)) or 1e-6
        J[:, k] = (pose_with(_perturbed(posed.camera, name, step))
                   - pose_with(_perturbed(posed.camera, name, -step))) / (2.0 * step)
    cov = J @ C @ J.T
    sx, sz, sy = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return float(sx), float(sz), float(sy)


def combine(terms: dict[str, tuple[float, float, float]]) -> tuple[float, float, float]:
    """Quadrature sum of independent (x_mm, z_mm, yaw_deg) 1-sigma terms."""
    a = np.array([[v if math.isfinite(v) else 0.0 for v in t] for t in terms.values()], float)
    s = np.sqrt((a * a).sum(axis=0))
    return float(s[0]), float(s[1]), float(s[2])
