"""Sub-pixel edge estimator and robust line fits on synthetic data with known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from doorloc.vision.coarse import coarse_edges
from doorloc.vision.edge_samples import ScanWindow
from doorloc.vision.edges import AreaEdgeReader, subpixel_edges
from doorloc.vision.far_band import FarBand
from doorloc.vision.far_face import BLUR_DOUBT, subpixel_edges_far_face
from doorloc.vision.lines import (
    fit_image_line,
    fit_rectangle_edges,
    fit_rectangle_lines,
    own_scatter_weights,
    ransac_line,
    revote_direction,
)
from doorloc.vision.step_blur import step_blur
from doorloc.vision.transition import transition_width


def _box_step_image(
    edges_v: np.ndarray, low: float, high: float, blur: float = 0.0, n_rows: int = 60
) -> np.ndarray:
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


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float64])
@pytest.mark.parametrize("axis", ["col", "row"])
def test_a_prepared_area_reader_reads_what_subpixel_edges_reads(dtype, axis):
    """The board check reads one photograph's windows through hundreds of response tables: the prepared
    reader gives subpixel_edges's edges and validity to the bit, with and without a table, on the planes
    the compiled branch reads and on others (which take subpixel_edges whole); windows cut by the image's
    border and a prediction of NaN included."""
    rng = np.random.default_rng(5)
    edges_v = 30.0 + 0.2 * (np.arange(80) - 40) + rng.uniform(-0.4, 0.4, 80)
    img = _box_step_image(edges_v, 20.0, 200.0, 1.2, n_rows=64) + rng.normal(0, 1.5, (64, 80))
    top = 255 if dtype != np.uint16 else 4095
    plane = np.clip(img * top / 255, 0, top).astype(dtype)
    if axis == "row":
        plane = np.ascontiguousarray(plane.T)
    scan = np.arange(80)
    centre = edges_v + rng.uniform(-1, 1, 80)
    centre[[0, 7]] = [np.nan, 62.0]  # no prediction; a window past the image's end
    reader = AreaEdgeReader(plane, axis, scan, centre, 4, plateau=3)
    luts = [None, ((np.arange(top + 1) / top) ** 2.2 * top).astype(np.float32)]
    for lut in luts[: 1 if dtype == np.float64 else 2]:  # (a table maps stored integer levels only)
        s = subpixel_edges(plane, axis, scan, centre, 4, plateau=3, lut=lut)
        along, valid = reader.along(lut)
        assert np.array_equal(valid, s.valid) and valid.sum() > 60
        assert np.array_equal(along, s.along, equal_nan=True)


def test_transition_width_measures_the_blur():
    u = np.arange(300)
    edges_v = 30.0 + 0.01 * u
    img = _box_step_image(edges_v, 20.0, 200.0, 2.0, n_rows=70)
    s = subpixel_edges(img, "col", u, edges_v, 9, plateau=4)
    w = transition_width(img, s, s.valid, 9)
    assert abs(w - math.sqrt(4.0 + 1.0 / 12.0)) < 0.1


@pytest.mark.parametrize("blur", [1.6, 2.0])
def test_transition_width_on_the_quiet_side_is_not_widened_by_texture_beside_the_edge(blur):
    """A grain line brightening the face a few px beyond the edge adds to the step that normalises the
    gradients: the whole window reads it as blur; the background's half of the mean transition does not."""
    import cv2

    u = np.arange(300)
    edges_v = 30.0 + 0.01 * u
    d = np.arange(80)[:, None] + 0.5 - edges_v[None, :]
    grain = 1.0 + 0.2 * np.where(d > 0, 1.0 - np.cos(2.0 * np.pi * np.clip(d, 0.0, None) / 14.0), 0.0)
    img = 20.0 + 180.0 * np.clip(d, 0.0, 1.0) * grain  # dark above (the background), the face below
    img = cv2.GaussianBlur(img, (0, 0), blur, borderType=cv2.BORDER_REFLECT)
    s = subpixel_edges(img, "col", u, edges_v, 9, plateau=4)
    true = math.sqrt(blur * blur + 1.0 / 12.0)
    whole = transition_width(img, s, s.valid, 9)
    quiet = transition_width(img, s, s.valid, 9, quiet_side=-1)
    assert whole > true + 0.2
    assert abs(quiet - true) < 0.1
    # the textured side's half is no better than the whole, and a clean edge reads alike either way
    assert transition_width(img, s, s.valid, 9, quiet_side=1) == pytest.approx(whole)
    clean = cv2.GaussianBlur(20.0 + 180.0 * np.clip(d, 0.0, 1.0), (0, 0), blur, borderType=cv2.BORDER_REFLECT)
    sc = subpixel_edges(clean, "col", u, edges_v, 9, plateau=4)
    assert transition_width(clean, sc, sc.valid, 9, quiet_side=-1) == pytest.approx(
        transition_width(clean, sc, sc.valid, 9), abs=0.03
    )


@pytest.mark.parametrize("blur", [0.0, 0.5, 1.0, 1.5, 2.0])
@pytest.mark.parametrize("row", [30.0, 30.1, 30.37, 30.5])
def test_transition_width_of_an_edge_along_a_pixel_row(blur, row):
    """Every profile at one pixel phase fills one bin in four of the width's 0.25 px grid: the width is
    still the blur's (it was read three times too wide there: a sharp edge 2 px, a 1 px blur 1.5)."""
    u = np.arange(300)
    edges_v = np.full(u.size, row)
    img = _box_step_image(edges_v, 20.0, 200.0, blur, n_rows=70)
    s = subpixel_edges(img, "col", u, edges_v, 9, plateau=4)
    w = transition_width(img, s, s.valid, 9)
    if blur == 0.0:
        # a sharp step at one phase: one or two pixels of gradient, 0 to 0.5 px apart (the phase decides)
        assert w <= 0.55, w
    else:
        expected = math.sqrt(blur * blur + 1.0 / 12.0)
        assert abs(w - expected) < max(0.15 * expected, 0.12), (w, expected)


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
@given(
    st.floats(-3.0, 3.0),
    st.floats(-20, 20),
    st.floats(-20, 20),
    st.floats(20, 110),
    st.integers(0, 2**31 - 1),
)
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


@settings(max_examples=60, deadline=None)
@given(
    st.floats(1e-9, 1e-3) | st.floats(-1e-3, -1e-9) | st.just(0.0),
    st.floats(-10, 10),
    st.floats(-10, 10),
    st.floats(30, 100),
)
def test_rectangle_fit_of_exact_lines_keeps_a_tiny_angle(yaw_deg, x0, z0, thickness):
    # the normal of a line near an axis came from a difference of near-equal scatter terms, whose
    # rounding turned a 3e-7 deg door by 1e-6 deg (a model-check property test's failure in CI)
    t = math.radians(yaw_deg)
    ex, ez = np.array([math.cos(t), math.sin(t)]), np.array([-math.sin(t), math.cos(t)])
    c = np.array([x0, z0])
    zs, xs = np.linspace(1, 80, 40), np.linspace(2, thickness - 2, 40)
    groups = {
        "bottom": (c + xs[:, None] * ex, True),
        "reference": (c + zs[:, None] * ez, False),
        "far": (c + thickness * ex + zs[:, None] * ez, False),
    }
    fit = fit_rectangle_edges(groups, n_iter=1)
    assert abs(fit.angle_rad - t) < 1e-14
    assert abs(fit.offsets["reference"] - c @ ex) < 1e-12
    assert abs(fit.offsets["bottom"] - c @ ez) < 1e-12


@settings(max_examples=25, deadline=None)
@given(st.floats(-3.0, 3.0), st.floats(20, 110), st.integers(1, 9), st.integers(0, 2**31 - 1))
def test_the_lines_alone_are_the_rectangle_fit_s_bit_for_bit(yaw_deg, thickness, n_iter, seed):
    rng = np.random.default_rng(seed)
    t = math.radians(yaw_deg)
    ex, ez = np.array([math.cos(t), math.sin(t)]), np.array([-math.sin(t), math.cos(t)])
    zs, xs = np.linspace(1, 80, 24), np.linspace(2, thickness - 2, 24)
    groups = {
        "bottom": (xs[:, None] * ex + rng.normal(0, 0.01, (24, 1)) * ez, True),
        "reference": (zs[:, None] * ez + rng.normal(0, 0.01, (24, 1)) * ex, False),
        "far": (thickness * ex + zs[:, None] * ez + rng.normal(0, 0.01, (24, 1)) * ex, False),
    }
    groups["far"][0][:3] += 1.5 * ex  # outliers, so that later iterations reweigh
    fit = fit_rectangle_edges(groups, n_iter=n_iter)
    assert fit_rectangle_lines(groups, n_iter=n_iter) == (fit.angle_rad, fit.offsets)


@settings(max_examples=40, deadline=None)
@given(
    st.floats(-2.0, 2.0),
    st.lists(st.floats(-0.05, 0.05), min_size=3, max_size=3),
    st.lists(st.floats(0.01, 100.0), min_size=3, max_size=3),
    st.floats(20, 110),
)
def test_a_revoted_direction_is_the_lines_own_directions_weighed_by_their_votes(
    yaw_deg, tilts_deg, votes, thickness
):
    """Three exact lines, each turned by its own small angle about its middle: the revoted direction is the
    votes' weighted mean of the three (to second order in the tilts), and each offset goes through its
    line's points."""

    def line(start, angle, along_x, length, n):
        t = math.radians(angle)
        d = np.array([math.cos(t), math.sin(t)]) if along_x else np.array([-math.sin(t), math.cos(t)])
        u = np.linspace(-0.5 * length, 0.5 * length, n)
        return start + u[:, None] * d

    t = math.radians(yaw_deg)
    ex, ez = np.array([math.cos(t), math.sin(t)]), np.array([-math.sin(t), math.cos(t)])
    names = ("bottom", "reference", "far")
    mids = {"bottom": 0.5 * thickness * ex, "reference": 70 * ez, "far": thickness * ex + 70 * ez}
    lengths = {"bottom": thickness - 4, "reference": 140.0, "far": 140.0}
    groups = {
        k: (line(mids[k], yaw_deg + d, k == "bottom", lengths[k], 60), k == "bottom")
        for k, d in zip(names, tilts_deg, strict=True)
    }
    fit = fit_rectangle_edges(groups, n_iter=1)
    revoted = revote_direction(fit, groups, dict(zip(names, votes, strict=True)))
    expected = yaw_deg + float(np.average(tilts_deg, weights=votes))
    assert abs(math.degrees(revoted.angle_rad) - expected) < 2e-4
    for k in names:
        assert abs(float(np.mean(revoted.residuals[k]))) < 1e-9


def test_a_line_without_a_vote_keeps_its_offset_only():
    t = math.radians(1.0)
    ex, ez = np.array([math.cos(t), math.sin(t)]), np.array([-math.sin(t), math.cos(t)])
    zs, xs = np.linspace(5, 140, 80), np.linspace(3, 37, 30)
    turned = math.radians(1.02)
    ref_dir = np.array([-math.sin(turned), math.cos(turned)])
    groups = {
        "bottom": (xs[:, None] * ex, True),
        "reference": (zs[:, None] * ref_dir, False),
        "far": (40 * ex + zs[:, None] * ez, False),
    }
    fit = fit_rectangle_edges(groups, n_iter=1)
    assert abs(math.degrees(fit.angle_rad) - 1.0) > 1e-3  # the joint fit has the turned line's share
    alone = revote_direction(fit, groups, {"reference": 1.0})
    assert abs(math.degrees(alone.angle_rad) - 1.02) < 1e-9
    others = revote_direction(fit, groups, {"bottom": 1.0, "far": 1.0})
    assert abs(math.degrees(others.angle_rad) - 1.0) < 1e-9


@settings(max_examples=30, deadline=None)
@given(
    amplitude=st.floats(0.1, 2.0),
    offset=st.floats(-3.0, 3.0),
    covered=st.floats(0.05, 0.4),
    seed=st.integers(0, 10_000),
)
def test_a_line_judged_by_its_own_scatter_keeps_a_slow_wave_and_drops_a_covered_stretch(
    amplitude, offset, covered, seed
):
    """A line's points on a slow wave about their own centre (grain beside a far arris) all keep weight,
    whatever the wave's size and wherever the centre lies; a stretch displaced by ten waves (something on the
    edge) weighs nothing, and points not valid or NaN weigh nothing."""
    rng = np.random.default_rng(seed)
    n = 500
    scan = np.arange(n, dtype=float)
    r = offset + amplitude * np.sin(2.0 * math.pi * scan / 430.0) + 0.02 * amplitude * rng.standard_normal(n)
    valid = np.ones(n, bool)
    valid[::50] = False
    r[7] = np.nan
    weights, centred = own_scatter_weights(r, valid)
    ok = valid & np.isfinite(r)
    assert np.all(weights[ok] > 0)
    assert np.all(weights[~ok] == 0)
    assert abs(np.nanmedian(centred[ok])) < 1e-9
    hit = (scan > 100) & (scan < 100 + covered * n)
    r[hit] += 10.0 * amplitude + 5.0
    weights, _ = own_scatter_weights(r, valid)
    assert np.all(weights[hit] == 0)
    assert np.count_nonzero(weights[ok & ~hit] > 0) >= 0.9 * np.count_nonzero(ok & ~hit)


def test_ransac_line_ignores_outliers():
    s = np.arange(100.0)
    a = 5.0 + 0.03 * s
    a[::5] += 40.0
    line = ransac_line(s, a, 1.0)
    assert line is not None
    assert abs(line.b - 0.03) < 1e-9 and abs(line.a - 5.0) < 1e-7
    assert line.inliers.sum() == 80


def _far_face_image(
    e1: np.ndarray, width: float, hinge: float, band: float, background: float, blur: float, n_rows: int = 80
) -> np.ndarray:
    """Columns across a far arris at row ``e1[u]``: hinge face above, a band ``width`` px wide, background below."""
    import cv2

    v = np.arange(n_rows)[:, None]
    cov1 = np.clip(v + 0.5 - e1[None, :], 0.0, 1.0)
    cov2 = np.clip(v + 0.5 - (e1 + width)[None, :], 0.0, 1.0)
    img = hinge + (band - hinge) * cov1 + (background - band) * cov2
    return cv2.GaussianBlur(img, (0, 0), blur, borderType=cv2.BORDER_REFLECT) if blur > 0 else img


def _far_window(img: np.ndarray, u: np.ndarray, centre: np.ndarray, door_side: int) -> ScanWindow:
    """Columns ``u`` across a far arris predicted at ``centre``: 6-px half window, 4-px plateaus, grey levels
    0-255 as they are, the hinge face on ``door_side``."""
    return ScanWindow(img, "col", u, centre, 6, 4, 1.0, None, 0, door_side)


@pytest.mark.parametrize(
    "width,blur", [(1.5, 0.8), (2.5, 0.8), (2.5, 1.6), (4.0, 1.6), (12.0, 0.8), (12.0, 1.6)]
)
@pytest.mark.parametrize("band", [190.0, 150.0, 80.0])
@pytest.mark.parametrize("miss", [-2.0, 1.0])
def test_far_face_fit_finds_the_arris_beside_a_band_of_any_brightness(width, blur, band, miss):
    """A band brighter than the hinge face (the area estimator's blind spot), between, or darker;
    noise-free, so the bound is the model's own (cv2's sampled blur kernel is not exactly the model's)."""
    u = np.arange(160)
    e1 = 30.0 + 0.013 * u  # every sub-pixel phase
    slope = -0.72  # the back edge moves 0.28 px per px of the arris
    img = _far_face_image(e1, width, 120.0, band, 50.0, blur)
    centre = e1 + miss  # a prediction off by up to 2 px; the band width predicted there follows the geometry
    s, fit = subpixel_edges_far_face(
        _far_window(img, u, centre, -1),
        FarBand(width + slope * (centre - e1), slope),
        blur_px=blur,
    )
    inner = slice(12, -12)
    assert s.valid[inner].all()
    assert np.max(np.abs(s.along - e1)[inner]) < 0.2
    assert abs(np.median((s.along - e1)[inner])) < 0.1
    assert fit.band_level == pytest.approx((band - 120.0) / (50.0 - 120.0), abs=0.1)


@pytest.mark.parametrize(("band", "ambiguous"), [(52.0, True), (118.0, True), (85.0, False)])
def test_a_band_like_the_background_or_the_hinge_face_names_its_other_reading(band, ambiguous):
    """A far face about as dark as the background leaves one step, the arris; one about as bright as the
    hinge face leaves one step too, its back edge. Each reading's other is a band's width away (inwards by
    w / (1 + slope): the band widens as the arris moves in; outwards by w), and the true arris is one of the
    two to within a pixel even where the fit takes the wrong one (the band 2 grey levels below the hinge
    face, noise-free: the fit reads the step as the arris). A band half-way between has one reading."""
    u = np.arange(160)
    e1 = 30.0 + 0.013 * u
    slope = -0.72
    img = _far_face_image(e1, 3.0, 120.0, band, 50.0, 0.8)
    s, fit = subpixel_edges_far_face(
        _far_window(img, u, e1, -1),
        FarBand(np.full(u.size, 3.0), slope),
        blur_px=0.8,
    )
    inner = slice(12, -12)
    assert s.valid[inner].all()
    if not ambiguous:
        assert fit.other_reading_px == 0.0
        assert np.max(np.abs(s.along - e1)[inner]) < 0.2
        return
    assert fit.other_reading_px != 0.0
    miss = [float(np.median((s.along + d - e1)[inner])) for d in (0.0, fit.other_reading_px)]
    # one reading within a pixel, and the arris within the reading's 2-sigma reach (sigma half the distance)
    assert min(abs(m) for m in miss) < 1.0, miss
    assert abs(miss[0]) <= abs(fit.other_reading_px), miss


@pytest.mark.parametrize(
    "width,blur,band",
    [(0.5, 0.8, 190.0), (0.5, 1.6, 150.0), (1.0, 1.6, 190.0), (1.0, 0.8, 80.0), (1.5, 1.6, 150.0)],
)
def test_far_face_fit_beside_a_band_narrower_than_the_blur_stays_within_a_pixel_and_a_half(width, blur, band):
    """Band level, width and blur trade off here: the arris is not exact, but far within the 1 mm
    (about 5 px) thickness tolerance."""
    u = np.arange(160)
    e1 = 30.0 + 0.013 * u
    img = _far_face_image(e1, width, 120.0, band, 50.0, blur)
    s, _ = subpixel_edges_far_face(
        _far_window(img, u, e1 + 0.6, -1),
        FarBand(width - 0.72 * 0.6, -0.72),
        blur_px=blur,
    )
    assert s.valid[12:-12].all() and np.max(np.abs(s.along - e1)[12:-12]) < 1.5


@pytest.mark.parametrize(
    "width,blur,band,blur_off",
    [(1.0, 1.2, 85.0, BLUR_DOUBT), (1.5, 1.2, 118.0, -BLUR_DOUBT), (1.0, 1.6, 60.0, BLUR_DOUBT)],
)
def test_the_far_face_doubt_covers_a_blur_off_by_its_doubt_beside_a_narrow_band(width, blur, band, blur_off):
    """The fit takes the reference arris's blur; given one off by BLUR_DOUBT beside a band about as narrow as
    the blur, it moves the band's level to make up for it, and that level moves the arris (noise-free: the
    miss is the model's alone). Counted at a fixed level the doubt missed it at 4-8 sigma."""
    u = np.arange(160)
    e1 = 30.0 + 0.013 * u
    img = _far_face_image(e1, width, 120.0, band, 50.0, blur)
    s, fit = subpixel_edges_far_face(
        _far_window(img, u, e1, -1),
        FarBand(np.full(u.size, width), -0.72),
        blur_px=blur + blur_off,
    )
    miss = float(np.median((s.along - e1)[12:-12]))
    assert abs(miss) > 0.25  # the case: a miss of a quarter pixel and more
    assert abs(miss) <= 2.0 * math.hypot(fit.model_sigma_px, fit.arris_sigma_px), (miss, fit)


def test_far_face_fit_without_a_band_is_a_plain_step_and_step_blur_measures_the_blur():
    u = np.arange(160)
    e1 = 30.0 + 0.013 * u
    img = _far_face_image(e1, 0.0, 120.0, 120.0, 50.0, 1.2)
    s, fit = subpixel_edges_far_face(
        _far_window(img, u, e1 + 0.7, -1),
        FarBand(np.full(u.size, -1.5), -0.72),
        blur_px=1.2,
    )
    assert np.max(np.abs(s.along - e1)[12:-12]) < 0.01 and fit.band_px == 0.0
    plain = subpixel_edges(img, "col", u, e1, 6, plateau=4)
    assert step_blur(img, plain, np.arange(u.size) % 10 > 0, 6) == pytest.approx(1.2, abs=0.03)
    # mirrored: the hinge face below, the background above
    s2, _ = subpixel_edges_far_face(
        _far_window(img[::-1], u, 79 - e1 + 0.5, +1),
        FarBand(np.full(u.size, -0.5), -0.72),
        blur_px=1.2,
    )
    assert np.max(np.abs(s2.along - (79 - e1))[12:-12]) < 0.01


@pytest.mark.parametrize("seed", range(12))
def test_far_face_start_ranked_on_a_subset_of_scan_lines_gives_the_exhaustive_search_s_answer(
    seed, monkeypatch
):
    """The start search ranks its shifts on a subset of the scan lines and costs the best few on all of them
    (speed): on noisy, grainy profiles with a prediction off by up to 5 px it ends exactly where
    costing every shift on every line ends (ranking on 10 lines and keeping only the best fails 3 of these)."""
    import doorloc.vision.far_face as far_face_mod

    rng = np.random.default_rng(seed)
    u = np.arange(400)
    e1 = 30.0 + 0.013 * u + 0.2 * np.sin(u / 37.0)
    img = _far_face_image(
        e1, rng.uniform(0.3, 6.0), 120.0, rng.uniform(60.0, 200.0), 50.0, rng.uniform(0.6, 1.8)
    )
    img = img * (1.0 + 0.08 * np.sin(u / rng.uniform(3.0, 9.0)))[None, :] + rng.normal(0.0, 8.0, img.shape)
    miss = rng.uniform(-5.0, 5.0)
    args = (
        _far_window(img, u, e1 + miss, -1),
        FarBand(np.full(u.size, 3.0), -0.72),
    )
    every = []  # the scan-line strides the start search costed its shifts on
    costs = far_face_mod.far_face_start_costs
    monkeypatch.setattr(far_face_mod, "far_face_start_costs", lambda *a: every.append(a[-1]) or costs(*a))
    s, fit = subpixel_edges_far_face(*args, blur_px=1.0)
    assert every[0] > 1 and every[1:] == [1]  # the subset ranking ran, then the best on every line
    monkeypatch.setattr(far_face_mod, "START_SUBSET_MIN_LINES", 10**9)
    s_all, fit_all = subpixel_edges_far_face(*args, blur_px=1.0)
    assert every[2:] == [1]  # every shift on every line
    np.testing.assert_array_equal(s.along, s_all.along)
    assert str(fit) == str(fit_all)  # (NaN fields compare unequal)


def test_fit_image_line_is_the_least_squares_line_and_refuses_too_few_samples():
    rng = np.random.default_rng(3)
    scan = np.sort(rng.choice(1000, 50, replace=False))
    along = 12.5 + 0.013 * scan
    line = fit_image_line(scan, along)
    assert line.b == pytest.approx(0.013, abs=1e-12) and line.a == pytest.approx(12.5, abs=1e-9)
    assert line.inliers.all() and line.inliers.size == scan.size
    noisy = along + rng.normal(0, 0.3, scan.size)
    b, a = np.polyfit(scan, noisy, 1)
    got = fit_image_line(scan, noisy)
    assert got.b == pytest.approx(b, rel=1e-9) and got.a == pytest.approx(a, rel=1e-9)
    with pytest.raises(ValueError, match="two or more"):
        fit_image_line(scan[:1], along[:1])
