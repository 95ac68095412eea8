"""Board edges placed and measured against the corner lines: rendered boards with a known print, the real
photographs' plain-model figure, and the photometric model's response maps."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from doorloc.calib.camera import CameraModel
from doorloc.calib.detect import Chessboard, detect_chessboard, to_gray
from doorloc.calib.folder import read_folder
from doorloc.calib.io import load_calibration
from doorloc.photometric.board_edges import BoardEdges, EdgeWindows, board_edge_curves, measure_board_edges
from doorloc.photometric.model import PhotometricModel
from doorloc.sim.boards import Checkerboard, render_board
from doorloc.sim.effects import Effects
from doorloc.sim.photometric import random_board_views

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"
CAMERA = CameraModel.from_values(
    [[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], [-0.2, 0.05, 0, 0, 0], (640, 480)
)


def _offsets(model: PhotometricModel, seed: int, n: int = 2) -> tuple[list[float], list[float]]:
    meds, scale = [], []
    for name, img in random_board_views(CAMERA, Checkerboard(9, 6, 25.0), model, n, seed):
        det = detect_chessboard(img, Chessboard(9, 6, 25.0))
        assert det is not None, name
        be = measure_board_edges(img, det.corners_px[np.argsort(det.ids)], 9, 6, 25.0, CAMERA, image=name)
        assert be.n_edges == 8 * 6 + 9 * 5
        meds.append(be.median_offset_px())
        scale.append(float(np.median(be.px_per_mm)))
    return meds, scale


def test_plain_rendered_board_has_no_offset():
    meds, _ = _offsets(PhotometricModel(), seed=11)
    assert np.all(np.abs(meds) < 0.02), meds


def test_print_spread_moves_edges_by_its_length_on_the_board():
    spread = 0.2
    meds, scale = _offsets(PhotometricModel(print_spread_mm=spread), seed=12)
    # dark squares grown: each edge lies towards the bright side by spread_mm at the board's scale
    np.testing.assert_allclose(meds, spread * np.asarray(scale), atol=0.04)


@pytest.mark.parametrize(
    "turn_rad, turned", [(0.2, False), (np.pi / 2 - 0.2, True), (-np.pi / 2 + 0.1, True)]
)
def test_a_board_turned_a_quarter_turn_is_told_from_one_that_is_not(turn_rad, turned):
    # a cause acting on one direction of edges in the image (the camera's lines) and one acting on one
    # direction on the board (its print) are told apart only by photographs turned both ways
    board = Checkerboard(9, 6, 25.0)
    centre = np.array([4 * 25.0, 2.5 * 25.0, 0.0])
    rvec = np.array([0.1, -0.1, turn_rad])
    R = cv2.Rodrigues(rvec)[0]
    tvec = -R @ centre + np.array([0.0, 0.0, 400.0])
    img = render_board(CAMERA, board, rvec, tvec, effects=Effects(blur_sigma_px=0.8)).image
    det = detect_chessboard(img, Chessboard(9, 6, 25.0))
    assert det is not None
    be = measure_board_edges(img, det.corners_px[np.argsort(det.ids)], 9, 6, 25.0, CAMERA, image="view")
    assert be.along_board_rows is not None and int(be.along_board_rows.sum()) == 8 * 6
    assert be.board_turned() is turned
    assert dataclasses.replace(be, along_board_rows=None).board_turned() is None


def test_edge_curve_follows_the_distortion_not_the_chord():
    cam = CameraModel.from_values(
        [[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], [-0.4, 0.1, 0, 0, 0], (640, 480)
    )
    # two corners far from the centre: the distorted image of the straight edge bows away from the chord
    obj = np.array([[-150.0, -100.0, 400.0], [-100.0, -100.0, 400.0]])
    uv = cam.project(obj)
    curve, _ = board_edge_curves(uv, 2, 1, cam, np.array([0.5]))
    true_mid = cam.project(0.5 * (obj[0] + obj[1])[None])[0]
    np.testing.assert_allclose(curve[0, 0], true_mid, atol=1e-6)
    assert np.linalg.norm(curve[0, 0] - uv.mean(0)) > 0.05


@settings(max_examples=40, deadline=None)
@given(
    st.floats(0.5, 3.0),
    st.floats(0.0, 0.15),
    st.floats(0.4, 1.0),
    st.floats(-0.3, 0.3),
    st.floats(0.02, 0.98),
)
# (a level just inside the flat dark end, 0.0015 below the curvature's turning point: rising across the
# window around it but not at it, it has no inverse; a fresh draw found it)
@example(0.5, 0.0, 1.0, 0.1171875, 0.1171875)
def test_response_maps_invert_each_other(gamma, black, shoulder, curvature, g):
    m = PhotometricModel(gamma=gamma, black_level=black, shoulder=shoulder, curvature=curvature)
    L, table_g = m.response_table()
    # rising on both sides of g (an inverse exists only where the response rises through it)
    rises = bool(np.all(np.diff(m.light_from_grey(np.array([g - 2e-3, g, g + 2e-3]))) > 0))
    if g <= black + 0.01 or not rises or g > table_g[-1]:
        return  # no inverse where the response is flat (held flat beyond the curvature's turning point)
    back = m.grey_from_light(m.light_from_grey(np.array([g])))[0]
    assert back == pytest.approx(g, abs=2e-3)


def test_model_refuses_unknown_or_bad_values():
    with pytest.raises(ValueError, match="unknown"):
        PhotometricModel.from_dict({"gama": 2.0})
    with pytest.raises(ValueError, match="gamma"):
        PhotometricModel(gamma=-1.0)
    assert PhotometricModel.from_dict(PhotometricModel(gamma=2.0).to_dict()) == PhotometricModel(gamma=2.0)


@pytest.mark.slow
@pytest.mark.skipif(not (DATA / "opencv-left").is_dir(), reason="../shared/data/opencv-left is not here")
def test_opencv_left_plain_offsets_as_measured_before():
    """The plain model's figure on OpenCV's left camera (published calibration): bright areas look larger on
    most photographs, RMS over photographs about 0.23 px."""
    cam = load_calibration(DATA / "opencv-left" / "published_left_intrinsics.yml").camera
    meds = []
    for name, img, _ in read_folder(DATA / "opencv-left", "left*.jpg"):
        gray = to_gray(img)
        det = detect_chessboard(gray, Chessboard(9, 6, 25.0))
        assert det is not None, name
        meds.append(
            measure_board_edges(gray, det.corners_px[np.argsort(det.ids)], 9, 6, 25.0, cam).median_offset_px()
        )
    meds = np.asarray(meds)
    assert 0.18 < np.sqrt(np.mean(meds**2)) < 0.28
    assert np.sum(meds < 0) >= 10 and meds.min() < -0.35


def _windows_of(grey: np.ndarray) -> BoardEdges:
    n = grey.shape[0]
    w = EdgeWindows(
        np.zeros(n, int),
        np.ones(n, bool),
        np.arange(n),
        np.full(n, 7.0),
        np.ones(n),
        np.ones(n),
        np.zeros(n, int),
        grey,
    )
    nan = np.full(n, np.nan)
    one = np.zeros((1, 2))
    return BoardEdges("synthetic", (64, 64), one, one, np.ones(1), np.ones(1), w, nan, nan, nan, nan)


@pytest.mark.parametrize("sigma", [0.7, 2.0, 5.0])
def test_plateau_spread_rms_reads_the_noise_sigma(sigma):
    rng = np.random.default_rng(3)
    step = np.where(np.arange(15) < 7, 40.0, 180.0)
    # each scan line with its own levels (light falling off along the edge): only the spread about them counts
    levels = rng.uniform(-10, 10, (4000, 1))
    grey = step[None, :] + levels + rng.normal(0.0, sigma, (4000, 15))
    assert BoardEdges.plateau_spread_rms(_windows_of(grey), 3) == pytest.approx(sigma, rel=0.03)


def test_plateau_spread_rms_is_an_rms_not_a_median():
    rng = np.random.default_rng(4)
    grey = np.where(np.arange(15) < 7, 40.0, 180.0)[None, :] + rng.normal(0.0, 1.0, (4000, 15))
    # one scan line in ten on a textured patch: the RMS rises well above the typical line's spread
    grey[::10] += rng.normal(0.0, 6.0, (400, 15))
    be = _windows_of(grey)
    assert be.plateau_spread_rms(3) == pytest.approx(np.sqrt(1.0 + 0.1 * 36.0), rel=0.05)
    assert be.plateau_spread_rms(3, np.arange(4000) % 10 != 0) == pytest.approx(1.0, rel=0.05)
    assert np.isnan(be.plateau_spread_rms(1))
