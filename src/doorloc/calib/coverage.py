"""How well a set of board views covers the image, and what a planned set of views will deliver.

A calibration is only as good as where its corners fell: the distortion model is pinned down where
corners were seen, at the angles the board was seen from. This module gives

* :func:`corner_coverage`: corners per image cell (the figure the report shows and warns on),
  :func:`thin_cells` the cells with far fewer corners than a balanced set would put there;
* :func:`board_tilts_deg`: how far each board was tilted about the camera's horizontal and vertical
  axes (tilt is what separates focal length from distance; guides ask for +-30-45 deg both ways);
* :func:`predicted_projection_sigma`: the projection uncertainty a set of board poses will give for a
  known corner noise, before any image is taken, so views can be planned (or more asked for) until
  the uncertainty is below what the application needs.

Pixels follow OpenCV's convention (origin at the centre of the top-left pixel); cells are counted
``(nx, ny)`` across and down.
"""

from __future__ import annotations

import cv2
import numpy as np

from doorloc.calib.calibrate import (
    Candidate,
    projection_jacobian,
    projection_uncertainty,
    sigma_from_covariance,
    view_information,
)

__all__ = [
    "COVERAGE_CELLS",
    "THIN_FRACTION",
    "corner_coverage",
    "thin_cells",
    "cell_names",
    "board_tilts_deg",
    "predicted_projection_sigma",
    "select_views",
    "coverage_gain",
]

#: coverage is counted on this many cells across and down the image
COVERAGE_CELLS = (8, 6)
#: a cell is thin when it holds fewer corners than this fraction of the median cell
THIN_FRACTION = 0.25


def corner_coverage(
    points_px: np.ndarray, image_size: tuple[int, int], cells: tuple[int, int] = COVERAGE_CELLS
) -> np.ndarray:
    """Number of corners in each of ``cells = (nx, ny)`` image cells.

    ``points_px`` (N, 2) pixels of all views together; returns int array of shape (ny, nx).

    >>> corner_coverage(np.array([[0.0, 0.0], [639.0, 479.0], [1.0, 2.0]]), (640, 480), (2, 2)).tolist()
    [[2, 0], [0, 1]]
    """
    w, h = image_size
    nx, ny = cells
    pts = np.asarray(points_px, float).reshape(-1, 2)
    ix = np.clip((pts[:, 0] + 0.5) / w * nx, 0, nx - 1).astype(int)
    iy = np.clip((pts[:, 1] + 0.5) / h * ny, 0, ny - 1).astype(int)
    grid = np.zeros((ny, nx), int)
    np.add.at(grid, (iy, ix), 1)
    return grid


def thin_cells(coverage: np.ndarray, fraction: float = THIN_FRACTION) -> list[tuple[int, int]]:
    """Cells ``(ix, iy)`` holding fewer corners than ``fraction`` of the median cell (empty cells included)."""
    need = fraction * float(np.median(coverage))
    iy, ix = np.nonzero(coverage < need) if need > 0 else np.nonzero(coverage == 0)
    return [(int(x), int(y)) for x, y in zip(ix, iy, strict=True)]


def coverage_gain(coverage: np.ndarray, points_px: np.ndarray, image_size: tuple[int, int]) -> float:
    """How much a view with corners at ``points_px`` (N, 2) would fill the thin cells of ``coverage`` (ny, nx).

    The sum over the cells the view reaches of ``1 / (1 + corners already there)``: an empty cell
    counts 1, a well-covered one next to nothing. Used to put the next board where corners are missing.
    """
    ny, nx = coverage.shape
    reached = corner_coverage(points_px, image_size, (nx, ny)) > 0
    return float(np.sum(1.0 / (1.0 + coverage[reached])))


def cell_names(cells: list[tuple[int, int]], shape: tuple[int, int]) -> list[str]:
    """Words for cells ``(ix, iy)`` of a (ny, nx) grid: the 3x3 region each lies in, e.g. ``"top-right"``.

    Each region is named once, in the order the cells come.
    """
    ny, nx = shape
    rows, cols = ("top", "", "bottom"), ("left", "", "right")
    out: list[str] = []
    for ix, iy in cells:
        r, c = rows[min(3 * iy // ny, 2)], cols[min(3 * ix // nx, 2)]
        name = "-".join(p for p in (r, c) if p) or "centre"
        if name not in out:
            out.append(name)
    return out


def board_tilts_deg(rvecs: list[np.ndarray]) -> np.ndarray:
    """Tilt of each board about the camera's x (horizontal) and y (vertical) axes, degrees, shape (V, 2).

    From the board normal ``n`` in the camera frame, oriented away from the camera (``n_z > 0``):
    ``atan2(-n_y, n_z)`` and ``atan2(n_x, n_z)``. A board square-on to the camera has (0, 0); a board
    turned from square-on by ``R_x(a) R_y(b)`` has x tilt ``a``, by ``R_y(b) R_x(a)`` y tilt ``b``.
    """
    out = []
    for r in rvecs:
        n = cv2.Rodrigues(np.asarray(r, float).reshape(3))[0][:, 2]
        if n[2] < 0:
            n = -n
        out.append((np.degrees(np.arctan2(-n[1], n[2])), np.degrees(np.arctan2(n[0], n[2]))))
    return np.array(out, float).reshape(-1, 2)


def predicted_projection_sigma(
    camera,
    candidate: Candidate,
    poses,
    object_points: np.ndarray,
    pixels: np.ndarray,
    corner_sigma_px: float,
    *,
    aligned: bool = True,
) -> np.ndarray:
    """1-sigma projection uncertainty (px) at ``pixels`` that calibrating from these views would give.

    Parameters
    ----------
    camera : CameraModel
        The camera (a nominal or earlier calibration is good enough: the uncertainty depends on it weakly).
    candidate : Candidate
        The model that will be fitted (its free parameters).
    poses : list of (rvec, tvec_mm)
        Board -> camera poses of the planned views.
    object_points : ndarray (N, 3) or list of them
        Board corners (mm, board frame), one array for every view or one per view.
    pixels : ndarray (M, 2)
        Where to evaluate; with ``aligned`` the rotation is fitted over these (see
        :func:`doorloc.calib.calibrate.projection_uncertainty`).
    corner_sigma_px : float
        Corner noise per coordinate (px); a detected corner's RMS 2-D error divided by sqrt(2).

    Returns
    -------
    ndarray (M,)
    """
    obj = object_points if isinstance(object_points, list) else [object_points] * len(poses)
    info = sum(view_information(camera, candidate, o, r, t) for o, (r, t) in zip(obj, poses, strict=True))
    cov = corner_sigma_px**2 * np.linalg.pinv(info)
    return projection_uncertainty(camera, candidate, cov, pixels, aligned=aligned)


def select_views(
    camera,
    candidate: Candidate,
    poses,
    object_points: np.ndarray,
    n_views: int,
    pixels: np.ndarray,
    *,
    chosen: list[int] | None = None,
) -> list[int]:
    """Greedily choose ``n_views`` of the candidate board ``poses`` that minimise the predicted projection sigma.

    Each step adds the pose whose view lowers the largest predicted rotation-aligned projection
    uncertainty over ``pixels`` the most (the mean uncertainty breaks near-ties), given the views
    already chosen (``chosen``, indices into ``poses``, kept first). This is the "where should the
    next board go" question an operator asks, answered by the same uncertainty the calibration
    reports. ``object_points`` (N, 3) mm for every pose; returns indices into ``poses``.
    """
    infos = np.array([view_information(camera, candidate, object_points, r, t) for r, t in poses])
    A = projection_jacobian(camera, candidate, pixels, aligned=True)
    A = A[np.all(np.isfinite(A), axis=(1, 2))]
    # A weak prior (a millionth of one average view's information) makes the first, rank-deficient steps defined.
    prior = 1e-6 * np.diag(np.diag(infos.mean(axis=0)))
    picked = list(chosen or [])
    total = prior + infos[picked].sum(axis=0) if picked else prior.copy()
    while len(picked) < n_views:
        best, best_score = -1, (np.inf, np.inf)
        for i in range(len(poses)):
            if i in picked:
                continue
            s = sigma_from_covariance(A, np.linalg.pinv(total + infos[i]))
            score = (float(s.max()), float(np.mean(s**2)))
            if score < best_score:
                best, best_score = i, score
        if best < 0:
            break
        picked.append(best)
        total = total + infos[best]
    return picked
