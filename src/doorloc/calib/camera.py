"""The one camera model used everywhere in doorloc: OpenCV pinhole + distortion.

Conventions (OpenCV's, shared/SPEC.md section 1):

- pixel coordinates ``(u, v)``: origin at the centre of the top-left pixel, u to the right, v down;
- camera frame: +Z along the optical axis, +X to image-right, +Y to image-down; millimetres;
- normalized coordinates ``(x, y) = (X/Z, Y/Z)`` before distortion ("ideal"), ``(x_d, y_d)`` after;
- distortion coefficients in OpenCV order ``k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4]]]``;
  4, 5, 8 or 12 of them (the tilted-sensor model with 14 is refused: no calibration here fits it);
- extrinsics ``p_cam = R(rvec) @ p_cell + tvec`` (what ``cv2.solvePnP`` returns).

Unlike ``cv2.undistortPoints`` with its default five fixed-point iterations, :meth:`CameraModel.undistort`
runs Newton's method until the distortion of the answer reproduces the input to 1e-10 in normalized
units, and returns NaN where it cannot (beyond the radius where the model folds over): a pixel whose ray
the model cannot tell is reported, not guessed.

Why a model "fails" matters as much as the model: a polynomial distortion fitted on data that did not
reach the image corners can turn back on itself (its radial map stops being monotonic) inside the image.
:func:`distortion_validity` finds that radius and says what the model predicts at the image corners.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = [
    "CameraModel",
    "Extrinsics",
    "PosedCamera",
    "DistortionValidity",
    "distortion_validity",
    "UNDISTORT_TOL",
]

#: Convergence tolerance of :meth:`CameraModel.undistort`, in normalized image units.
UNDISTORT_TOL = 1e-10
_SUPPORTED_NCOEFFS = (0, 4, 5, 8, 12)


def _as_points2(a: np.ndarray) -> np.ndarray:
    p = np.asarray(a, dtype=float)
    if p.shape[-1] != 2:
        raise ValueError(f"expected points of shape (..., 2), got {p.shape}")
    return p


@dataclass(frozen=True, eq=False)
class CameraModel:
    """Pinhole camera with OpenCV distortion.

    Attributes
    ----------
    camera_matrix : ndarray, shape (3, 3)
        ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` in pixels (no skew, as in OpenCV).
    dist_coeffs : ndarray, shape (N,)
        N in {0, 4, 5, 8, 12}; stored padded to 12 internally by :attr:`coeffs12`.
    image_size : tuple of int
        ``(width, height)`` in pixels.
    observed_radius_px : float or None
        Largest distance from the principal point at which calibration data were observed;
        the model is only trusted inside it (None: unknown, e.g. a datasheet model).

    Examples
    --------
    >>> cam = CameraModel.from_values([[1000, 0, 640], [0, 1000, 360], [0, 0, 1]], [-0.1, 0.01, 0, 0, 0], (1280, 720))
    >>> uv = cam.project([[100.0, 50.0, 1000.0]])
    >>> xy = cam.undistort(uv)
    >>> np.allclose(xy, [[0.1, 0.05]], atol=1e-10)
    True
    """

    camera_matrix: np.ndarray
    dist_coeffs: np.ndarray
    image_size: tuple[int, int]
    observed_radius_px: float | None = None
    coeffs12: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        K = np.asarray(self.camera_matrix, dtype=float).reshape(3, 3)
        d = np.asarray(self.dist_coeffs, dtype=float).ravel()
        if d.size not in _SUPPORTED_NCOEFFS:
            raise ValueError(
                f"{d.size} distortion coefficients: doorloc supports 4, 5 (plumb_bob), 8 (rational) or 12 "
                "(thin prism) in OpenCV order k1 k2 p1 p2 k3 k4 k5 k6 s1 s2 s3 s4"
            )
        if not (
            K[0, 0] > 0 and K[1, 1] > 0 and K[2, 2] == 1 and K[1, 0] == 0 and K[2, 0] == 0 and K[2, 1] == 0
        ):
            raise ValueError(f"not a camera matrix (need fx, fy > 0 and last row 0 0 1): {K.tolist()}")
        if K[0, 1] != 0:
            # OpenCV's projection ignores K[0, 1]; accepting it would make us disagree with every OpenCV call.
            raise ValueError(
                f"camera matrix has skew {K[0, 1]}: OpenCV's camera model has none; set K[0][1] = 0"
            )
        w, h = (int(v) for v in self.image_size)
        if w <= 0 or h <= 0:
            raise ValueError(f"image size must be positive, got {self.image_size}")
        c12 = np.zeros(12)
        c12[: d.size] = d
        object.__setattr__(self, "camera_matrix", K)
        object.__setattr__(self, "dist_coeffs", d)
        object.__setattr__(self, "image_size", (w, h))
        object.__setattr__(self, "coeffs12", c12)
        K.setflags(write=False)
        d.setflags(write=False)
        c12.setflags(write=False)

    @classmethod
    def from_values(cls, camera_matrix, dist_coeffs, image_size, observed_radius_px=None) -> CameraModel:
        return cls(
            np.asarray(camera_matrix, float),
            np.asarray(dist_coeffs, float),
            tuple(image_size),
            observed_radius_px,
        )

    # -- properties ---------------------------------------------------------------------------
    @property
    def fx(self) -> float:
        return float(self.camera_matrix[0, 0])

    @property
    def fy(self) -> float:
        return float(self.camera_matrix[1, 1])

    @property
    def cx(self) -> float:
        return float(self.camera_matrix[0, 2])

    @property
    def cy(self) -> float:
        return float(self.camera_matrix[1, 2])

    @property
    def skew(self) -> float:
        return float(self.camera_matrix[0, 1])

    @property
    def distortion_model(self) -> str:
        """ROS name of the distortion model: ``plumb_bob`` (<= 5 coefficients) or ``rational_polynomial``."""
        return "plumb_bob" if self.dist_coeffs.size <= 5 else "rational_polynomial"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, CameraModel):
            return NotImplemented
        return (
            self.image_size == other.image_size
            and np.array_equal(self.camera_matrix, other.camera_matrix)
            and np.array_equal(self.coeffs12, other.coeffs12)
        )

    def with_observed_radius(self, radius_px: float | None) -> CameraModel:
        return CameraModel(self.camera_matrix, self.dist_coeffs, self.image_size, radius_px)

    # -- distortion in normalized coordinates --------------------------------------------------
    def distort(self, xy: np.ndarray) -> np.ndarray:
        """Ideal normalized ``(x, y)`` -> distorted normalized ``(x_d, y_d)``. Shape ``(..., 2)``."""
        xd, _ = self._distort_and_jacobian(_as_points2(xy), jacobian=False)
        return xd

    def distort_with_jacobian(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distortion and its Jacobian at ideal normalized points.

        Shapes ``(..., 2) -> ((..., 2), (..., 2, 2))``; ``J[..., i, j] = d x_d[i] / d x[j]``.
        """
        return self._distort_and_jacobian(_as_points2(xy))

    def _distort_and_jacobian(self, xy: np.ndarray, jacobian: bool = True):
        k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = self.coeffs12
        x, y = xy[..., 0], xy[..., 1]
        r2 = x * x + y * y
        r4 = r2 * r2
        r6 = r4 * r2
        a = 1 + k1 * r2 + k2 * r4 + k3 * r6
        b = 1 + k4 * r2 + k5 * r4 + k6 * r6
        rad = a / b
        xd = x * rad + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) + s1 * r2 + s2 * r4
        yd = y * rad + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y + s3 * r2 + s4 * r4
        out = np.stack([xd, yd], axis=-1)
        if not jacobian:
            return out, None
        da = k1 + 2 * k2 * r2 + 3 * k3 * r4
        db = k4 + 2 * k5 * r2 + 3 * k6 * r4
        drad = (da * b - a * db) / (b * b)  # d rad / d r2
        tx = s1 + 2 * s2 * r2
        ty = s3 + 2 * s4 * r2
        j = np.empty(xy.shape[:-1] + (2, 2))
        j[..., 0, 0] = rad + 2 * x * x * drad + 2 * p1 * y + 6 * p2 * x + 2 * x * tx
        j[..., 0, 1] = 2 * x * y * drad + 2 * p1 * x + 2 * p2 * y + 2 * y * tx
        j[..., 1, 0] = 2 * x * y * drad + 2 * p1 * x + 2 * p2 * y + 2 * x * ty
        j[..., 1, 1] = rad + 2 * y * y * drad + 6 * p1 * y + 2 * p2 * x + 2 * y * ty
        return out, j

    def undistort_normalized(self, xy_d: np.ndarray, max_iter: int = 50) -> np.ndarray:
        """Distorted normalized -> ideal normalized by Newton's method, converged to 1e-10.

        Points where Newton does not converge, or converges onto the far side of the fold-over
        radius, come back as NaN. Shape ``(..., 2)``.
        """
        target = _as_points2(xy_d)
        if not np.any(self.coeffs12):
            return target.copy()
        xy = target.copy()
        for _ in range(max_iter):
            f, j = self._distort_and_jacobian(xy)
            res = f - target
            if np.all(np.abs(res) < UNDISTORT_TOL * 0.01) or not np.any(np.isfinite(res)):
                break
            det = j[..., 0, 0] * j[..., 1, 1] - j[..., 0, 1] * j[..., 1, 0]
            with np.errstate(divide="ignore", invalid="ignore"):
                dx = (j[..., 1, 1] * res[..., 0] - j[..., 0, 1] * res[..., 1]) / det
                dy = (-j[..., 1, 0] * res[..., 0] + j[..., 0, 0] * res[..., 1]) / det
            step = np.stack([dx, dy], axis=-1)
            # A full Newton step can jump across the fold; limit it to half the current radius + 0.05.
            lim = 0.5 * np.linalg.norm(xy, axis=-1, keepdims=True) + 0.05
            n = np.linalg.norm(step, axis=-1, keepdims=True)
            with np.errstate(divide="ignore", invalid="ignore"):
                step = np.where(n > lim, step * (lim / n), step)
            xy = xy - step
        f, j = self._distort_and_jacobian(xy)
        det = j[..., 0, 0] * j[..., 1, 1] - j[..., 0, 1] * j[..., 1, 0]
        bad = ~(np.all(np.abs(f - target) <= UNDISTORT_TOL, axis=-1) & (det > 0))
        xy[bad] = np.nan
        return xy

    # -- pixels ---------------------------------------------------------------------------------
    def normalized_to_pixel(self, xy_d: np.ndarray) -> np.ndarray:
        """Distorted normalized -> pixel ``(u, v)``. Shape ``(..., 2)``."""
        p = _as_points2(xy_d)
        K = self.camera_matrix
        u = K[0, 0] * p[..., 0] + K[0, 1] * p[..., 1] + K[0, 2]
        v = K[1, 1] * p[..., 1] + K[1, 2]
        return np.stack([u, v], axis=-1)

    def pixel_to_normalized_distorted(self, uv: np.ndarray) -> np.ndarray:
        """Pixel -> distorted normalized (inverse of K only). Shape ``(..., 2)``."""
        p = _as_points2(uv)
        K = self.camera_matrix
        y = (p[..., 1] - K[1, 2]) / K[1, 1]
        x = (p[..., 0] - K[0, 2] - K[0, 1] * y) / K[0, 0]
        return np.stack([x, y], axis=-1)

    def undistort(self, uv: np.ndarray) -> np.ndarray:
        """Pixel ``(u, v)`` -> ideal normalized ``(x, y)`` (NaN where the model cannot tell).

        Shape ``(..., 2) -> (..., 2)``.
        """
        return self.undistort_normalized(self.pixel_to_normalized_distorted(uv))

    def undistort_pixels(self, uv: np.ndarray) -> np.ndarray:
        """Pixel -> the pixel an ideal (distortion-free) camera with the same K would see."""
        return self.normalized_to_pixel(self.undistort(uv))

    def distort_pixels(self, uv_ideal: np.ndarray) -> np.ndarray:
        """Ideal pinhole pixel -> real (distorted) pixel. Inverse of :meth:`undistort_pixels`."""
        return self.normalized_to_pixel(self.distort(self.pixel_to_normalized_distorted(uv_ideal)))

    def project(self, points_cam: np.ndarray) -> np.ndarray:
        """Camera-frame points ``(..., 3)`` (mm) -> pixels ``(..., 2)``. Points behind the camera give NaN."""
        p = np.asarray(points_cam, dtype=float)
        z = p[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            xy = p[..., :2] / np.where(z > 0, z, np.nan)[..., None]
        return self.normalized_to_pixel(self.distort(xy))

    def backproject(self, uv: np.ndarray) -> np.ndarray:
        """Pixel ``(..., 2)`` -> unit ray directions ``(..., 3)`` in the camera frame (NaN if unknown)."""
        xy = self.undistort(uv)
        rays = np.concatenate([xy, np.ones(xy.shape[:-1] + (1,))], axis=-1)
        return rays / np.linalg.norm(rays, axis=-1, keepdims=True)

    def image_corners_px(self) -> np.ndarray:
        """The four outer pixel corners of the sensor, shape (4, 2): TL, TR, BR, BL (pixel-edge coordinates)."""
        w, h = self.image_size
        return np.array([[-0.5, -0.5], [w - 0.5, -0.5], [w - 0.5, h - 0.5], [-0.5, h - 0.5]])

    def scaled(self, factor: float) -> CameraModel:
        """The same camera for an image resized by ``factor`` (pixel-centre convention kept)."""
        K = self.camera_matrix.copy()
        K[0, :] *= factor
        K[1, :] *= factor
        K[0, 2] = (self.cx + 0.5) * factor - 0.5
        K[1, 2] = (self.cy + 0.5) * factor - 0.5
        w, h = self.image_size
        r = None if self.observed_radius_px is None else self.observed_radius_px * factor
        return CameraModel(K, self.dist_coeffs, (round(w * factor), round(h * factor)), r)


@dataclass(frozen=True, eq=False)
class Extrinsics:
    """Pose of the cell frame in the camera: ``p_cam = R(rvec) @ p_cell + tvec`` (mm).

    Attributes
    ----------
    rvec : ndarray, shape (3,)
        Rodrigues vector, radians.
    tvec_mm : ndarray, shape (3,)
        Translation, mm.
    """

    rvec: np.ndarray
    tvec_mm: np.ndarray
    _rotation: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        r = np.array(self.rvec, float).reshape(3)
        t = np.array(self.tvec_mm, float).reshape(3)
        R = Rotation.from_rotvec(r).as_matrix()
        for a in (r, t, R):
            a.setflags(write=False)
        object.__setattr__(self, "rvec", r)
        object.__setattr__(self, "tvec_mm", t)
        object.__setattr__(self, "_rotation", R)

    @property
    def rotation(self) -> np.ndarray:
        """``R``, shape (3, 3): cell directions -> camera directions (read-only)."""
        return self._rotation

    @property
    def camera_centre_cell(self) -> np.ndarray:
        """Camera centre in the cell frame, mm, shape (3,)."""
        return -self.rotation.T @ self.tvec_mm

    @classmethod
    def from_rotation(cls, rotation: np.ndarray, tvec_mm: np.ndarray | Sequence[float]) -> Extrinsics:
        """Extrinsics from a rotation matrix ``R`` (cell -> camera) and a translation, mm.

        scipy's quaternion route keeps full precision near 180 deg, where the textbook
        ``(R - R.T) / (2 sin theta)`` formula (and ``cv2.Rodrigues``, ~1e-5 there) loses digits.
        """
        rvec = Rotation.from_matrix(np.asarray(rotation, float)).as_rotvec()
        return cls(rvec, np.asarray(tvec_mm, float))

    def cell_to_camera(self, points_cell: np.ndarray) -> np.ndarray:
        """Shape ``(..., 3) -> (..., 3)``, mm."""
        p = np.asarray(points_cell, float)
        return p @ self.rotation.T + self.tvec_mm


@dataclass(frozen=True, eq=False)
class PosedCamera:
    """A camera model placed in the cell: what locate and the renderer share.

    Examples
    --------
    >>> cam = CameraModel.from_values([[1000, 0, 640], [0, 1000, 360], [0, 0, 1]], [], (1280, 720))
    >>> ext = Extrinsics([math.pi / 2, 0, 0], [0, 0, 300])   # looking along cell +Y
    >>> pc = PosedCamera(cam, ext)
    >>> p = pc.intersect_plane_y(pc.project_cell([[10.0, 0.0, 20.0]]), 0.0)
    >>> np.allclose(p, [[10.0, 0.0, 20.0]])
    True
    """

    camera: CameraModel
    extrinsics: Extrinsics

    def project_cell(self, points_cell: np.ndarray) -> np.ndarray:
        """Cell-frame points ``(..., 3)`` (mm) -> pixels ``(..., 2)``."""
        return self.camera.project(self.extrinsics.cell_to_camera(points_cell))

    def rays_cell(self, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixels ``(..., 2)`` -> (origin ``(3,)``, unit directions ``(..., 3)``) in the cell frame."""
        d_cam = self.camera.backproject(uv)
        return self.extrinsics.camera_centre_cell, d_cam @ self.extrinsics.rotation

    def intersect_plane_y(self, uv: np.ndarray, y_mm: float) -> np.ndarray:
        """Back-project pixels onto the cell plane ``Y = y_mm``. ``(..., 2) -> (..., 3)`` mm."""
        o, d = self.rays_cell(uv)
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (y_mm - o[1]) / d[..., 1]
        s = np.where(s > 0, s, np.nan)
        return o + d * s[..., None]

    def scale_mm_per_px(self, point_cell: np.ndarray, y_mm: float | None = None) -> float:
        """Mean size of one pixel on the plane ``Y = y`` through ``point_cell`` (mm per pixel).

        The thesis's dynamic scaling factor: the square root of the area that one pixel at the
        projection of ``point_cell`` covers on the plane.
        """
        p = np.asarray(point_cell, float).reshape(3)
        y = p[1] if y_mm is None else y_mm
        uv = self.project_cell(p[None])[0]
        q = self.intersect_plane_y(np.array([uv, uv + [1.0, 0.0], uv + [0.0, 1.0]]), y)
        a, b = q[1] - q[0], q[2] - q[0]
        return float(math.sqrt(abs(np.linalg.norm(np.cross(a, b)))))


@dataclass(frozen=True)
class DistortionValidity:
    """Where a distortion model can be trusted (pixels are distances from the principal point).

    Attributes
    ----------
    fold_radius_px : float or None
        Smallest image-space radius at which the model's mapping stops being one-to-one (the
        Jacobian determinant of the distortion reaches zero); None if it does not fold within the
        searched range (three times the image diagonal).
    corner_radius_px : float
        Distance from the principal point to the farthest sensor corner.
    observed_radius_px : float or None
        Radius reached by calibration data, if known.
    valid_radius_px : float or None
        ``min(fold, observed)``: the radius inside which the model is to be used.
    corners_inside_fold : bool
        True if every sensor corner lies inside the fold-over radius.
    corner_report : list of dict
        Per sensor corner: its pixel, whether it can be undistorted, the distortion shift (px) the
        model predicts there, and the field angle (deg) of its ray.
    warnings : list of str
        Sentences a person can act on.
    """

    fold_radius_px: float | None
    corner_radius_px: float
    observed_radius_px: float | None
    valid_radius_px: float | None
    corners_inside_fold: bool
    corner_report: list[dict]
    warnings: list[str]

    @property
    def usable_over_whole_image(self) -> bool:
        return self.corners_inside_fold and (
            self.observed_radius_px is None or self.observed_radius_px >= self.corner_radius_px * 0.95
        )

    def to_dict(self) -> dict:
        return {
            "fold_radius_px": self.fold_radius_px,
            "corner_radius_px": self.corner_radius_px,
            "observed_radius_px": self.observed_radius_px,
            "valid_radius_px": self.valid_radius_px,
            "corners_inside_fold": self.corners_inside_fold,
            "corner_report": self.corner_report,
            "warnings": self.warnings,
        }


def distortion_validity(camera: CameraModel, n_angles: int = 360, n_radii: int = 3000) -> DistortionValidity:
    """Find the radius where ``camera``'s distortion folds over and report what it predicts at the corners.

    The distortion maps ideal normalized points to distorted ones; it is usable only where that
    map is one-to-one, i.e. where its Jacobian determinant stays positive along every ray from the
    principal point. The search runs over ``n_angles`` directions out to three image diagonals.

    Examples
    --------
    The coefficients the thesis reports (radial 0.0206, 10.4073, -115.4536) fold over well inside
    its 1920x1080 image:

    >>> cam = CameraModel.from_values([[1678.35, 0, 946.41], [0, 1727.22, 510.71], [0, 0, 1]],
    ...                               [0.0206, 10.4073, 0, 0, -115.4536], (1920, 1080))
    >>> v = distortion_validity(cam)
    >>> v.corners_inside_fold, round(v.fold_radius_px)
    (False, 560)
    """
    corners = camera.image_corners_px()
    c = np.array([camera.cx, camera.cy])
    corner_radius = float(np.max(np.linalg.norm(corners - c, axis=1)))
    corners_n = camera.pixel_to_normalized_distorted(corners)
    r_max = 3.0 * float(np.max(np.linalg.norm(corners_n, axis=1)))

    theta = np.linspace(0, 2 * np.pi, n_angles, endpoint=False)
    r = np.linspace(0, r_max, n_radii)[1:]
    dirs = np.stack([np.cos(theta), np.sin(theta)], axis=-1)
    xy = r[None, :, None] * dirs[:, None, :]  # (angles, radii, 2)
    f, j = camera._distort_and_jacobian(xy)
    det = j[..., 0, 0] * j[..., 1, 1] - j[..., 0, 1] * j[..., 1, 0]
    folded = ~(det > 0)
    fold_px: float | None = None
    rays = np.flatnonzero(folded.any(axis=1))
    if rays.size:
        # Bisect on det(J) between the last good and the first folded sample, all rays at once.
        i = folded[rays].argmax(axis=1)
        lo = np.where(i > 0, r[np.maximum(i - 1, 0)], 0.0)
        hi = r[i]
        d = dirs[rays]
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            _, jm = camera._distort_and_jacobian(mid[:, None] * d)
            good = jm[:, 0, 0] * jm[:, 1, 1] - jm[:, 0, 1] * jm[:, 1, 0] > 0
            lo, hi = np.where(good, mid, lo), np.where(good, hi, mid)
        pd = camera.normalized_to_pixel(camera.distort(lo[:, None] * d))
        fold_px = float(np.min(np.linalg.norm(pd - c, axis=1)))

    report = []
    for name, uv in zip(("top-left", "top-right", "bottom-right", "bottom-left"), corners, strict=True):
        xy_ideal = camera.undistort(uv[None])[0]
        ideal_px = camera.normalized_to_pixel(camera.pixel_to_normalized_distorted(uv[None]))[0]
        forward = camera.normalized_to_pixel(camera.distort(camera.pixel_to_normalized_distorted(uv[None])))[
            0
        ]
        entry = {
            "corner": name,
            "pixel": [float(uv[0]), float(uv[1])],
            "undistortable": bool(np.all(np.isfinite(xy_ideal))),
            # Where the model sends the ray that a distortion-free camera would image at this corner.
            "ideal_ray_lands_at_px": [float(forward[0]), float(forward[1])],
            "distortion_shift_px": float(np.linalg.norm(forward - ideal_px)),
            "field_angle_deg": (
                float(np.degrees(np.arctan(np.linalg.norm(xy_ideal))))
                if np.all(np.isfinite(xy_ideal))
                else None
            ),
        }
        report.append(entry)

    inside = fold_px is None or fold_px > corner_radius
    observed = camera.observed_radius_px
    candidates = [v for v in (fold_px, observed) if v is not None]
    valid = min(candidates) if candidates else None
    warnings = []
    if not inside:
        warnings.append(
            f"the distortion model folds over at {fold_px:.0f} px from the principal point, inside the image "
            f"(corners at {corner_radius:.0f} px): pixels beyond it have no trustworthy ray. Recalibrate with "
            "board views that reach the image corners, or use only the region inside that radius."
        )
    if observed is not None and observed < 0.95 * corner_radius:
        warnings.append(
            f"calibration data reached only {observed:.0f} px from the principal point (corners at "
            f"{corner_radius:.0f} px): the model is extrapolated beyond that; add views with the board "
            "near the image corners."
        )
    return DistortionValidity(fold_px, corner_radius, observed, valid, inside, report, warnings)
