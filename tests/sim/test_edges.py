"""Geometric exactness of the renderer: rendered straight edges lie on the analytic projection."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from doorloc.calib.camera import CameraModel
from doorloc.sim.edgecheck import edge_agreement
from doorloc.sim.raster import Surface, box_coverage, render_radiance

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


def _square(doubled_corner_offset_mm: np.ndarray | None) -> Surface:
    """A 200 mm square 1 m in front of the camera, one corner given twice (the copy ``offset`` from it)."""
    poly = [[-100.0, -100.0], [100.0, -100.0], [100.0, 100.0], [-100.0, 100.0]]
    if doubled_corner_offset_mm is not None:
        poly.insert(3, list(np.array([100.0, 100.0]) + doubled_corner_offset_mm))
    return Surface(
        origin=np.array([0.0, 0.0, 1000.0]),
        s_axis=np.array([1.0, 0, 0]),
        t_axis=np.array([0, 1.0, 0]),
        polygon_st=np.array(poly),
        shade=1.0,
    )


@settings(max_examples=25, deadline=None)
@given(angle=st.floats(0.0, 2.0 * np.pi), length=st.floats(1e-12, 1e-9))
def test_an_outline_with_a_corner_given_twice_renders_as_without(angle, length):
    """A face clipped by three planes at one corner has that corner twice, a rounding error apart; the
    edge between the copies has no direction worth the name, and must not cut the face (it cut a thin
    door's far face 4-11 px short at some poses: tests/sim/test_door.py)."""
    offset = length * np.array([np.cos(angle), np.sin(angle)])
    plain = render_radiance(NO_DIST, [_square(None)], 0.0)
    doubled = render_radiance(NO_DIST, [_square(offset)], 0.0)
    assert plain.sum() > 1000.0
    assert np.max(np.abs(doubled - plain)) <= 1e-6
