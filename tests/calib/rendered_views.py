"""Rendered board views of a known camera for the calibration tests and ``bench/bench_calib_rendered.py``.

Poses are planned so that the board centre lands on a 3x3 grid of image targets (corners, edges,
centre) with alternating tilts, keeping every corner inside the image with a margin.
"""

from __future__ import annotations

import math

import numpy as np

from doorloc.calib.camera import CameraModel, Extrinsics


def true_camera() -> CameraModel:
    """A VGA camera with clear barrel distortion and a slightly off-centre principal point."""
    return CameraModel.from_values([[610.0, 0, 326.3], [0, 612.5, 236.8], [0, 0, 1]],
                                   [-0.22, 0.09, 0.0007, -0.0004, -0.015], (640, 480))


def _rot(ax: float, ay: float, az: float) -> np.ndarray:
    cx, sx, cy, sy, cz, sz = math.cos(ax), math.sin(ax), math.cos(ay), math.sin(ay), math.cos(az), math.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def plan_views(camera: CameraModel, object_points: np.ndarray, n_views: int = 15, seed: int = 0,
               margin_px: float = 12.0) -> list[tuple[np.ndarray, np.ndarray]]:
    """(rvec, tvec_mm) poses of a planar board whose views cover the image; ``object_points`` (N, 3) mm."""
    rng = np.random.default_rng(seed)
    w, h = camera.image_size
    centre_obj = object_points.mean(axis=0)
    span = float(np.ptp(object_points[:, 0]) + np.ptp(object_points[:, 1])) / 2
    targets = [(fx, fy) for fy in (0.22, 0.5, 0.78) for fx in (0.2, 0.5, 0.8)]
    poses = []
    k = 0
    while len(poses) < n_views and k < 50 * n_views:
        tx, ty = targets[len(poses) % len(targets)]
        tilt = math.radians(rng.uniform(15, 40))
        az = rng.uniform(0, 2 * math.pi)
        R = _rot(tilt * math.cos(az), tilt * math.sin(az), math.radians(rng.uniform(-15, 15)))
        uv = np.array([[tx * w + rng.uniform(-15, 15), ty * h + rng.uniform(-15, 15)]])
        ray = np.append(camera.undistort(uv)[0], 1.0)
        for dist_scale in (1.4, 1.7, 2.0, 2.4, 2.9):
            dist = camera.fx * span / (0.55 * w) * dist_scale
            t = ray * dist / np.linalg.norm(ray) * np.linalg.norm(ray) - R @ centre_obj
            ext = Extrinsics.from_rotation(R, t)
            px = camera.project(ext.cell_to_camera(object_points))
            if np.all(np.isfinite(px)) and px[:, 0].min() > margin_px and px[:, 1].min() > margin_px \
                    and px[:, 0].max() < w - 1 - margin_px and px[:, 1].max() < h - 1 - margin_px:
                poses.append((ext.rvec.copy(), ext.tvec_mm.copy()))
                break
        k += 1
    return poses


def render_views(camera: CameraModel, board, n_views: int = 15, seed: int = 0, effects=None):
    """[(name, image, true corners_px)] for ``n_views`` planned poses (uses doorloc.sim.boards.render_board)."""
    from doorloc.sim.boards import render_board

    out = []
    for i, (r, t) in enumerate(plan_views(camera, board.object_points(), n_views, seed)):
        rb = render_board(camera, board, r, t, seed=seed * 1000 + i, effects=effects)
        out.append((f"view{i:02d}.png", rb.image, rb.corners_px))
    return out
