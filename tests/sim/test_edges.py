"""Geometric exactness of the renderer: rendered straight edges lie on the analytic projection."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from doorloc.calib.camera import CameraModel
from doorloc.sim.edgecheck import edge_agreement
from doorloc.sim.raster import box_coverage

K = [[800.0, 0, 479.5], [0, 800.0, 359.5], [0, 0, 1]]
NO_DIST = CameraModel.from_values(K, [0, 0, 0, 0, 0], (960, 720))
BARREL = CameraModel.from_values(K, [-0.25, 0.08, 0.001, -0.0008, 0.0], (960, 720))


@pytest.mark.parametrize("camera", [NO_DIST, BARREL], ids=["no-distortion", "distortion"])
@pytest.mark.parametrize("angle", [0.0, 2.0, 30.0])
@pytest.mark.parametrize("kind", ["outline", "texture"])
def test_edge_position_agrees_with_analytic_projection(camera, angle, kind):
    check = edge_agreement(camera, angle, kind=kind)
    assert check.residuals_px.size > 600
    assert check.rms_px <= 0.01
    assert np.max(np.abs(check.residuals_px)) <= 0.02


def test_distortion_really_bends_the_checked_edge():
    # guards the test above against checking a straight line only: the barrel edge is curved by pixels
    w, h = BARREL.image_size
    xs = np.linspace(0, w - 1, 5)
    ideal_row = np.full_like(xs, 0.75 * h)
    q = NO_DIST.undistort(np.stack([xs, ideal_row], axis=1))
    bent = BARREL.normalized_to_pixel(BARREL.distort(q))
    assert np.ptp(bent[:, 1]) > 5.0


@settings(max_examples=200, deadline=None)
@given(
    theta=st.floats(0, 2 * np.pi),
    d=st.floats(-0.8, 0.8),
)
def test_box_coverage_matches_dense_sampling(theta, d):
    m = np.array([np.cos(theta), np.sin(theta)])
    n = 400
    g = (np.arange(n) + 0.5) / n - 0.5
    du, dv = np.meshgrid(g, g)
    dense = np.mean(m[0] * du + m[1] * dv <= d)
    assert float(box_coverage(m, np.array(d))) == pytest.approx(dense, abs=3.0 / n)
