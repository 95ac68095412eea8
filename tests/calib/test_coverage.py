"""Coverage of the image by board corners, board tilts, and the projection uncertainty of planned views."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rendered_views import CORNER_SIGMA_PX, candidate_poses, true_camera
from scipy.spatial.transform import Rotation

from doorloc.calib.calibrate import CANDIDATES_BY_NAME, View, calibrate_views, pixels_within
from doorloc.calib.camera import Extrinsics
from doorloc.calib.coverage import (
    board_tilts_deg,
    cell_names,
    corner_coverage,
    coverage_gain,
    predicted_projection_sigma,
    select_views,
    thin_cells,
)

BOARD = np.array([[x * 25.0, y * 25.0, 0.0] for y in range(6) for x in range(9)])
PLUMB_BOB = CANDIDATES_BY_NAME["plumb_bob"]


def test_coverage_counts_each_corner_in_its_cell():
    pts = np.array([[0.0, 0.0], [639.4, 479.4], [1.0, 2.0], [330.0, 250.0], [-0.5, -0.5]])
    cov = corner_coverage(pts, (640, 480), (8, 6))
    assert cov.shape == (6, 8) and cov.sum() == 5
    assert cov[0, 0] == 3 and cov[5, 7] == 1 and cov[3, 4] == 1


def test_thin_cells_are_named_in_words():
    cov = np.full((6, 8), 20)
    cov[0, 7] = 2  # top-right corner cell
    cov[5, 0] = 0  # bottom-left
    thin = thin_cells(cov)
    assert sorted(thin) == [(0, 5), (7, 0)]
    assert cell_names(thin, cov.shape) == ["top-right", "bottom-left"]
    assert cell_names([(3, 2)], cov.shape) == ["centre"]
    assert coverage_gain(cov, np.array([[630.0, 10.0]]), (640, 480)) == pytest.approx(1 / 3)


def _r(axis: int, deg: float) -> np.ndarray:
    v = np.zeros(3)
    v[axis] = math.radians(deg)
    return cv2.Rodrigues(v)[0]


@settings(max_examples=40, deadline=None)
@given(a=st.floats(-60, 60), b=st.floats(-60, 60), roll=st.floats(-180, 180))
def test_board_tilts_are_recovered_from_the_pose(a, b, roll):
    # rolling the board about its own normal changes no tilt
    rx_first = _r(0, a) @ _r(1, b) @ _r(2, roll)
    ry_first = _r(1, b) @ _r(0, a) @ _r(2, roll)
    # scipy's matrix -> rotation vector keeps tiny angles (OpenCV's rounds them to zero)
    got = board_tilts_deg(Rotation.from_matrix(np.stack([rx_first, ry_first])).as_rotvec())
    assert got[0, 0] == pytest.approx(a, abs=1e-6)
    assert got[1, 1] == pytest.approx(b, abs=1e-6)
    assert board_tilts_deg([np.zeros(3)])[0] == pytest.approx([0.0, 0.0], abs=1e-12)


@pytest.fixture(scope="module")
def pool():
    cam = true_camera()
    return cam, candidate_poses(cam, BOARD, 60, np.random.default_rng(7))


def test_chosen_views_predict_less_uncertainty_than_the_first_ones(pool):
    cam, poses = pool
    grid = pixels_within(cam, 1e9, step_px=32.0)
    chosen = select_views(cam, PLUMB_BOB, poses, BOARD, 12, grid)
    assert len(set(chosen)) == 12
    s_chosen = predicted_projection_sigma(
        cam, PLUMB_BOB, [poses[i] for i in chosen], BOARD, grid, CORNER_SIGMA_PX
    )
    s_first = predicted_projection_sigma(cam, PLUMB_BOB, poses[:12], BOARD, grid, CORNER_SIGMA_PX)
    assert s_chosen.max() < 0.9 * s_first.max()
    # more views, less uncertainty
    more = select_views(cam, PLUMB_BOB, poses, BOARD, 24, grid, chosen=chosen)
    assert more[:12] == chosen
    assert (
        predicted_projection_sigma(
            cam, PLUMB_BOB, [poses[i] for i in more], BOARD, grid, CORNER_SIGMA_PX
        ).max()
        < s_chosen.max()
    )


def test_predicted_sigma_is_what_the_calibration_reports(pool):
    """Before any image: the prediction from the poses; after: the calibration's own figure on noisy corners."""
    cam, poses = pool
    rng = np.random.default_rng(1)
    views = []
    for k, (r, t) in enumerate(poses[:15]):
        px = cam.project(Extrinsics(r, t).cell_to_camera(BOARD))
        views.append(
            View(f"v{k}", BOARD, px + rng.normal(0, CORNER_SIGMA_PX, px.shape), np.arange(len(BOARD)))
        )
    res = calibrate_views(views, cam.image_size, candidates=(PLUMB_BOB,), reject=False)
    pixels = pixels_within(cam, res.camera.observed_radius_px, step_px=16.0)
    predicted = predicted_projection_sigma(cam, PLUMB_BOB, poses[:15], BOARD, pixels, CORNER_SIGMA_PX)
    reported = res.projection_sigma_px["max_observed_aligned"]
    assert predicted.max() == pytest.approx(reported, rel=0.15)  # the noise estimate itself varies by ~5 %


def test_max_error_quantile_of_one_pixel_is_the_rayleigh_quantile():
    from doorloc.calib.calibrate import max_error_quantile

    J = np.eye(2)[None]  # one pixel moving with two parameters of 0.05 px sigma each
    cov = 0.05**2 * np.eye(2)
    for q in (0.5, 0.95):
        assert max_error_quantile(J, cov, q, n_samples=20000) == pytest.approx(
            0.05 * math.sqrt(-2 * math.log(1 - q)), rel=0.03
        )
    # over many pixels moving independently, the largest error is larger than any one pixel's
    many = np.zeros((10, 2, 20))
    for m in range(10):
        many[m, 0, 2 * m] = many[m, 1, 2 * m + 1] = 1.0
    assert max_error_quantile(many, 0.05**2 * np.eye(20), 0.5) > 0.05 * math.sqrt(2 * math.log(2)) * 1.3
    assert max_error_quantile(np.full((3, 2, 2), np.nan), cov) is None
