"""The camera model against OpenCV, and its own invariants (property tests)."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from doorloc.calib.camera import UNDISTORT_TOL, CameraModel, Extrinsics, PosedCamera, distortion_validity

THESIS_K = [[1678.35, 0, 946.41], [0, 1727.22, 510.71], [0, 0, 1]]

# Realistic lenses: barrel or pincushion, mild tangential, optional rational terms.
dist5 = st.tuples(
    st.floats(-0.4, 0.2),
    st.floats(-0.2, 0.2),
    st.floats(-2e-3, 2e-3),
    st.floats(-2e-3, 2e-3),
    st.floats(-0.1, 0.1),
)
dist8 = st.tuples(
    *(st.floats(-0.3, 0.3) for _ in range(2)),
    st.floats(-2e-3, 2e-3),
    st.floats(-2e-3, 2e-3),
    st.floats(-0.05, 0.05),
    *(st.floats(0.0, 0.3) for _ in range(3)),
)


def make_camera(d) -> CameraModel:
    return CameraModel.from_values(
        [[1000.0, 0.0, 640.2], [0, 1012.0, 359.7], [0, 0, 1]], list(d), (1280, 720)
    )


@settings(max_examples=60, deadline=None)
@given(d=st.one_of(dist5, dist8), seed=st.integers(0, 2**31 - 1))
def test_project_matches_opencv(d, seed):
    cam = make_camera(d)
    P = np.random.default_rng(seed).uniform([-400, -250, 800], [400, 250, 1600], (200, 3))
    ours = cam.project(P)
    ref, _ = cv2.projectPoints(P, np.zeros(3), np.zeros(3), cam.camera_matrix, cam.dist_coeffs)
    np.testing.assert_allclose(ours, ref.reshape(-1, 2), atol=1e-8)


@settings(max_examples=60, deadline=None)
@given(d=st.one_of(dist5, dist8), seed=st.integers(0, 2**31 - 1))
def test_undistort_inverts_distort_to_tolerance(d, seed):
    cam = make_camera(d)
    validity = distortion_validity(cam, n_angles=90, n_radii=800)
    xy = np.random.default_rng(seed).uniform([-0.6, -0.35], [0.6, 0.35], (300, 2))
    uv = cam.project(np.column_stack([xy, np.ones(len(xy))]))
    back = cam.undistort(uv)
    inside = np.linalg.norm(uv - [cam.cx, cam.cy], axis=1) < (validity.fold_radius_px or np.inf) * 0.98
    assert np.all(np.isfinite(back[inside]))
    # The residual in distorted normalized space is what Newton converges on.
    resid = cam.distort(back[inside]) - cam.pixel_to_normalized_distorted(uv[inside])
    assert np.max(np.abs(resid)) <= UNDISTORT_TOL
    np.testing.assert_allclose(back[inside], xy[inside], atol=1e-8)


def test_undistort_is_tighter_than_opencv_default():
    """OpenCV's default 5 fixed-point iterations leave errors that our Newton solver does not."""
    cam = CameraModel.from_values(
        [[600, 0, 320], [0, 600, 240], [0, 0, 1]], [-0.45, 0.25, 0, 0, -0.08], (640, 480)
    )
    xy = np.array([[0.5, 0.38], [-0.52, 0.36]])
    uv = cam.project(np.column_stack([xy, np.ones(2)]))
    cv_default = cv2.undistortPoints(uv.reshape(-1, 1, 2), cam.camera_matrix, cam.dist_coeffs).reshape(-1, 2)
    ours = cam.undistort(uv)
    assert np.max(np.abs(ours - xy)) < 1e-10
    assert np.max(np.abs(cv_default - xy)) > 1e-5


def test_backproject_is_unit_and_reprojects():
    cam = make_camera((-0.2, 0.05, 1e-3, -1e-3, 0.0))
    uv = np.array([[10.0, 20.0], [640.0, 360.0], [1270.0, 700.0]])
    rays = cam.backproject(uv)
    np.testing.assert_allclose(np.linalg.norm(rays, axis=1), 1.0)
    np.testing.assert_allclose(cam.project(rays * 1234.5), uv, atol=1e-7)


def test_beyond_fold_is_nan_not_a_guess():
    cam = CameraModel.from_values(THESIS_K, [0.0206, 10.4073, 0, 0, -115.4536], (1920, 1080))
    uv = cam.image_corners_px()
    assert np.all(np.isnan(cam.undistort(uv)))
    assert np.all(np.isfinite(cam.undistort([[946.41, 510.71], [1100.0, 600.0]])))


def test_thesis_coefficients_flagged_unusable():
    cam = CameraModel.from_values(THESIS_K, [0.0206, 10.4073, 0, 0, -115.4536], (1920, 1080))
    v = distortion_validity(cam)
    assert not v.corners_inside_fold
    assert v.fold_radius_px is not None and 500 < v.fold_radius_px < 620
    assert v.corner_radius_px == pytest.approx(math.hypot(973.09, 568.79), abs=1.0)
    assert not any(c["undistortable"] for c in v.corner_report)
    # The ray an ideal camera would image at a corner lands thousands of pixels away, on the far side.
    assert all(c["distortion_shift_px"] > 1000 for c in v.corner_report)
    assert v.warnings and "folds over" in v.warnings[0]


def test_mild_lens_valid_over_whole_image():
    v = distortion_validity(make_camera((-0.1, 0.02, 0, 0, 0)))
    assert v.corners_inside_fold and v.usable_over_whole_image and not v.warnings


def test_observed_radius_limits_validity():
    cam = make_camera((-0.1, 0.02, 0, 0, 0)).with_observed_radius(300.0)
    v = distortion_validity(cam)
    assert v.valid_radius_px == 300.0 and not v.usable_over_whole_image
    assert any("reached only" in w for w in v.warnings)


@pytest.mark.parametrize("n", [1, 3, 6, 14])
def test_unsupported_coefficient_counts_are_refused(n):
    with pytest.raises(ValueError, match="distortion coefficients"):
        CameraModel.from_values(THESIS_K, [0.0] * n, (1920, 1080))


def test_bad_camera_matrix_refused():
    with pytest.raises(ValueError, match="camera matrix"):
        CameraModel.from_values([[0, 0, 1], [0, 1, 1], [0, 0, 1]], [], (10, 10))
    with pytest.raises(ValueError, match="skew"):
        CameraModel.from_values([[1, 0.5, 1], [0, 1, 1], [0, 0, 1]], [], (10, 10))


def test_scaled_camera_projects_consistently():
    cam = make_camera((-0.2, 0.05, 0, 0, 0))
    half = cam.scaled(0.5)
    P = np.array([[100.0, -50.0, 1000.0]])
    np.testing.assert_allclose(half.project(P), (cam.project(P) + 0.5) * 0.5 - 0.5, atol=1e-9)


@settings(max_examples=50, deadline=None)
@given(
    rvec=st.tuples(*(st.floats(-3.0, 3.0) for _ in range(3))),
    tvec=st.tuples(*(st.floats(-500, 500) for _ in range(3))),
)
def test_extrinsics_match_opencv_rodrigues(rvec, tvec):
    ext = Extrinsics(rvec, tvec)
    R_cv, _ = cv2.Rodrigues(np.asarray(rvec, float))
    np.testing.assert_allclose(ext.rotation, R_cv, atol=1e-12)
    back = Extrinsics.from_rotation(ext.rotation, tvec)
    np.testing.assert_allclose(back.rotation, ext.rotation, atol=1e-9)
    np.testing.assert_allclose(ext.rotation @ ext.camera_centre_cell + ext.tvec_mm, 0, atol=1e-9)


unit_axes = st.tuples(*(st.floats(-1.0, 1.0) for _ in range(3))).filter(lambda v: 0.1 < np.linalg.norm(v))


@settings(max_examples=200, deadline=None)
@given(
    axis=unit_axes, log_gap=st.floats(-12.0, -1.0), tvec=st.tuples(*(st.floats(-500, 500) for _ in range(3)))
)
def test_extrinsics_round_trip_keeps_full_precision_near_half_turn(axis, log_gap, tvec):
    """Near 180 deg the textbook ``(R - R.T) / (2 sin theta)`` loses ~7 digits; the library route must not."""
    k = np.asarray(axis) / np.linalg.norm(axis)
    rvec = k * (math.pi - 10.0**log_gap)
    ext = Extrinsics(rvec, tvec)
    np.testing.assert_allclose(ext.rotation, cv2.Rodrigues(rvec)[0], atol=1e-12)
    back = Extrinsics.from_rotation(ext.rotation, tvec)
    np.testing.assert_allclose(back.rotation, ext.rotation, atol=1e-12)
    np.testing.assert_allclose(back.tvec_mm, tvec, atol=0)


@settings(max_examples=50, deadline=None)
@given(x=st.floats(-60, 120), z=st.floats(-60, 60), y=st.floats(-30, 30))
def test_plane_intersection_inverts_projection(x, z, y):
    cam = CameraModel.from_values(THESIS_K, [-0.08, 0.05, 0, 0, 0], (1920, 1080))
    pc = PosedCamera(cam, Extrinsics([math.pi / 2, 0, 0], [-30.0, 40.0, 350.0]))
    p = np.array([[x, y, z]])
    np.testing.assert_allclose(pc.intersect_plane_y(pc.project_cell(p), y), p, atol=1e-7)


def test_scale_mm_per_px_is_depth_over_focal():
    cam = CameraModel.from_values([[1000, 0, 640], [0, 1000, 360], [0, 0, 1]], [], (1280, 720))
    pc = PosedCamera(cam, Extrinsics([math.pi / 2, 0, 0], [0, 0, 400.0]))
    assert pc.scale_mm_per_px([0, 0, 0]) == pytest.approx(0.4, rel=1e-9)
    assert pc.scale_mm_per_px([0, 100, 0]) == pytest.approx(0.5, rel=1e-9)
