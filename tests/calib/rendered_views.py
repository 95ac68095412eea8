"""Rendered board views of a known camera for the calibration tests and ``bench/bench_calib_rendered.py``.

The views are planned the way a calibration guide tells an operator to take them: boards over the
whole image, into its corners, tilted up to 45 deg about both axes (50 deg combined), near and far.
:func:`plan_views` draws a pool of such poses (each pushed from the image centre towards an edge or
corner as far as the whole board stays in the image), then chooses from it with the product's own
tools (:mod:`doorloc.calib.coverage`): first a third of the views where the corner coverage is
thinnest, then the views that lower the predicted projection uncertainty the most.
"""

from __future__ import annotations

import math

import numpy as np

from doorloc.calib.calibrate import CANDIDATES_BY_NAME, pixels_within
from doorloc.calib.camera import CameraModel, Extrinsics
from doorloc.calib.coverage import COVERAGE_CELLS, corner_coverage, coverage_gain, select_views

#: views per rendered calibration set: 30 put the predicted rotation-aligned projection sigma at
#: ~0.037 px inside the observed region (20 views: ~0.045 px), i.e. the 0.1 px target at ~2.7 sigma
N_VIEWS = 30
#: per-coordinate noise of a rendered corner (0.7 px blur, 1 DN noise: ~0.032 px RMS in 2-D)
CORNER_SIGMA_PX = 0.032 / math.sqrt(2)


def true_camera() -> CameraModel:
    """A VGA camera with clear barrel distortion and a slightly off-centre principal point."""
    return CameraModel.from_values(
        [[610.0, 0, 326.3], [0, 612.5, 236.8], [0, 0, 1]], [-0.22, 0.09, 0.0007, -0.0004, -0.015], (640, 480)
    )


def _rot(ax: float, ay: float, az: float) -> np.ndarray:
    cx, sx, cy, sy, cz, sz = (
        math.cos(ax),
        math.sin(ax),
        math.cos(ay),
        math.sin(ay),
        math.cos(az),
        math.sin(az),
    )
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _corners_px(camera: CameraModel, object_points: np.ndarray, pose: Extrinsics) -> np.ndarray:
    return camera.project(pose.cell_to_camera(object_points))


def _inside(camera: CameraModel, px: np.ndarray, margin_px: float) -> bool:
    w, h = camera.image_size
    return bool(
        np.all(np.isfinite(px))
        and px.min(axis=0).min() > margin_px
        and px[:, 0].max() < w - 1 - margin_px
        and px[:, 1].max() < h - 1 - margin_px
    )


def candidate_poses(
    camera: CameraModel,
    object_points: np.ndarray,
    n: int,
    rng: np.random.Generator,
    margin_px: float = 12.0,
    max_tilt_deg: float = 45.0,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """``n`` random board poses (rvec, tvec_mm) with the whole board inside the image.

    Tilt about x and y uniform in +-``max_tilt_deg`` (at most 50 deg combined, so the detector still
    sees the squares), roll +-30 deg, distance from filling ~45 % to ~20 % of the image width; the
    board is slid from the image centre in a random direction as far as it stays inside (three
    times in four; otherwise to a random point on the way), so edges and corners get boards.
    """
    w, h = camera.image_size
    centre_obj = object_points.mean(axis=0)
    span = float(np.ptp(object_points[:, 0]) + np.ptp(object_points[:, 1])) / 2
    c = np.array([camera.cx, camera.cy])
    out: list[tuple[np.ndarray, np.ndarray]] = []
    for _ in range(20 * n):
        if len(out) == n:
            break
        tx, ty = rng.uniform(-max_tilt_deg, max_tilt_deg, 2)
        if math.hypot(tx, ty) > 50.0:
            continue
        R = _rot(math.radians(tx), math.radians(ty), math.radians(rng.uniform(-30, 30)))
        dist = camera.fx * span / (0.55 * w) * rng.uniform(1.2, 2.6)
        a = rng.uniform(0, 2 * math.pi)
        d = np.array([math.cos(a), math.sin(a)])
        reach = min((w / 2 - 1) / max(abs(d[0]), 1e-9), (h / 2 - 1) / max(abs(d[1]), 1e-9))

        def translation(s: float, d=d, reach=reach, R=R, dist=dist) -> np.ndarray:
            ray = np.append(camera.undistort((c + s * reach * d)[None])[0], 1.0)
            return ray * dist - R @ centre_obj

        def fits(s: float, R=R) -> bool:
            return _inside(
                camera,
                _corners_px(camera, object_points, Extrinsics.from_rotation(R, translation(s))),
                margin_px,
            )

        if not fits(0.0):
            continue
        lo, hi = 0.0, 1.0
        if fits(1.0):
            lo = 1.0
        for _ in range(10 if lo < 1.0 else 0):
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if fits(mid) else (lo, mid)
        s = lo if rng.random() < 0.75 else lo * rng.uniform(0, 1)
        ext = Extrinsics.from_rotation(R, translation(s))
        out.append((ext.rvec.copy(), ext.tvec_mm.copy()))
    return out


def plan_views(
    camera: CameraModel,
    object_points: np.ndarray,
    n_views: int = N_VIEWS,
    seed: int = 0,
    margin_px: float = 12.0,
    pool_size: int = 200,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """(rvec, tvec_mm) poses of a planar board (``object_points`` (N, 3) mm) that calibrate ``camera`` well.

    A third of the views go where the corner coverage (:func:`doorloc.calib.coverage.corner_coverage`)
    is thinnest; the rest are chosen by :func:`doorloc.calib.coverage.select_views` to minimise the
    predicted rotation-aligned projection uncertainty of a plumb_bob fit over the whole image.
    """
    rng = np.random.default_rng(seed)
    pool = candidate_poses(camera, object_points, pool_size, rng, margin_px)
    pixels = [_corners_px(camera, object_points, Extrinsics(r, t)) for r, t in pool]
    coverage = np.zeros(COVERAGE_CELLS[::-1], int)
    chosen: list[int] = []
    for _ in range(min(n_views // 3, len(pool))):
        gains = [
            -1.0 if i in chosen else coverage_gain(coverage, p, camera.image_size)
            for i, p in enumerate(pixels)
        ]
        best = int(np.argmax(gains))
        chosen.append(best)
        coverage += corner_coverage(pixels[best], camera.image_size)
    grid = pixels_within(camera, 1e9, step_px=24.0)
    chosen = select_views(
        camera, CANDIDATES_BY_NAME["plumb_bob"], pool, object_points, n_views, grid, chosen=chosen
    )
    return [pool[i] for i in chosen]


def render_views(camera: CameraModel, board, n_views: int = N_VIEWS, seed: int = 0, effects=None):
    """[(name, image, true corners_px)] for ``n_views`` planned poses (uses doorloc.sim.boards.render_board)."""
    from doorloc.sim.boards import render_board

    out = []
    for i, (r, t) in enumerate(plan_views(camera, board.object_points(), n_views, seed)):
        rb = render_board(camera, board, r, t, seed=seed * 1000 + i, effects=effects)
        out.append((f"view{i:02d}.png", rb.image, rb.corners_px))
    return out
