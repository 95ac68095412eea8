"""The blurred step with the face's level sloped: it finds an edge beside a flank of wood grain where the
flat readers do not, and the step-fit model reads a textured plain edge with it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.ndimage import gaussian_filter1d
from scipy.optimize import minimize_scalar

from doorloc.cell import DoorSize, load_cell
from doorloc.pose import DoorPose
from doorloc.sim.door import render_door
from doorloc.sim.effects import Effects
from doorloc.vision.blurred_step import face_slope_step_fit, step_fit
from doorloc.vision.edge_models import (
    EDGE_MODELS,
    FACE_SLOPE_HALF_PX,
    ScanWindow,
    edge_kind,
)
from doorloc.vision.edge_samples import EdgeSamples
from doorloc.vision.locate import locate
from doorloc.vision.region import Track
from doorloc.vision.step_fit_lines import STEP_FIT_PHASE_SWEEP_PX, phase_sweep_px, phase_swept


@pytest.fixture(scope="module")
def cell(thesis_cell_path):
    return load_cell(thesis_cell_path)


SUPER = 64  # sub-samples per pixel of the reference images: blurred finely, then averaged per pixel


def _profile(face, edge: float, sigma: float, side: int, n_px: int = 40, background: float = 40.0):
    """Pixel values (n_px,) of pixels ``0..n_px-1`` (pixel k spans k-0.5..k+0.5): the background, and
    beyond ``edge`` on the side ``side`` the face's light ``face(distance from the edge, px)``, blurred by
    a Gaussian ``sigma`` px and integrated over each pixel, sampled finely (none of the fit's closed forms)."""
    x = (np.arange(n_px * SUPER) + 0.5) / SUPER - 0.5
    d = side * (x - edge)
    # (the sub-sample the edge crosses takes each side's share: the edge is not moved to the sub-grid)
    on_face = np.clip(d * SUPER + 0.5, 0.0, 1.0)
    light = on_face * face(np.maximum(d, 0.0)) + (1.0 - on_face) * background
    # (the light beyond the row continues as at its ends: no step at the row's ends)
    blurred = gaussian_filter1d(light, sigma * SUPER, mode="nearest")
    return blurred.reshape(n_px, SUPER).mean(axis=1)


@settings(max_examples=40, deadline=None)
@given(
    edge=st.floats(-0.5, 0.5),
    slope=st.floats(-4.0, 4.0),
    sigma=st.floats(0.6, 2.0),
    side=st.sampled_from([1, -1]),
)
def test_the_sloped_fit_finds_the_edge_beside_a_face_that_changes_linearly(edge, slope, sigma, side):
    h = FACE_SLOPE_HALF_PX
    n_px = 40
    c = n_px // 2
    vals = _profile(lambda d: 120.0 + slope * d, c + edge, sigma, side, n_px)[c - h : c + h + 1]
    bounds = np.arange(-h, h + 2, dtype=np.float64) - 0.5
    got = face_slope_step_fit(vals[None], np.zeros(1), bounds, sigma, side)[0]
    assert abs(got - edge) < 2e-3
    flat = step_fit(vals[None], np.zeros(1), bounds, sigma)[0]
    if abs(slope) > 2.0:  # (the flat levels' reading is off by a tenth of a pixel or more there)
        assert abs(flat - edge) > 0.05


def test_the_sloped_fit_on_a_flat_face_reads_the_flat_fit_s_edge():
    vals = _profile(lambda d: np.full_like(d, 160.0), 20.3, 1.1, 1)[12:29]
    bounds = np.arange(-8, 10, dtype=np.float64) - 0.5
    sloped = face_slope_step_fit(vals[None], np.zeros(1), bounds, 1.1, 1)[0]
    flat = step_fit(vals[None], np.zeros(1), bounds, 1.1)[0]
    assert abs(sloped - 0.3) < 1e-3 and abs(flat - 0.3) < 1e-3


def test_a_long_arris_is_read_by_the_step_fit_model_once_the_sloped_fit_has_a_blur(pass_settings):
    track = Track(np.arange(10), np.full(10, 50.0))
    assert edge_kind("far", track, pass_settings()) == "plain"
    assert edge_kind("far", track, pass_settings(face_slope_blur_px=1.2)) == "step_fit"
    assert edge_kind("reference", track, pass_settings(face_slope_blur_px=1.2)) == "step_fit"
    # (the grain runs across the bottom end: its levels follow it scan line by scan line)
    assert edge_kind("bottom", track, pass_settings(face_slope_blur_px=1.2)) == "plain"


def _grained_plane(edge: float, contrast: float, sigma: float = 1.3) -> np.ndarray:
    """Rows of one profile: the door (face) at increasing column beyond ``edge``, its light a stripe of
    wood grain along the edge (period 60 px) rising from its dark trough across the edge and beyond it."""
    n_px = 64

    def face(d):
        return 110.0 * (1.0 - contrast * np.cos(2.0 * np.pi * (d / 60.0 + 0.125)))

    row = _profile(face, edge, sigma, 1, n_px)
    rng = np.random.default_rng(3)
    return row[None, :] + rng.normal(0.0, 0.3, size=(200, n_px))  # (a little sensor noise)


@pytest.mark.parametrize("contrast", [0.0, 0.25])
def test_a_plain_edge_beside_a_grain_flank_is_read_with_its_face_sloped(contrast, pass_settings):
    edge = 30.35
    plane = _grained_plane(edge, contrast)
    scan = np.arange(20, 180)
    window = ScanWindow(plane, "row", scan, np.full(scan.size, 30.0), 4, 3, 1.0, None, 0, 1)
    track = Track(window.scan, window.centre)
    model = EDGE_MODELS["step_fit"]
    area = EDGE_MODELS["plain"].read(window, "reference", track, pass_settings()).samples
    reading = model.read(window, "reference", track, pass_settings(face_slope_blur_px=1.3))
    err = np.median(reading.samples.along) - edge
    if contrast == 0.0:  # no texture: the area estimate stands, as before
        assert reading.face_slope_half_px is None
        np.testing.assert_array_equal(reading.samples.along, area.along)
        assert abs(err) < 0.02
        return
    # the flat readers put the edge towards the face (its level near the edge is the trough's) ...
    assert np.median(area.along) - edge > 0.2
    flat = model.read(window, "reference", track, pass_settings(step_blur_px={"reference": 1.3}))
    assert flat.face_slope_half_px is None and np.median(flat.samples.along) - edge > 0.1
    # ... the sloped fit where it is
    assert reading.face_slope_half_px == FACE_SLOPE_HALF_PX
    assert abs(err) < 0.05
    assert reading.readers_apart is not None and abs(reading.readers_apart.shift_px) < 0.2


def test_the_sloped_reader_finds_the_lens_blur_under_a_transition_the_grain_widened():
    # the flat transition widths read a grained edge wider than the lens makes it: the sloped reader is
    # given twice the blur and finds the lens's in the profiles' misfit
    from doorloc.vision.blurred_step import refine_face_slope_fit
    from doorloc.vision.edges import subpixel_edges

    edge = 30.35
    plane = _grained_plane(edge, 0.25, sigma=1.3)
    scan = np.arange(20, 180)
    window = ScanWindow(plane, "row", scan, np.full(scan.size, 30.0), 4, 3, 1.0, None, 0, 1)
    area = subpixel_edges(*window.lines, window.plateau, window.scale_to_8bit)
    got = refine_face_slope_fit(plane, area, FACE_SLOPE_HALF_PX - 1, 2.6, 1)
    assert abs(got.blur_px - 1.3) < 0.15
    assert abs(np.median(got.samples.along) - edge) < 0.05
    told = refine_face_slope_fit(plane, area, FACE_SLOPE_HALF_PX - 1, 2.6, 1, search_blur=False)
    assert told.blur_px == 2.6 and abs(np.median(told.samples.along) - edge) > 0.1


@settings(max_examples=25, deadline=None)
@given(
    edge=st.floats(-0.5, 0.5),
    slope=st.floats(-4.0, 4.0),
    sigma=st.floats(0.6, 2.0),
    noise=st.floats(0.5, 4.0),
    seed=st.integers(0, 2**31),
)
def test_the_sloped_fit_stops_at_its_scan_lines_least_squares_edge(edge, slope, sigma, noise, seed):
    # the fit stops a scan line once its step is tiny (FACE_SLOPE_CONVERGED_PX): where it stops is the
    # least squares edge of that line, found here by a bounded scalar search over the line's own misfit
    h = FACE_SLOPE_HALF_PX
    rng = np.random.default_rng(seed)
    clean = _profile(lambda d: 120.0 + slope * d, 20 + edge, sigma, 1)[20 - h : 20 + h + 1]
    rows = clean + rng.normal(0.0, noise, (6, clean.size))
    bounds = np.arange(-h, h + 2, dtype=np.float64) - 0.5
    got = face_slope_step_fit(rows, np.zeros(6), bounds, sigma, 1, n_iter=60)

    def misfit(e: float, row: np.ndarray) -> float:
        # (one step from e: its misfit is the line's at e, before the step)
        rss = np.empty(1)
        face_slope_step_fit(row[None], np.array([e]), bounds, sigma, 1, n_iter=1, misfit=rss)
        return float(rss[0])

    for row, e in zip(rows, got, strict=True):
        best = minimize_scalar(
            misfit, bounds=(e - 0.05, e + 0.05), args=(row,), method="bounded", options={"xatol": 1e-9}
        )
        assert abs(e - best.x) < 1e-6 and misfit(e, row) <= best.fun * (1 + 1e-12) + 1e-12


def test_the_sloped_fit_refuses_rows_and_bounds_that_do_not_agree():
    with pytest.raises(ValueError, match="M \\+ 1 pixel bounds"):
        face_slope_step_fit(np.zeros((3, 9)), np.zeros(3), np.arange(9.0), 1.0, 1)


def test_an_edge_without_a_point_to_read_keeps_the_area_estimate(pass_settings):
    plane = _grained_plane(30.35, 0.25)
    scan = np.arange(20, 180)
    window = ScanWindow(plane, "row", scan, np.full(scan.size, 30.0), 4, 3, 1.0, None, 0, 1)
    track = Track(window.scan, window.centre)
    from doorloc.vision.blurred_step import refine_face_slope_fit

    area = EDGE_MODELS["plain"].read(window, "reference", track, pass_settings()).samples
    none = replace(area, valid=np.zeros_like(area.valid))
    got = refine_face_slope_fit(plane, none, FACE_SLOPE_HALF_PX - 1, 1.3, 1)
    assert np.isnan(got.blur_px) and got.samples is none


def test_a_sloped_line_whose_windows_missed_its_edge_is_read_again_where_its_points_put_it(cell):
    """A 20 % grain of 5.2 mm period whose bright stripe runs along the reference arris (strong-grain bench,
    set seed 506, door 36; blur 0.64 px, JPEG): the first pass's area estimates, whose plateau lay in the
    stripe's trough, put the arris 3.5-5 px into the face, and the final windows, centred there, lost 637 of
    the line's 704 points (refused `edge_not_straight`). The sloped fit of the 67 it kept places the line;
    windows centred there read 704 of 704, and the door is answered within its sigma."""
    door = DoorSize(900, 70.51464376689417, 2100)
    pose = DoorPose(-4.032459631308056, -1.3288362418945994, -0.6767083366263043)
    fx = Effects(
        albedo_hinge=0.4708824187523411,
        albedo_side=0.5947098403291953,
        albedo_background=0.2961498554161692,
        gradient_u=-0.13826651440616852,
        gradient_v=0.16391938385014398,
        vignetting=0.23488171681634482,
        grain_contrast=0.2055160618980808,
        grain_period_mm=5.169175226753651,
        blur_sigma_px=0.6442922501711735,
        read_noise_dn=1.958956015579954,
        jpeg_quality=88,
    )
    img = render_door(cell, door, pose, effects=fx, seed=506036).image
    r = locate(img, cell, door)
    assert r.ok, f"refused: {r.error_code}: {r.error}"
    ref = next(ln for ln in r.lines if ln.name == "reference")
    assert ref.n_inliers > 0.9 * ref.n_points
    assert abs(r.x_mm - pose.x_mm) < 2.0 * r.uncertainty.x_mm
    assert abs(r.z_mm - pose.z_mm) < 2.0 * r.uncertainty.z_mm
    assert abs(r.yaw_deg - pose.yaw_deg) < 2.0 * r.uncertainty.yaw_deg


@pytest.mark.parametrize("seed", [1581, 9358])
def test_a_sharp_noisy_edge_is_not_read_by_the_step_fit_with_the_blur_noise_made(cell, seed):
    """A sharp (0.24 px), faint door (a step of 36 grey levels), 0.06 deg from square, 2.7 grey levels of
    noise with shot noise. Its first pass's transitions, widened by the noise, read 0.5-0.7 px of optical
    blur, over the step fit's least; the step fits (flat and sloped) with that blur then read each point at
    a bias that follows the pixel's phase, the phase drifts along the nearly square lines, and the yaw was
    0.010 deg off at 3.7 and 4.0 sigma with these two noise draws. Its long lines sweep under a pixel of
    phase and the step's own blur is under 0.5 px, so the area estimator reads them, and the yaw is within
    twice its sigma."""
    door = DoorSize(900, 66.31841621013174, 2100)
    pose = DoorPose(-1.8811926482208285, -8.210508968187325, -0.06078829699030393)
    fx = Effects(
        albedo_hinge=0.2903945777642458,
        albedo_side=0.2857390093739019,
        albedo_background=0.14704968237325622,
        gradient_u=0.033947161220301725,
        vignetting=0.07905256558685908,
        blur_sigma_px=0.24138834265010112,
        full_well_e=20000.0,
        read_noise_dn=2.7271486821816655,
    )
    cfg = replace(cell.locate, calibration_sigma_px=0.0, optics_edge_sigma_px=0.0)
    r = locate(render_door(cell, door, pose, effects=fx, seed=seed).image, cell, door, config=cfg)
    assert r.ok and r.uncertainty is not None, r.error
    u = r.uncertainty
    assert abs(r.yaw_deg - pose.yaw_deg) <= 2.0 * u.yaw_deg, (r.yaw_deg - pose.yaw_deg, u)
    assert abs(r.x_mm - pose.x_mm) <= 2.0 * u.x_mm, (r.x_mm - pose.x_mm, u)
    assert abs(r.z_mm - pose.z_mm) <= 2.0 * u.z_mm, (r.z_mm - pose.z_mm, u)


def _line(slope: float, n: int = 150, first: int = 100, every: int = 5, offset: float = 40.3) -> EdgeSamples:
    scan = first + every * np.arange(n)
    z = np.zeros(n)
    return EdgeSamples("row", scan, offset + slope * scan, z, z, z, np.ones(n, bool), np.ones(n, bool))


@settings(max_examples=60, deadline=None)
@given(slope=st.floats(-0.05, 0.05), n=st.integers(3, 300), offset=st.floats(-500.0, 500.0))
def test_a_line_s_phase_sweep_is_its_slope_times_its_length(slope, n, offset):
    line = _line(slope, n=n, offset=offset)
    assert phase_sweep_px(line) == pytest.approx(abs(slope) * 5 * (n - 1), rel=1e-6, abs=1e-6)


def test_the_step_fits_keep_only_the_lines_that_sweep_many_phases():
    """Below the fit's least blur: a line sweeping 5 px keeps its fit, one sweeping 1 px loses it; the sloped
    fit (reference and far) stays only where both sweep far enough."""
    far_px, near_px = 5.0, 1.0
    assert near_px < STEP_FIT_PHASE_SWEEP_PX < far_px
    span = 5 * 149
    swept = {"bottom": _line(far_px / span), "reference": _line(-far_px / span), "far": _line(-far_px / span)}
    fits = {"bottom": 0.6, "reference": 0.6}
    assert phase_swept(fits, 0.6, swept) == (fits, 0.6)
    square = dict(swept, reference=_line(near_px / span))
    kept, sloped = phase_swept(fits, 0.6, square)
    assert kept == {"bottom": 0.6} and np.isnan(sloped)
    far_square = dict(swept, far=_line(near_px / span))
    kept, sloped = phase_swept(fits, 0.6, far_square)
    assert kept == fits and np.isnan(sloped)
