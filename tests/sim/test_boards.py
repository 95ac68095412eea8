"""Rendered calibration boards: OpenCV's detectors find the true corners."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from doorloc.calib.camera import CameraModel, Extrinsics
from doorloc.sim.boards import CharucoBoard, Checkerboard, render_board
from doorloc.sim.effects import Effects

CAM = CameraModel.from_values(
    [[1000.0, 0, 639.5], [0, 1000.0, 479.5], [0, 0, 1]], [-0.1, 0.05, 0.001, -0.0005, 0.0], (1280, 960)
)
CRIT = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 200, 1e-5)


def _rms(a, b):
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))


def _match_order(found, truth):
    """OpenCV may report a checkerboard's corners in reverse order; put them in the board's order."""
    return (
        found[::-1] if np.linalg.norm(found[0] - truth[-1]) < np.linalg.norm(found[0] - truth[0]) else found
    )


@pytest.mark.parametrize(
    "rvec,tvec",
    [([0.2, -0.3, 0.05], [-100.0, -60.0, 600.0]), ([-0.4, 0.1, -0.2], [-60.0, -80.0, 500.0])],
)
def test_checkerboard_corners_found_by_opencv_match_truth(rvec, tvec):
    board = Checkerboard(9, 6, 25.0)
    rb = render_board(CAM, board, rvec, tvec, effects=Effects(blur_sigma_px=0.8))
    assert rb.image.dtype == np.uint8 and rb.image.shape == (960, 1280)
    assert rb.in_image.all()
    ok, sb = cv2.findChessboardCornersSB(rb.image, (9, 6), flags=cv2.CALIB_CB_ACCURACY)
    assert ok
    sb = _match_order(sb.reshape(-1, 2), rb.corners_px)
    assert _rms(sb, rb.corners_px) <= 0.05
    ok, c = cv2.findChessboardCorners(rb.image, (9, 6))
    assert ok
    c = cv2.cornerSubPix(rb.image, c.reshape(-1, 1, 2).astype(np.float32), (11, 11), (-1, -1), CRIT).reshape(
        -1, 2
    )
    c = _match_order(c, rb.corners_px)
    assert _rms(c, rb.corners_px) <= 0.05


def test_checkerboard_corner_order_is_row_major_from_first_inner_corner():
    board = Checkerboard(5, 4, 30.0)
    rb = render_board(CAM, board, [0.0, 0.0, 0.0], [-60.0, -45.0, 500.0])
    # board x runs to image-right, y to image-down: row-major order walks right, then down
    assert np.all(np.diff(rb.corners_px[:5, 0]) > 0)
    assert rb.corners_px[5, 1] > rb.corners_px[0, 1]
    np.testing.assert_allclose(rb.object_points[6], [30.0, 30.0, 0.0])
    ok, c = cv2.findChessboardCornersSB(rb.image, (5, 4))
    assert ok


def test_charuco_detector_finds_every_corner_with_the_right_ids():
    board = CharucoBoard(7, 5, 30.0, 22.0)
    rb = render_board(
        CAM, board, [0.3, -0.3, 0.05], [-100.0, -60.0, 500.0], effects=Effects(blur_sigma_px=0.8)
    )
    det = cv2.aruco.CharucoDetector(board.cv_board())
    corners, ids, _, marker_ids = det.detectBoard(rb.image)
    assert ids is not None and len(ids) == len(rb.ids) == 24
    assert len(marker_ids) == 17
    ids = ids.ravel()
    assert _rms(corners.reshape(-1, 2), rb.corners_px[ids]) <= 0.1


def test_same_seed_same_bytes_and_noise_changes_with_seed():
    board = Checkerboard(4, 3, 20.0)
    fx = Effects(read_noise_dn=2.0, full_well_e=5000)
    a = render_board(CAM.scaled(0.5), board, [0.1, 0.1, 0], [-40.0, -30.0, 400.0], seed=3, effects=fx)
    b = render_board(CAM.scaled(0.5), board, [0.1, 0.1, 0], [-40.0, -30.0, 400.0], seed=3, effects=fx)
    c = render_board(CAM.scaled(0.5), board, [0.1, 0.1, 0], [-40.0, -30.0, 400.0], seed=4, effects=fx)
    assert a.image.tobytes() == b.image.tobytes()
    assert a.image.tobytes() != c.image.tobytes()


@pytest.mark.parametrize(
    "rvec,tvec", [([0.0, 0.0, 0.0], [-100.0, -60.0, 600.0]), ([0.3, -0.4, 0.6], [-60.0, -40.0, 500.0])]
)
def test_board_pixels_near_corners_match_brute_force_ray_casting(rvec, tvec):
    """Independent check of the whole pipeline: 64 x 64 rays per pixel through CameraModel.backproject."""
    board = Checkerboard(5, 4, 20.0)
    rb = render_board(CAM, board, rvec, tvec)
    ext = Extrinsics(rvec, tvec)
    R, tex, n = ext.rotation, board.texture(), 64
    sub = (np.arange(n) + 0.5) / n - 0.5
    for k in (0, 7, 19):
        cu, cv = np.round(rb.corners_px[k]).astype(int)
        us, vs = np.meshgrid(np.arange(cu - 3, cu + 4), np.arange(cv - 3, cv + 4))
        pu = us[..., None, None] + sub[None, None, None, :]
        pv = vs[..., None, None] + sub[None, None, :, None]
        uv = np.stack(np.broadcast_arrays(pu, pv), axis=-1).reshape(-1, 2)
        rays = CAM.backproject(uv)
        lam = (R[:, 2] @ ext.tvec_mm) / (rays @ R[:, 2])
        p = rays * lam[:, None] - ext.tvec_mm
        brute = tex.lookup(p @ R[:, 0], p @ R[:, 1]).reshape(7, 7, n * n).mean(axis=-1)
        err = rb.radiance[cv - 3 : cv + 4, cu - 3 : cu + 4] - brute
        contrast = 0.84
        assert np.abs(err).max() <= 1.5 * contrast / n  # the brute force's own sampling error
        assert np.sqrt(np.mean(err**2)) <= 0.25 * contrast / n
