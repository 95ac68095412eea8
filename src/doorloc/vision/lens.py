"""The camera's distortion for locate's hot path: :meth:`CameraModel.undistort_normalized` and
:meth:`CameraModel.distort`, compiled point by point.

Why: locate maps a few dozen points between the image and the hinge-face plane a couple of hundred times
per frame. :meth:`CameraModel.undistort_normalized` solves the distortion by Newton's method on whole
arrays, about thirty numpy calls per iteration on arrays too small to amortise them, and every point
iterates until the slowest has converged: on a lens with distortion that was the largest part of a frame.
The same Newton iteration compiled costs about a microsecond a point. It is the array code's step for step
(same start, same step limit, every point stepping until all have converged, the same validity test: points
that do not converge, or converge beyond the fold-over radius, are NaN), each number formed by the same
operations in the same order, so the answers are the array code's to the bit.
"""

from __future__ import annotations

import math

import numpy as np

from doorloc.calib.camera import UNDISTORT_TOL
from doorloc.vision.jit import kernel, read_only

__all__ = ["MAX_ITER", "distort_to_pixels", "undistort_pixels"]

#: Newton iterations at most (as :meth:`CameraModel.undistort_normalized`)
MAX_ITER = 50


def _undistort_warm_up(k) -> None:
    for c in (np.zeros(12), read_only(np.zeros(12))):  # a camera's coefficients are read-only
        k(np.zeros((2, 2)), np.array([1000.0, 0.0, 500.0, 1000.0, 400.0]), c, MAX_ITER)


@kernel(_undistort_warm_up)
def undistort_pixels(uv, k, c, max_iter):
    """Pixels ``uv`` (N, 2) -> ideal normalized ``(x, y)`` (N, 2), NaN where the model cannot tell.

    ``k``: ``(fx, skew, cx, fy, cy)`` of the camera matrix; ``c``: the 12 distortion coefficients in OpenCV
    order (:attr:`CameraModel.coeffs12`). :meth:`CameraModel.undistort` step for step, so to the bit: Newton's
    method from the distorted points, each step limited to half the current radius + 0.05 (a full step can
    jump across the fold), all points stepping until the distortion of every answer reproduces its input
    within ``UNDISTORT_TOL / 100`` (or none is finite); NaN where it does not within ``UNDISTORT_TOL`` with a
    positive Jacobian determinant.
    """
    fx, sk, cx, fy, cy = k[0], k[1], k[2], k[3], k[4]
    k1, k2, p1, p2, k3, k4, k5, k6 = c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]
    s1, s2, s3, s4 = c[8], c[9], c[10], c[11]
    n = uv.shape[0]
    tx = np.empty(n)
    ty = np.empty(n)
    x = np.empty(n)
    y = np.empty(n)
    for i in range(n):
        ty[i] = (uv[i, 1] - cy) / fy
        tx[i] = (uv[i, 0] - cx - sk * ty[i]) / fx
        x[i] = tx[i]
        y[i] = ty[i]
    rx = np.empty(n)
    ry = np.empty(n)
    jac = np.empty((n, 4))
    for it in range(max_iter + 1):
        converged = True
        finite = False
        for i in range(n):
            xi, yi = x[i], y[i]
            r2 = xi * xi + yi * yi
            r4 = r2 * r2
            r6 = r4 * r2
            a = 1 + k1 * r2 + k2 * r4 + k3 * r6
            b = 1 + k4 * r2 + k5 * r4 + k6 * r6
            rad = a / b
            rx[i] = xi * rad + 2 * p1 * xi * yi + p2 * (r2 + 2 * xi * xi) + s1 * r2 + s2 * r4 - tx[i]
            ry[i] = yi * rad + p1 * (r2 + 2 * yi * yi) + 2 * p2 * xi * yi + s3 * r2 + s4 * r4 - ty[i]
            da = k1 + 2 * k2 * r2 + 3 * k3 * r4
            db = k4 + 2 * k5 * r2 + 3 * k6 * r4
            drad = (da * b - a * db) / (b * b)
            gx = s1 + 2 * s2 * r2
            gy = s3 + 2 * s4 * r2
            jac[i, 0] = rad + 2 * xi * xi * drad + 2 * p1 * yi + 6 * p2 * xi + 2 * xi * gx
            jac[i, 1] = 2 * xi * yi * drad + 2 * p1 * xi + 2 * p2 * yi + 2 * yi * gx
            jac[i, 2] = 2 * xi * yi * drad + 2 * p1 * xi + 2 * p2 * yi + 2 * xi * gy
            jac[i, 3] = rad + 2 * yi * yi * drad + 6 * p1 * yi + 2 * p2 * xi + 2 * yi * gy
            if not (abs(rx[i]) < UNDISTORT_TOL * 0.01 and abs(ry[i]) < UNDISTORT_TOL * 0.01):
                converged = False
            if math.isfinite(rx[i]) or math.isfinite(ry[i]):
                finite = True
        if it == max_iter or converged or not finite:
            break
        for i in range(n):
            j00, j01, j10, j11 = jac[i, 0], jac[i, 1], jac[i, 2], jac[i, 3]
            det = j00 * j11 - j01 * j10
            dx = (j11 * rx[i] - j01 * ry[i]) / det
            dy = (-j10 * rx[i] + j00 * ry[i]) / det
            lim = 0.5 * math.sqrt(x[i] * x[i] + y[i] * y[i]) + 0.05
            m = math.sqrt(dx * dx + dy * dy)
            if m > lim:
                dx = dx * (lim / m)
                dy = dy * (lim / m)
            x[i] = x[i] - dx
            y[i] = y[i] - dy
    out = np.empty((n, 2))
    for i in range(n):
        det = jac[i, 0] * jac[i, 3] - jac[i, 1] * jac[i, 2]
        if abs(rx[i]) <= UNDISTORT_TOL and abs(ry[i]) <= UNDISTORT_TOL and det > 0:
            out[i, 0] = x[i]
            out[i, 1] = y[i]
        else:
            out[i, 0] = np.nan
            out[i, 1] = np.nan
    return out


def _distort_warm_up(k) -> None:
    for c in (np.zeros(12), read_only(np.zeros(12))):
        k(np.zeros(2), np.zeros(2), np.array([1000.0, 0.0, 500.0, 1000.0, 400.0]), c)


@kernel(_distort_warm_up)
def distort_to_pixels(x, y, k, c):
    """Ideal normalized points ``(x, y)`` (N,) each -> pixels (N, 2) through the distortion ``c`` (the 12
    coefficients) and the camera matrix ``k`` = ``(fx, skew, cx, fy, cy)``: :meth:`CameraModel.distort`
    then :meth:`CameraModel.normalized_to_pixel`."""
    fx, sk, cx, fy, cy = k[0], k[1], k[2], k[3], k[4]
    k1, k2, p1, p2, k3, k4, k5, k6 = c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]
    s1, s2, s3, s4 = c[8], c[9], c[10], c[11]
    out = np.empty((x.size, 2))
    for i in range(x.size):
        xi, yi = x[i], y[i]
        r2 = xi * xi + yi * yi
        r4 = r2 * r2
        r6 = r4 * r2
        rad = (1 + k1 * r2 + k2 * r4 + k3 * r6) / (1 + k4 * r2 + k5 * r4 + k6 * r6)
        xd = xi * rad + 2 * p1 * xi * yi + p2 * (r2 + 2 * xi * xi) + s1 * r2 + s2 * r4
        yd = yi * rad + p1 * (r2 + 2 * yi * yi) + 2 * p2 * xi * yi + s3 * r2 + s4 * r4
        out[i, 0] = fx * xd + sk * yd + cx
        out[i, 1] = fy * yd + cy
    return out
