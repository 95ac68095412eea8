"""One-shot cell calibration: the camera's pose in the cell frame from one image of a board.

Replaces the thesis's "move the door 10 mm and divide" scale calibration. A board lies on the
hinge-face plane at a known position in the cell frame; its detected corners and the camera's
intrinsics give the extrinsics ``p_cam = R(rvec) @ p_cell + tvec`` (``cv2.solvePnP``, planar IPPE
start, Levenberg-Marquardt refinement), the reprojection error, and the mm-per-pixel scale this
implies at the door's reference corner.

Board placement: the board's own origin (chessboard: corner 0, the inner corner seen top-left with
rows running left to right in the image, see :mod:`doorloc.calib.detect`; ChArUco: corner id 0)
lies at ``origin_mm`` in the cell frame; the board's x axis (along a row) points along
``x_axis`` and its y axis (down a column) along ``y_axis``. In the reference mount
(SPEC section 1: image-right is +X, image-up is +Z) these are +X = (1, 0, 0) and -Z = (0, 0, -1).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from doorloc.calib.camera import CameraModel, Extrinsics, PosedCamera

__all__ = ["CellCalibration", "CellCalibrationError", "board_points_in_cell", "calibrate_cell_extrinsics"]


class CellCalibrationError(ValueError):
    """The cell calibration could not be done; the message says why."""


@dataclass(frozen=True)
class CellCalibration:
    """Result of a one-shot cell calibration.

    Attributes
    ----------
    extrinsics : Extrinsics
        Cell -> camera.
    rms_px, max_residual_px : float
        Reprojection error of the board corners, px.
    n_corners : int
    reference_corner_px : ndarray, shape (2,)
        Where the reference corner ``(0, face_y, 0)`` projects.
    scale_mm_per_px : float
        Size of one pixel on the hinge-face plane at the reference corner (the thesis's dynamic
        scaling factor), mm.
    camera_centre_cell_mm : ndarray, shape (3,)
    reference_corner_sigma_px : float
        1-sigma uncertainty (major axis) of where the reference corner projects, from the pose's
        covariance (Gauss-Newton, intrinsics taken as exact); times ``scale_mm_per_px`` it is how
        far this calibration may misplace the reference corner on the hinge face.
    """

    extrinsics: Extrinsics
    rms_px: float
    max_residual_px: float
    n_corners: int
    reference_corner_px: np.ndarray
    scale_mm_per_px: float
    camera_centre_cell_mm: np.ndarray
    reference_corner_sigma_px: float = float("nan")

    def to_dict(self) -> dict:
        return {
            "rms_px": self.rms_px,
            "max_residual_px": self.max_residual_px,
            "n_corners": self.n_corners,
            "reference_corner_px": [float(v) for v in self.reference_corner_px],
            "scale_mm_per_px": self.scale_mm_per_px,
            "camera_centre_cell_mm": [float(v) for v in self.camera_centre_cell_mm],
            "reference_corner_sigma_px": self.reference_corner_sigma_px,
            "reference_corner_sigma_mm": self.reference_corner_sigma_px * self.scale_mm_per_px,
        }


def board_points_in_cell(
    board_points_mm: np.ndarray, origin_mm, x_axis=(1.0, 0.0, 0.0), y_axis=(0.0, 0.0, -1.0)
) -> np.ndarray:
    """Board-frame points ``(N, 3)`` (z = 0 on the board) -> cell-frame points ``(N, 3)``, mm.

    ``x_axis`` and ``y_axis`` are the cell directions of the board's x and y axes; they must be
    perpendicular (they are normalised here).

    Examples
    --------
    >>> board_points_in_cell([[25.0, 50.0, 0.0]], [100.0, 0.0, 300.0]).tolist()
    [[125.0, 0.0, 250.0]]
    """
    bx = np.asarray(x_axis, float).reshape(3)
    by = np.asarray(y_axis, float).reshape(3)
    nx, ny = np.linalg.norm(bx), np.linalg.norm(by)
    if nx == 0 or ny == 0 or abs(bx @ by) > 1e-6 * nx * ny:
        raise CellCalibrationError(
            f"board axes must be non-zero and perpendicular, got x {bx.tolist()} y {by.tolist()}"
        )
    bx, by = bx / nx, by / ny
    bz = np.cross(bx, by)
    p = np.asarray(board_points_mm, float).reshape(-1, 3)
    return np.asarray(origin_mm, float).reshape(3) + p[:, :1] * bx + p[:, 1:2] * by + p[:, 2:3] * bz


def calibrate_cell_extrinsics(
    camera: CameraModel, points_cell_mm: np.ndarray, corners_px: np.ndarray, reference_face_y_mm: float = 0.0
) -> CellCalibration:
    """Camera pose in the cell from board corners with known cell positions.

    Parameters
    ----------
    camera : the calibrated intrinsics
    points_cell_mm : ndarray, shape (N, 3)
        Cell-frame positions of the detected corners, mm (N >= 4, not all on one line).
    corners_px : ndarray, shape (N, 2)
        Their pixels.
    reference_face_y_mm : float
        Hinge-face depth of the default door, where the scale at the reference corner is taken.

    Raises
    ------
    CellCalibrationError
        Too few corners, or no pose puts the board in front of the camera.
    """
    obj = np.asarray(points_cell_mm, float).reshape(-1, 3)
    img = np.asarray(corners_px, float).reshape(-1, 2)
    if len(obj) < 4 or len(obj) != len(img):
        raise CellCalibrationError(f"need at least 4 board corners with known positions, got {len(img)}")
    K, d = camera.camera_matrix, camera.dist_coeffs
    o3, i2 = obj.reshape(-1, 1, 3), img.reshape(-1, 1, 2)
    planar = np.linalg.svd(obj - obj.mean(axis=0), compute_uv=False)[-1] < 1e-6 * max(np.ptp(obj), 1.0)
    try:
        if planar:
            ok, r, t = cv2.solvePnP(o3, i2, K, d, flags=cv2.SOLVEPNP_IPPE)
        else:
            ok, r, t = cv2.solvePnP(o3, i2, K, d, flags=cv2.SOLVEPNP_ITERATIVE)
        if not ok:
            raise CellCalibrationError("OpenCV found no camera pose for these board corners")
        r, t = cv2.solvePnPRefineLM(o3, i2, K, d, r, t)
    except cv2.error as e:
        raise CellCalibrationError(f"OpenCV could not solve the camera pose: {e.err or e}") from None
    ext = Extrinsics(r.ravel(), t.ravel())
    pc = PosedCamera(camera, ext)
    if np.any(ext.cell_to_camera(obj)[:, 2] <= 0):
        raise CellCalibrationError(
            "the solved pose puts the board behind the camera; check --board-origin and axes"
        )
    res = img - pc.project_cell(obj)
    norms = np.linalg.norm(res, axis=1)
    ref = np.array([0.0, float(reference_face_y_mm), 0.0])
    # Pose covariance s^2 (J^T J)^-1 from the board corners, propagated to the reference corner pixel.
    _, jac = cv2.projectPoints(o3, r, t, K, d)
    J = jac[:, :6]
    s2 = float(np.sum(res**2)) / max(2 * len(obj) - 6, 1)
    cov = s2 * np.linalg.pinv(J.T @ J)
    _, jref = cv2.projectPoints(ref.reshape(1, 1, 3), r, t, K, d)
    S = jref[:, :6] @ cov @ jref[:, :6].T
    ref_sigma = float(np.sqrt(max(np.linalg.eigvalsh(S)[-1], 0.0)))
    return CellCalibration(
        extrinsics=ext,
        rms_px=float(np.sqrt(np.mean(norms**2))),
        max_residual_px=float(norms.max()),
        n_corners=int(len(obj)),
        reference_corner_px=pc.project_cell(ref[None])[0],
        scale_mm_per_px=pc.scale_mm_per_px(ref),
        camera_centre_cell_mm=ext.camera_centre_cell,
        reference_corner_sigma_px=ref_sigma,
    )
