"""Sub-pixel edge estimator and robust line fits on synthetic data with known answers."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from doorloc.vision.edges import coarse_edges, subpixel_edges, transition_width
from doorloc.vision.lines import fit_rectangle_edges, ransac_line


def _box_step_image(edges_v: np.ndarray, low: float, high: float, blur: float = 0.0, n_rows: int = 60) -> np.ndarray:
    """Columns with a horizontal step at sub-pixel row ``edges_v[u]`` (dark above, bright below), box-filtered."""
    import cv2

    v = np.arange(n_rows)[:, None]
    frac = np.clip(v + 0.5 - edges_v[None, :], 0.0, 1.0)  # exact pixel coverage of the bright side
    img = low + (high - low) * frac
    if blur > 0:
        img = cv2.GaussianBlur(img, (0, 0), blur, borderType=cv2.BORDER_REFLECT)
    return img


@settings(max_examples=25, deadline=None)
@given(st.floats(20.0, 40.0), st.floats(0.0, 2.0), st.floats(-0.05, 0.05))
def test_area_estimator_is_unbiased_for_box_filtered_blurred_steps(e0, blur, slope):
    u = np.arange(200)
    edges_v = e0 + slope * (u - 100)
    img = _box_step_image(edges_v, 30.0, 200.0, blur)
    half = int(np.clip(math.ceil(3 * max(blur, 0.3) + 1.5), 3, 9))
    s = subpixel_edges(img, "col", u, edges_v + 0.3, half, plateau=4)
    assert s.valid.all()
    # A straight slanted edge integrated over the column width is exact at the column centre
    # (columns near the image sides are left out: the blur's border reflection bends the edge there).
    inner = slice(12, -12)
    assert np.max(np.abs(s.along - edges_v)[inner]) < 2e-3
    assert np.allclose(s.step, 170.0, atol=0.5)


def test_linear_shading_across_the_edge_is_cancelled():
    u = np.arange(120)
    edges_v = np.full(u.size, 30.37)
    img = _box_step_image(edges_v, 40.0, 180.0, 1.0)
    img = img * (1.0 + 0.01 * (np.arange(img.shape[0])[:, None] - 30))  # 1 % per pixel gradient
    flat = subpixel_edges(img, "col", u, edges_v + 2.4, 6, plateau=4)  # off-centre window, flat plateaus
    sloped = subpixel_edges(img, "col", u, edges_v + 2.4, 6, plateau=4, slope_smooth=5)
    assert np.median(np.abs(sloped.along - 30.37)) < 0.01
    assert np.median(np.abs(sloped.along - 30.37)) < np.median(np.abs(flat.along - 30.37))


def test_window_that_misses_the_edge_is_invalid():
    img = _box_step_image(np.full(50, 30.2), 20.0, 200.0)
    s = subpixel_edges(img, "col", np.arange(50), np.full(50, 45.0), 3, plateau=4)
    assert not s.valid.any()


def test_transition_width_measures_the_blur():
    u = np.arange(300)
    edges_v = 30.0 + 0.01 * u
    img = _box_step_image(edges_v, 20.0, 200.0, 2.0, n_rows=70)
    s = subpixel_edges(img, "col", u, edges_v, 9, plateau=4)
    w = transition_width(img, s, s.valid, 9)
    assert abs(w - math.sqrt(4.0 + 1.0 / 12.0)) < 0.1


def test_coarse_edges_respects_polarity_and_band():
    img = np.full((40, 100), 50.0)
    img[:, 30:] = 200.0  # rising at u = 29.5
    img[:, 70:] = 60.0  # falling at u = 69.5
    rows = np.arange(5, 35)
    lo, hi = np.full(rows.size, 10), np.full(rows.size, 90)
    a_up, s_up = coarse_edges(img, "row", rows, lo, hi, +1)
    a_dn, s_dn = coarse_edges(img, "row", rows, lo, hi, -1)
    assert np.all(a_up == 29.5) and np.all(a_dn == 69.5)
    assert np.all(s_up > 100) and np.all(s_dn > 100)


@settings(max_examples=25, deadline=None)
@given(st.floats(-3.0, 3.0), st.floats(-20, 20), st.floats(-20, 20), st.floats(20, 110), st.integers(0, 2**31 - 1))
def test_rectangle_fit_recovers_angle_offsets_despite_outliers(yaw_deg, x0, z0, thickness, seed):
    rng = np.random.default_rng(seed)
    t = math.radians(yaw_deg)
    ex, ez = np.array([math.cos(t), math.sin(t)]), np.array([-math.sin(t), math.cos(t)])
    c = np.array([x0, z0])
    zs, xs = np.linspace(3, 140, 300), np.linspace(3, thickness - 3, 120)
    ref = c + zs[:, None] * ez + rng.normal(0, 0.01, (300, 1)) * ex
    far = c + thickness * ex + zs[:, None] * ez + rng.normal(0, 0.01, (300, 1)) * ex
    bot = c + xs[:, None] * ex + rng.normal(0, 0.01, (120, 1)) * ez
    ref[:30] += 2.0 * ex  # a clump of outliers (debris on the edge)
    fit = fit_rectangle_edges({"bottom": (bot, True), "reference": (ref, False), "far": (far, False)})
    assert abs(math.degrees(fit.angle_rad) - yaw_deg) < 4e-3  # ~6 sigma for 0.01 mm point noise
    assert abs(fit.offsets["reference"] - c @ ex) < 6e-3  # ~6 sigma
    assert abs(fit.offsets["far"] - fit.offsets["reference"] - thickness) < 6e-3
    assert abs(fit.offsets["bottom"] - c @ ez) < 8e-3
    assert (fit.weights["reference"][:30] == 0).all()


def test_ransac_line_ignores_outliers():
    s = np.arange(100.0)
    a = 5.0 + 0.03 * s
    a[::5] += 40.0
    line = ransac_line(s, a, 1.0)
    assert line is not None
    assert abs(line.b - 0.03) < 1e-9 and abs(line.a - 5.0) < 1e-7
    assert line.inliers.sum() == 80
