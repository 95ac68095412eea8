"""Board detection: corner order, refinement window, accuracy against rendered truth."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from doorloc.calib.detect import (
    CharucoSpec,
    Chessboard,
    canonical_grid_order,
    detect_charuco,
    detect_chessboard,
    half_window_from_square,
    local_square_px,
    scan_images,
)


def _grid(cols, rows, angle_rad, spacing=20.0, origin=(300.0, 200.0)):
    c, r = np.meshgrid(np.arange(cols), np.arange(rows))
    p = np.stack([c.ravel(), r.ravel()], axis=1) * spacing
    R = np.array([[math.cos(angle_rad), -math.sin(angle_rad)], [math.sin(angle_rad), math.cos(angle_rad)]])
    return p @ R.T + origin


@settings(max_examples=50, deadline=None)
@given(st.floats(-180, 180), st.booleans(), st.integers(2, 9), st.integers(2, 8))
def test_canonical_order_is_the_same_whichever_end_a_detector_starts_from(angle_deg, reverse, cols, rows):
    g = _grid(cols, rows, math.radians(angle_deg))
    out = canonical_grid_order(g[::-1] if reverse else g, cols, rows)
    np.testing.assert_allclose(out, canonical_grid_order(g, cols, rows))
    # rows run left to right in the image (never right to left)
    assert out[cols - 1, 0] >= out[0, 0] - 1e-9
    if cols != rows and abs(angle_deg) < 89:
        np.testing.assert_allclose(out, g)


def test_square_pattern_allows_quarter_turns():
    g = _grid(5, 5, math.radians(10))
    turned = np.rot90(g.reshape(5, 5, 2), 1, axes=(0, 1)).reshape(-1, 2)
    np.testing.assert_allclose(canonical_grid_order(turned, 5, 5), g)


def test_refinement_window_stays_inside_the_local_square():
    g = _grid(6, 4, 0.2, spacing=12.0)
    sq = local_square_px(g, 6, 4)
    np.testing.assert_allclose(sq, 12.0)
    hw = half_window_from_square(np.array([6.0, 12.0, 25.0, 35.0, 200.0]))
    assert hw.tolist() == [2, 3, 7, 11, 15]
    # a window never reaches half-way to the neighbouring corner
    assert np.all(2 * hw[1:4] + 1 < np.array([12.0, 25.0, 35.0]))


def test_real_photographs_are_found_with_square_sized_windows(opencv_left):
    board, scan, views = opencv_left
    assert len(scan.detections) == 13 and not scan.skipped
    for det in scan.detections.values():
        assert det.corners_px.shape == (54, 2)
        assert np.all(det.half_window_px <= 0.35 * det.square_px)
        g = det.corners_px.reshape(6, 9, 2)
        assert np.mean(g[:, -1, 0] - g[:, 0, 0]) > 0  # canonical order: rows run to image-right


def test_rendered_chessboard_corners_are_sub_tenth_pixel():
    from rendered_views import plan_views, true_camera

    from doorloc.sim.boards import Checkerboard, render_board
    from doorloc.sim.effects import Effects

    cam = true_camera()
    sim_board = Checkerboard(9, 6, 25.0)
    board = Chessboard(9, 6, 25.0)
    errs = []
    for i, (r, t) in enumerate(plan_views(cam, sim_board.object_points(), 4, seed=5)):
        rb = render_board(cam, sim_board, r, t, seed=i, effects=Effects(blur_sigma_px=0.7, read_noise_dn=1.0))
        det = detect_chessboard(rb.image, board)
        assert det is not None
        d = np.linalg.norm(det.corners_px[:, None] - rb.corners_px[None], axis=2)
        match = d.argmin(axis=1)
        assert len(set(match.tolist())) == 54
        errs.append(det.corners_px - rb.corners_px[match])
        # same physical layout: the detected order is the truth order or its 180-degree reversal
        assert np.array_equal(match, np.arange(54)) or np.array_equal(match, np.arange(54)[::-1])
    e = np.concatenate(errs)
    assert np.sqrt(np.mean(np.sum(e**2, axis=1))) < 0.08
    assert np.max(np.linalg.norm(e, axis=1)) < 0.3


def test_rendered_charuco_corners_keep_their_ids():
    from rendered_views import true_camera

    from doorloc.sim.boards import CharucoBoard, render_board

    cam = true_camera()
    sim_board = CharucoBoard(7, 5, 30.0, 22.0, "DICT_4X4_50")
    spec = CharucoSpec(7, 5, 30.0, 22.0, "DICT_4X4_50")
    np.testing.assert_allclose(spec.object_points(), sim_board.object_points())
    rb = render_board(cam, sim_board, [0.2, -0.3, 0.05], [-90.0, -60.0, 420.0])
    det = detect_charuco(rb.image, spec)
    assert det is not None and len(det.ids) >= 20
    err = np.linalg.norm(det.corners_px - rb.corners_px[det.ids], axis=1)
    assert np.max(err) < 0.3


def test_scan_skips_unreadable_blank_and_odd_sized_images(opencv_left):
    import cv2

    from conftest import OPENCV_LEFT

    board = Chessboard(9, 6, 25.0)
    good = cv2.imread(str(OPENCV_LEFT / "left01.jpg"), cv2.IMREAD_GRAYSCALE)
    images = [
        ("good.jpg", good, None),
        ("broken.jpg", None, "is not an image OpenCV can decode"),
        ("blank.png", np.full_like(good, 128), None),
        ("small.png", cv2.resize(good, (320, 240)), None),
        ("good_bgr.jpg", cv2.cvtColor(good, cv2.COLOR_GRAY2BGR), None),
    ]
    scan = scan_images(images, board)
    assert scan.image_size == (640, 480)
    assert sorted(scan.detections) == ["good.jpg", "good_bgr.jpg"]
    reasons = {s.name: s.reason for s in scan.skipped}
    assert "decode" in reasons["broken.jpg"]
    assert "no 9x6 chessboard" in reasons["blank.png"]
    assert "320x240" in reasons["small.png"]


def test_16_bit_photographs_keep_their_levels_for_the_response(opencv_left):
    # a response is read on the levels as stored: the calibration's board views keep a 16-bit photograph's
    # depth (its levels v * 257 here read as v / 255 of full scale, as the 8-bit ones), and the model
    # check's 8-bit view of it is the fixed scale 255 / 65535, rounded, not each image stretched to its
    # own brightest level (a gain per photograph) and truncated
    from doorloc.calib.detect import stored_bits_of, stored_grey_8bit, to_gray
    from doorloc.calib.folder import full_board_views, read_folder
    from doorloc.vision.board_response import board_response

    board, scan, _ = opencv_left
    images = read_folder(Path(__file__).parents[2].parent / "shared" / "data" / "opencv-left", "left*.jpg")
    deep = [(name, None if im is None else im.astype(np.uint16) * 257, why) for name, im, why in images]
    v8 = full_board_views(images, scan, board)
    v16 = full_board_views(deep, scan, board)
    assert len(v8) == len(v16) == 13
    for (a, ca), (b, cb) in zip(v8, v16, strict=True):
        assert a.dtype == np.uint8 and b.dtype == np.uint16 and np.array_equal(b, a.astype(np.uint16) * 257)
        assert np.array_equal(stored_grey_8bit(b), a) and np.array_equal(ca, cb)
    r8, r16 = board_response(v8, 9, 6), board_response(v16, 9, 6)
    assert r8 is not None and r16 is not None
    # (the same light; a 16-bit image's rounding is taken as 1/65535 of full scale, not these levels' 1/255)
    assert abs(r16.gamma - r8.gamma) < 0.5 * r8.sigma, (r8, r16)
    # a 12-bit camera storing its levels from 0 (v as round(v * 4095 / 255)): its depth is read off the
    # photographs, its 8-bit view on its own full scale is the 8-bit photographs' levels again, and the
    # response reads the same light
    twelve_bit = [
        (n, None if im is None else np.rint(im * (4095 / 255)).astype(np.uint16), w) for n, im, w in images
    ]
    assert stored_bits_of(im for _, im, _ in twelve_bit) == 12
    assert (
        stored_bits_of(im for _, im, _ in deep) is None and stored_bits_of(im for _, im, _ in images) is None
    )
    v12 = full_board_views(twelve_bit, scan, board)
    for (a, _), (b, _) in zip(v8, v12, strict=True):
        assert b.dtype == np.uint16 and b.max() <= 4095 and np.array_equal(stored_grey_8bit(b, 12), a)
    r12 = board_response(v12, 9, 6)
    assert r12 is not None and abs(r12.gamma - r8.gamma) < 0.5 * r8.sigma, (r8, r12)
    # for finding corners a dark 16-bit image (12 bits of it used) is still stretched to its brightest level,
    # rounded (2000 of 4095 is 124.5 of 255: it was truncated to 124)
    twelve = np.array([[0, 1000, 2000, 4095]], np.uint16)
    assert to_gray(twelve).tolist() == [[0, 62, 125, 255]]
