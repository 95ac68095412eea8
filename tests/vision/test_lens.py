"""The compiled lens model (doorloc.vision.lens) gives the camera model's answers: the Newton solution of
:meth:`CameraModel.undistort_normalized` to the bit over the image a door can fill and beyond, the same NaN
where the model cannot tell, and :meth:`CameraModel.distort` to the bit."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from doorloc.calib.camera import CameraModel
from doorloc.vision.lens import MAX_ITER, distort_to_pixels, undistort_pixels

K = [[1678.35, 0, 946.41], [0, 1727.22, 510.71], [0, 0, 1]]


def _kvec(cam: CameraModel) -> np.ndarray:
    return np.array([cam.fx, cam.skew, cam.cx, cam.fy, cam.cy])


@settings(max_examples=60, deadline=None)
@given(
    st.floats(-0.4, 0.3),
    st.floats(-0.2, 0.2),
    st.floats(-0.005, 0.005),
    st.floats(-0.005, 0.005),
    st.floats(-0.1, 0.1),
    st.sampled_from([5, 8, 12]),
    st.integers(0, 2**32 - 1),
)
def test_undistort_matches_newton_over_the_image(k1, k2, p1, p2, k3, n, seed):
    rng = np.random.default_rng(seed)
    d = np.zeros(n)
    d[:5] = k1, k2, p1, p2, k3
    if n >= 8:
        d[5:8] = rng.uniform(-0.1, 0.1, 3)
    if n == 12:
        d[8:] = rng.uniform(-0.003, 0.003, 4)
    cam = CameraModel.from_values(K, d, (1920, 1080))
    # random pixels over the whole frame and a little beyond (a door's edges can run to its border)
    uv = rng.uniform([-20.0, -20.0], [1940.0, 1100.0], (200, 2))
    got = undistort_pixels(uv, _kvec(cam), cam.coeffs12, MAX_ITER)
    want = cam.undistort(uv)
    assert np.array_equal(np.isnan(got), np.isnan(want)), f"seed {seed}: another set of pixels without a ray"
    ok = ~np.isnan(want[:, 0])
    # the same Newton iteration, step for step: the same numbers to the bit (so well within 1e-6 px)
    np.testing.assert_array_equal(got[ok], want[ok], err_msg=f"seed {seed}")
    # and the answer reproduces the pixel through the forward model
    back = distort_to_pixels(got[ok, 0].copy(), got[ok, 1].copy(), _kvec(cam), cam.coeffs12)
    assert np.abs(back - uv[ok]).max(initial=0.0) < 1e-6


def test_undistort_refuses_beyond_the_fold():
    # the thesis's reported coefficients fold over about 560 px from the principal point
    cam = CameraModel.from_values(K, [0.0206, 10.4073, 0, 0, -115.4536], (1920, 1080))
    uv = np.array([[946.41 + 100.0, 510.71], [0.0, 0.0], [1919.0, 1079.0]])
    got = undistort_pixels(uv, _kvec(cam), cam.coeffs12, MAX_ITER)
    want = cam.undistort(uv)
    assert np.isfinite(got[0]).all()
    assert np.isnan(got[1:]).all()
    assert np.array_equal(np.isnan(got), np.isnan(want))


@settings(max_examples=40, deadline=None)
@given(st.floats(-0.4, 0.3), st.floats(-0.2, 0.2), st.floats(-0.01, 0.01), st.integers(0, 2**32 - 1))
def test_distort_matches_the_camera_model(k1, k2, p1, seed):
    cam = CameraModel.from_values(K, [k1, k2, p1, -p1, 0.01], (1920, 1080))
    xy = np.random.default_rng(seed).uniform(-0.7, 0.7, (100, 2))
    got = distort_to_pixels(xy[:, 0].copy(), xy[:, 1].copy(), _kvec(cam), cam.coeffs12)
    want = cam.normalized_to_pixel(cam.distort(xy))
    np.testing.assert_array_equal(got, want)
