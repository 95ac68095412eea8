"""The camera's distortion for locate's hot path: :meth:`CameraModel.undistort_normalized` and
:meth:`CameraModel.distort`, compiled point by point.

Why: locate maps a few dozen points between the image and the hinge-face plane a couple of hundred times
per frame. :meth:`CameraModel.undistort_normalized` solves the distortion by Newton's method on whole
arrays, about thirty numpy calls per iteration on arrays too small to amortise them, and every point
iterates until the slowest has converged: on a lens with distortion that was the largest part of a frame.
The same Newton iteration run per point, compiled, costs well under a microsecond a point. The answers are
the array code's (same start, same step limit, same convergence and validity tests: points that do not
converge, or converge beyond the fold-over radius, are NaN), up to the rounding of the last iterations.
"""

from __future__ import annotations

import math

import numpy as np

from doorloc.calib.camera import UNDISTORT_TOL
from doorloc.vision.jit import kernel

__all__ = ["MAX_ITER", "distort_to_pixels", "undistort_pixels"]

#: Newton iterations at most (as :meth:`CameraModel.undistort_normalized`)
MAX_ITER = 50


def _undistort_warm_up(k) -> None:
    k(np.zeros((2, 2)), np.array([1000.0, 0.0, 500.0, 1000.0, 400.0]), np.zeros(12), MAX_ITER)


@kernel(_undistort_warm_up)
def undistort_pixels(uv, k, c, max_iter):
    """Pixels ``uv`` (N, 2) -> ideal normalized ``(x, y)`` (N, 2), NaN where the model cannot tell.

    ``k``: ``(fx, skew, cx, fy, cy)`` of the camera matrix; ``c``: the 12 distortion coefficients in OpenCV
    order (:attr:`CameraModel.coeffs12`). Newton's method per point from the distorted point, each step
    limited to half the current radius + 0.05 (a full step can jump across the fold), until the distortion
    of the answer reproduces the input within ``UNDISTORT_TOL / 100``; NaN unless it does within
    ``UNDISTORT_TOL`` with a positive Jacobian determinant.
    """
    fx, sk, cx, fy, cy = k[0], k[1], k[2], k[3], k[4]
    k1, k2, p1, p2, k3, k4, k5, k6 = c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]
    s1, s2, s3, s4 = c[8], c[9], c[10], c[11]
    n = uv.shape[0]
    out = np.empty((n, 2))
    for i in range(n):
        ty = (uv[i, 1] - cy) / fy
        tx = (uv[i, 0] - cx - sk * ty) / fx
        x, y = tx, ty
        for it in range(max_iter + 1):
            r2 = x * x + y * y
            r4 = r2 * r2
            r6 = r4 * r2
            a = 1 + k1 * r2 + k2 * r4 + k3 * r6
            b = 1 + k4 * r2 + k5 * r4 + k6 * r6
            rad = a / b
            rx = x * rad + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) + s1 * r2 + s2 * r4 - tx
            ry = y * rad + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y + s3 * r2 + s4 * r4 - ty
            da = k1 + 2 * k2 * r2 + 3 * k3 * r4
            db = k4 + 2 * k5 * r2 + 3 * k6 * r4
            drad = (da * b - a * db) / (b * b)
            gx = s1 + 2 * s2 * r2
            gy = s3 + 2 * s4 * r2
            j00 = rad + 2 * x * x * drad + 2 * p1 * y + 6 * p2 * x + 2 * x * gx
            j01 = 2 * x * y * drad + 2 * p1 * x + 2 * p2 * y + 2 * y * gx
            j10 = 2 * x * y * drad + 2 * p1 * x + 2 * p2 * y + 2 * x * gy
            j11 = rad + 2 * y * y * drad + 6 * p1 * y + 2 * p2 * x + 2 * y * gy
            det = j00 * j11 - j01 * j10
            if it == max_iter or (abs(rx) < UNDISTORT_TOL * 0.01 and abs(ry) < UNDISTORT_TOL * 0.01):
                break
            if not (math.isfinite(rx) and math.isfinite(ry)):
                break
            dx = (j11 * rx - j01 * ry) / det
            dy = (-j10 * rx + j00 * ry) / det
            lim = 0.5 * math.sqrt(x * x + y * y) + 0.05
            m = math.sqrt(dx * dx + dy * dy)
            if m > lim:
                dx = dx * (lim / m)
                dy = dy * (lim / m)
            x -= dx
            y -= dy
        # (rx, ry, det: at the final (x, y), as the array code's validity test)
        if abs(rx) <= UNDISTORT_TOL and abs(ry) <= UNDISTORT_TOL and det > 0:
            out[i, 0] = x
            out[i, 1] = y
        else:
            out[i, 0] = np.nan
            out[i, 1] = np.nan
    return out


def _distort_warm_up(k) -> None:
    k(np.zeros(2), np.zeros(2), np.array([1000.0, 0.0, 500.0, 1000.0, 400.0]), np.zeros(12))


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
