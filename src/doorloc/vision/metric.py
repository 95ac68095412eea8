"""Image <-> hinge-face plane, and the metric door pose from the fitted edges (thesis section 3.7-3.8).

The hinge face lies on the cell plane ``Y = face_y`` (from the door width, ``Fixture.face_y``): every
edge point is back-projected through K, the distortion and the extrinsics onto that plane, so lines are
fitted in millimetres where they are exactly straight, whatever the lens distortion. A chamfered or
rounded arris of size ``a`` moves the visible outline (the silhouette) to the plane ``Y = face_y + a``,
where the reference and far faces — perpendicular to the hinge face — meet it; back-projecting onto
that plane puts the outline on the lines of the sharp solid's faces, so the pose refers to the sharp
corner.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from doorloc.calib.camera import PosedCamera
from doorloc.vision.jit import kernel, read_only
from doorloc.vision.lens import MAX_ITER, distort_to_pixels, undistort_pixels
from doorloc.vision.lines import RectangleFit

__all__ = ["PlaneMap", "plane_points", "image_points", "MetricPose", "pose_from_fit"]


class PlaneMap:
    """Pixels <-> ``(X, Z)`` on a cell plane ``Y = depth_y``, through the full camera model.

    The same maths as :meth:`PosedCamera.intersect_plane_y` / :meth:`PosedCamera.project_cell`, with the
    rotation computed once (locate maps points dozens of times per image).

    Examples
    --------
    >>> from doorloc.calib.camera import CameraModel, Extrinsics
    >>> cam = CameraModel.from_values([[1000, 0, 640], [0, 1000, 360], [0, 0, 1]], [-0.1, 0, 0, 0, 0], (1280, 720))
    >>> m = PlaneMap(PosedCamera(cam, Extrinsics([math.pi / 2, 0, 0], [0, 0, 300])), 5.0)
    >>> bool(np.allclose(m.to_plane(m.to_image([[10.0, 20.0]])), [[10.0, 20.0]]))
    True
    """

    def __init__(self, posed: PosedCamera, depth_y: float) -> None:
        self.posed = posed
        self.camera = posed.camera
        self.depth_y = float(depth_y)
        self.R = np.ascontiguousarray(posed.extrinsics.rotation, dtype=np.float64)
        self.t = np.ascontiguousarray(posed.extrinsics.tvec_mm, dtype=np.float64)
        self.centre = -self.R.T @ self.t
        self._distorted = bool(np.any(self.camera.coeffs12))
        K = self.camera.camera_matrix
        self._k = (K[0, 0], K[0, 1], K[0, 2], K[1, 1], K[1, 2])
        # the camera matrix and distortion as the compiled lens model takes them (doorloc.vision.lens)
        self._kvec = np.array(self._k, dtype=np.float64)
        self._coeffs = np.ascontiguousarray(self.camera.coeffs12, dtype=np.float64)

    def at_depth(self, depth_y: float) -> PlaneMap:
        """The same camera onto another plane ``Y = depth_y``."""
        return PlaneMap(self.posed, depth_y)

    def depth_move(self, uv: np.ndarray, dy_mm: float) -> tuple[float, float]:
        """How far (``|dX|, |dZ|`` mm) the point under the pixel ``uv`` moves on the plane when the plane
        moves by ``dy_mm`` along Y (the mean over a move each way): what a depth known to ``dy_mm`` leaves
        in doubt of a point the image places."""
        ends = [self.at_depth(self.depth_y + s * dy_mm).to_plane(np.asarray([uv], float))[0] for s in (-1, 1)]
        dx, dz = np.abs(ends[1] - ends[0]) / 2.0
        return float(dx), float(dz)

    def to_plane(self, uv: np.ndarray) -> np.ndarray:
        """Pixels ``(N, 2)`` -> ``(X, Z)`` mm on the plane, shape ``(N, 2)`` (NaN where no ray)."""
        uv = np.asarray(uv, float).reshape(-1, 2)
        if self._distorted:
            xy = undistort_pixels(np.ascontiguousarray(uv), self._kvec, self._coeffs, MAX_ITER)
            x, y = xy[:, 0], xy[:, 1]
        else:
            fx, sk, cx, fy, cy = self._k
            y = (uv[:, 1] - cy) / fy
            x = (uv[:, 0] - cx - sk * y) / fx
        return _rays_to_plane(
            np.ascontiguousarray(x), np.ascontiguousarray(y), self.R, self.centre, self.depth_y
        )

    def to_image(self, xz: np.ndarray) -> np.ndarray:
        """``(X, Z)`` mm on the plane -> pixels ``(N, 2)``."""
        xz = np.asarray(xz, float).reshape(-1, 2)
        x, y = _plane_to_rays(np.ascontiguousarray(xz), self.R, self.t, self.depth_y)
        if self._distorted:
            return distort_to_pixels(x, y, self._kvec, self._coeffs)
        fx, sk, cx, fy, cy = self._k
        out = np.empty((len(xz), 2))
        out[:, 0] = fx * x + sk * y + cx
        out[:, 1] = fy * y + cy
        return out

    def scale_mm_per_px(self, xz: np.ndarray) -> float:
        """Mean size of one pixel on this plane at the point ``(X, Z)`` (mm per pixel): the square root of
        the area a pixel there covers (as :meth:`PosedCamera.scale_mm_per_px`)."""
        return self.scale_at_pixel(self.to_image(np.asarray(xz, float).reshape(1, 2))[0])

    def scale_at_pixel(self, uv: np.ndarray) -> float:
        """:meth:`scale_mm_per_px` at the plane point seen at pixel ``uv`` (u, v), mm per pixel."""
        u, v = float(uv[0]), float(uv[1])
        q = self.to_plane(np.array([[u, v], [u + 1.0, v], [u, v + 1.0]]))
        a, b = q[1] - q[0], q[2] - q[0]
        return float(math.sqrt(abs(a[0] * b[1] - a[1] * b[0])))


def _rays_warm_up(k) -> None:
    for R in (np.eye(3), read_only(np.eye(3))):  # a pose's rotation is read-only
        k(np.zeros(2), np.zeros(2), R, np.ones(3), 5.0)


@kernel(_rays_warm_up)
def _rays_to_plane(x, y, R, centre, depth_y):
    """Normalised image points ``(x, y)`` -> ``(X, Z)`` (N, 2) where their rays from ``centre`` meet the
    plane ``Y = depth_y`` (the cell direction ``R^T (x, y, 1)``); NaN where the ray runs away from it."""
    out = np.empty((x.size, 2))
    for i in range(x.size):
        dx = R[0, 0] * x[i] + R[1, 0] * y[i] + R[2, 0]
        dy = R[0, 1] * x[i] + R[1, 1] * y[i] + R[2, 1]
        dz = R[0, 2] * x[i] + R[1, 2] * y[i] + R[2, 2]
        s = (depth_y - centre[1]) / dy
        if not s > 0:
            s = np.nan
        out[i, 0] = centre[0] + s * dx
        out[i, 1] = centre[2] + s * dz
    return out


def _plane_warm_up(k) -> None:
    for R, t in ((np.eye(3), np.ones(3)), (read_only(np.eye(3)), read_only(np.ones(3)))):
        k(np.zeros((2, 2)), R, t, 5.0)


@kernel(_plane_warm_up)
def _plane_to_rays(xz, R, t, depth_y):
    """``(X, Z)`` (N, 2) on the plane ``Y = depth_y`` -> normalised image points ``x``, ``y`` (N,) (camera
    frame ``R p + t``; NaN behind the camera)."""
    n = xz.shape[0]
    x = np.empty(n)
    y = np.empty(n)
    for i in range(n):
        X, Z = xz[i, 0], xz[i, 1]
        p0 = R[0, 0] * X + R[0, 1] * depth_y + R[0, 2] * Z + t[0]
        p1 = R[1, 0] * X + R[1, 1] * depth_y + R[1, 2] * Z + t[1]
        p2 = R[2, 0] * X + R[2, 1] * depth_y + R[2, 2] * Z + t[2]
        zc = p2 if p2 > 0 else np.nan
        x[i] = p0 / zc
        y[i] = p1 / zc
    return x, y


def plane_points(posed: PosedCamera, uv: np.ndarray, depth_y: float) -> np.ndarray:
    """Pixels ``(N, 2)`` -> ``(X, Z)`` mm on the plane ``Y = depth_y``, shape ``(N, 2)`` (NaN where no ray)."""
    return PlaneMap(posed, depth_y).to_plane(uv)


def image_points(posed: PosedCamera, xz: np.ndarray, depth_y: float) -> np.ndarray:
    """``(X, Z)`` mm on the plane ``Y = depth_y`` -> pixels ``(N, 2)``."""
    return PlaneMap(posed, depth_y).to_image(xz)


@dataclass(frozen=True)
class MetricPose:
    """The door pose measured on the hinge-face plane.

    Attributes
    ----------
    x_mm, z_mm : float
        Reference corner on the plane (cell X, Z), mm.
    yaw_deg : float
        Door yaw (SPEC section 1), degrees.
    thickness_mm : float
        Distance between the reference and far arris lines, mm.
    corner_px : ndarray (2,)
        The corner's pixel (u, v).
    scale_mm_per_px : float
        Dynamic scaling factor at the corner on the hinge-face plane, mm/px.
    """

    x_mm: float
    z_mm: float
    yaw_deg: float
    thickness_mm: float
    corner_px: np.ndarray
    scale_mm_per_px: float

    @property
    def x_axis(self) -> np.ndarray:
        """Door +X on the plane, (X, Z) unit vector."""
        t = math.radians(self.yaw_deg)
        return np.array([math.cos(t), math.sin(t)])

    @property
    def z_axis(self) -> np.ndarray:
        """Door +Z on the plane, (X, Z) unit vector."""
        t = math.radians(self.yaw_deg)
        return np.array([-math.sin(t), math.cos(t)])

    @property
    def corner(self) -> np.ndarray:
        return np.array([self.x_mm, self.z_mm])


def pose_from_fit(fit: RectangleFit, face_map: PlaneMap) -> MetricPose:
    """Corner, yaw and thickness from a :class:`RectangleFit` of the bottom, reference and far lines.

    Solves ``cos t X + sin t Z = c_ref`` and ``-sin t X + cos t Z = c_bottom`` for the corner; the
    thickness is ``c_far - c_ref``. The outline was back-projected to ``face_y + arris``
    (the lines are the same at any depth); the corner pixel and the scale are taken on the hinge face, ``face_map``'s plane.
    """
    t = fit.angle_rad
    c, s = math.cos(t), math.sin(t)
    cr, cb = fit.offsets["reference"], fit.offsets["bottom"]
    x = c * cr - s * cb
    z = s * cr + c * cb
    thickness = fit.offsets["far"] - cr if "far" in fit.offsets else float("nan")
    corner_px = face_map.to_image(np.array([[x, z]]))[0]
    scale = face_map.scale_at_pixel(corner_px)  # = scale_mm_per_px((x, z)), without projecting it again
    return MetricPose(float(x), float(z), math.degrees(t), float(thickness), corner_px, scale)
