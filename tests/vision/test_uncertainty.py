"""The answer's uncertainty: texture bias, calibration covariance (saved, read back, propagated), refusal."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import erf

from doorloc.calib.calibrate import Candidate, projection_uncertainty
from doorloc.calib.io import CalibrationFile, CalibrationFileError, load_calibration, save_calibration
from doorloc.cell import DoorSize, load_cell
from doorloc.pose import DoorPose
from doorloc.sim.door import render_door
from doorloc.sim.effects import Effects
from doorloc.sim.photometric import jpeg_roundtrip
from doorloc.vision.blurred_step import refine_step_fit
from doorloc.vision.edges import subpixel_edges
from doorloc.vision.locate import locate
from doorloc.vision.metric import PlaneMap
from doorloc.vision.texture import texture_bias
from doorloc.vision.uncertainty import (
    CAMERA_RESPONSE,
    EDGE_MODEL_FLOOR_PX,
    JPEG_BLOCK_RATIO,
    JPEG_DRIFT_SWEEP_PX,
    JPEG_DRIFT_TILT,
    JPEG_EDGE_DOUBT_PX,
    JPEG_EDGE_GREY_DN,
    EdgeModelTerms,
    LineDoubt,
    LineLever,
    calibration_pose_sigma,
    jpeg_drift_tilt,
    jpeg_edge_doubt_px,
    jpeg_edge_grey_dn,
    jpeg_tilt_sigma,
    propagate,
)

NAMES = ("fx", "fy", "cx", "cy", "k1")


@pytest.fixture(scope="module")
def cell(thesis_cell_path):
    return load_cell(thesis_cell_path)


def _edge_image(grain: float, period_px: float = 14.0, phase: float = 0.3, seed: int = 0) -> np.ndarray:
    """A vertical step at u = 100.3 (dark background left), grain stripes along the edge on the door side."""
    rng = np.random.default_rng(seed)
    u = np.arange(200) + 0.5
    fine = np.linspace(0, 200, 200 * 16, endpoint=False) + 1 / 32
    door = fine >= 100.3
    level = np.where(door, 150.0 * (1 + grain * np.sin(2 * np.pi * (fine - 100.3) / period_px + phase)), 50.0)
    row = level.reshape(200, 16).mean(axis=1)
    img = np.tile(row, (300, 1)) + rng.normal(0, 1.0, (300, 200))
    assert u.size == img.shape[1]
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def _bias(img: np.ndarray) -> tuple[float, float]:
    scan = np.arange(20, 280)
    s = subpixel_edges(img, "row", scan, np.full(scan.size, 100.0), 3, 2, level_smooth=10)
    est = float(np.nanmean(s.along)) - 99.8  # pixel k spans k - 0.5 .. k + 0.5: the step at 100.3 - 0.5
    return est, texture_bias(img, s, s.valid, 3, 2).offset_sigma_px


def test_texture_bias_is_small_on_a_plain_step_and_covers_grain():
    err0, sig0 = _bias(_edge_image(0.0))
    assert abs(err0) < 0.02 and sig0 < 0.02
    # grain along the edge at random phases: the estimate moves, and the measured texture bias covers it
    z = []
    for k, phase in enumerate(np.linspace(0, 2 * np.pi, 12, endpoint=False)):
        err, sig = _bias(_edge_image(0.1, period_px=10 + k, phase=phase, seed=k))
        assert sig > 3 * sig0
        z.append(abs(err) / math.hypot(sig, EDGE_MODEL_FLOOR_PX))
    z = np.array(z)
    assert (
        max(abs(_bias(_edge_image(0.1, 12.0, p))[0]) for p in (0.0, 1.5, 3.0)) > 0.03
    )  # grain does bias the edge
    assert np.mean(z <= 2.0) >= 0.75 and np.max(z) <= 5.0, z


def _blurred_edge(grain: float, period_px: float, phase: float, blur: float, seed: int) -> np.ndarray:
    import cv2

    fine = np.linspace(0, 200, 200 * 16, endpoint=False) + 1 / 32
    level = np.where(
        fine >= 100.3, 150.0 * (1 + grain * np.sin(2 * np.pi * (fine - 100.3) / period_px + phase)), 50.0
    )
    row = (
        cv2.GaussianBlur(level[None, :].astype(np.float32), (0, 0), blur * 16)[0]
        .reshape(200, 16)
        .mean(axis=1)
    )
    img = np.tile(row, (300, 1)) + np.random.default_rng(seed).normal(0, 1.0, (300, 200))
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def test_step_fit_is_exact_on_a_plain_step_and_beats_the_area_estimate_on_grain():
    scan = np.arange(20, 280)
    errs_area, errs_fit = [], []
    for k, phase in enumerate(np.linspace(0, 2 * np.pi, 8, endpoint=False)):
        for grain in (0.0, 0.1):
            img = _blurred_edge(grain, 12.0 + k, phase, 1.2, k)
            s = subpixel_edges(img, "row", scan, np.full(scan.size, 100.0), 4, 1, level_smooth=10)
            f = refine_step_fit(img, s, 4, 1.2)
            ea, ef = float(np.nanmean(s.along)) - 99.8, float(np.nanmean(f.along)) - 99.8
            if grain == 0.0:
                assert abs(ea) < 0.02 and abs(ef) < 0.02  # within the blur term of the edge-model doubt
            else:
                errs_area.append(ea)
                errs_fit.append(ef)
    rms_a, rms_f = np.sqrt(np.mean(np.square(errs_area))), np.sqrt(np.mean(np.square(errs_fit)))
    assert rms_f < 0.6 * rms_a, (rms_a, rms_f)


def test_edge_model_terms_add_in_quadrature():
    t = EdgeModelTerms((LineDoubt("texture", "reference", 0.03), LineDoubt("arris", "reference", 0.04)))
    assert t.line_sigma_px("reference") == pytest.approx(
        math.sqrt(0.03**2 + 0.04**2 + EDGE_MODEL_FLOOR_PX**2)
    )
    assert t.line_sigma_px("bottom") == pytest.approx(EDGE_MODEL_FLOOR_PX)


_LEVERS = {
    "reference": LineLever(30.0, 2.0e6, 900.0),
    "bottom": LineLever(20.0, 5.0e5, 400.0),
    "far": LineLever(35.0, 1.5e6, 800.0),
}
_CAMERA = {"calibration": (0.004, 0.005, 0.002), "cell": (0.01, 0.01, 0.003)}


def _budget_of(doubts, other_mm=None):
    model = EdgeModelTerms(tuple(doubts), blur_px=0.9)
    offsets = {"reference": 0.002, "bottom": 0.003, "far": 0.004}
    return propagate(model, offsets, 2e-5, _LEVERS, 0.2, _CAMERA, other_mm)


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.sampled_from(["texture", "far_face", "jpeg", "arris", "response"]),
            st.sampled_from(["bottom", "reference", "far"]),
            st.floats(0.0, 0.3),
            st.floats(0.0, 1e-3),
        ),
        max_size=8,
        unique_by=lambda t: (t[0], t[1]),
    ),
    st.one_of(st.none(), st.floats(-4.0, 4.0)),
)
def test_the_budget_s_terms_make_up_the_uncertainty(doubts, other_mm):
    b = _budget_of(
        [LineDoubt(s, k, o, t, CAMERA_RESPONSE if s == "response" else None) for s, k, o, t in doubts],
        other_mm,
    )
    # each source's share, in quadrature, is the pose's and the thickness's sigma: nothing counted twice
    # or left out
    for field, total in (("x_mm", b.x_mm), ("z_mm", b.z_mm), ("yaw_deg", b.yaw_deg)):
        assert math.hypot(*(getattr(t, field) for t in b.terms)) == pytest.approx(total, rel=1e-9)
    t_terms = [t.thickness_mm for t in b.terms if t.thickness_mm is not None]
    assert math.hypot(*t_terms) == pytest.approx(b.thickness_reported_mm, rel=1e-9)
    assert {t.source for t in b.terms} >= {"fit", "floor", "blur", "calibration", "cell"}
    assert len({t.source for t in b.terms}) == len(b.terms)


def test_lines_voted_by_their_doubts_carry_the_inverse_variance_yaw():
    """Where the direction was voted by each line's doubt (LineLever.vote = 1 / tilt^2), the budget weighs
    the tilts by the same votes: the yaw's doubt from them is the inverse-variance combination, below the
    least of them; weighed by the points' spread, one line in much doubt would dominate it."""
    tilts = {"reference": 2e-4, "bottom": 1e-3, "far": 1e-4}  # px per px
    doubts = [LineDoubt("texture", k, 0.0, t) for k, t in tilts.items()]
    model = EdgeModelTerms(tuple(doubts), blur_px=0.9)
    offsets = {"reference": 0.002, "bottom": 0.003, "far": 0.004}
    voted = {k: replace(lv, vote=1.0 / tilts[k] ** 2) for k, lv in _LEVERS.items()}
    by_votes = propagate(model, offsets, 2e-5, voted, 0.2, _CAMERA)
    by_spread = propagate(model, offsets, 2e-5, _LEVERS, 0.2, _CAMERA)
    yaw = {t.source: t.yaw_deg for t in by_votes.terms}["texture"]
    assert yaw == pytest.approx(math.degrees(1.0 / math.sqrt(sum(t**-2 for t in tilts.values()))), rel=1e-12)
    assert yaw < math.degrees(min(tilts.values())) < {t.source: t.yaw_deg for t in by_spread.terms}["texture"]


def test_one_camera_exponent_moves_both_arrises_so_their_doubts_add_in_the_thickness():
    both = [LineDoubt("response", k, 0.1, group=CAMERA_RESPONSE) for k in ("reference", "far")]
    apart = [LineDoubt("response", k, 0.1) for k in ("reference", "far")]
    linked, independent = _budget_of(both), _budget_of(apart)
    share = {t.source: t for t in linked.terms}["response"]
    assert share.thickness_mm == pytest.approx(0.2 * 0.2)  # (0.1 + 0.1) px at 0.2 mm/px
    assert {t.source: t for t in independent.terms}["response"].thickness_mm == pytest.approx(
        math.hypot(0.1, 0.1) * 0.2
    )
    assert linked.thickness_mm > independent.thickness_mm
    # the pose is the same either way: x moves with the reference line only
    assert (linked.x_mm, linked.z_mm, linked.yaw_deg) == (
        independent.x_mm,
        independent.z_mm,
        independent.yaw_deg,
    )
    assert share.x_mm == pytest.approx(0.1 * 0.2) and share.z_mm == 0.0


def test_the_answer_reports_its_budget_by_source(cell):
    """diagnostics["uncertainty_budget"]: each source's 1-sigma share of the pose and the thickness, which
    in quadrature make the reported ones (so the dominant term can be read off)."""
    door = DoorSize(900, 50, 2100)
    fx = Effects(grain_contrast=0.03, blur_sigma_px=1.2, read_noise_dn=1.0, jpeg_quality=85)
    r = locate(render_door(cell, door, DoorPose(2.0, -3.0, 0.4), effects=fx, seed=3).image, cell, door)
    assert r.ok, r.error
    budget = r.diagnostics["uncertainty_budget"]
    assert all(set(t) == {"source", "x_mm", "z_mm", "yaw_deg", "thickness_mm"} for t in budget)
    sources = [t["source"] for t in budget]
    assert len(set(sources)) == len(sources)
    assert {"fit", "floor", "blur", "texture", "jpeg", "response", "calibration", "cell"} <= set(sources)
    for key in ("x_mm", "z_mm", "yaw_deg"):
        assert math.hypot(*(t[key] for t in budget)) == pytest.approx(getattr(r.uncertainty, key), abs=1e-6)
    thickness = [t["thickness_mm"] for t in budget if t["thickness_mm"] is not None]
    assert math.hypot(*thickness) == pytest.approx(r.diagnostics["thickness_check"]["sigma_mm"], abs=1e-5)


def test_a_tilt_moves_the_yaw_and_through_the_lever_the_corner():
    b = _budget_of([LineDoubt("jpeg", "bottom", 0.0, tilt=1e-4)])
    jpeg = {t.source: t for t in b.terms}["jpeg"]
    assert jpeg.yaw_deg > 0 and jpeg.thickness_mm == 0.0
    # the yaw's doubt times each line's lever
    assert jpeg.x_mm == pytest.approx(math.radians(jpeg.yaw_deg) * 30.0)
    assert jpeg.z_mm == pytest.approx(math.radians(jpeg.yaw_deg) * 20.0)


def _covariance(sig=(0.8, 0.8, 0.5, 0.5, 1e-3)) -> np.ndarray:
    return np.diag(np.square(sig))


@pytest.mark.parametrize("fmt", ["opencv", "ros"])
def test_calibration_covariance_round_trips(cell, tmp_path, fmt):
    cov = _covariance() + 0.1 * np.outer([1, 1, 0, 0, 0], [1, 1, 0, 0, 0])
    path = tmp_path / "cam.yaml"
    save_calibration(CalibrationFile(cell.camera, 0.2, [], "cam", {}, cov, NAMES), path, fmt)
    back = load_calibration(path)
    assert back.covariance_names == NAMES
    np.testing.assert_allclose(back.covariance, cov)


def test_a_malformed_covariance_is_refused_with_its_key(cell, tmp_path):
    path = tmp_path / "cam.yaml"
    save_calibration(CalibrationFile(cell.camera, 0.2, [], "cam", {}, _covariance(), NAMES), path, "ros")
    doc = yaml.safe_load(path.read_text())
    doc["intrinsics_covariance_names"] = ["fx", "fy"]
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(CalibrationFileError, match="intrinsics_covariance"):
        load_calibration(path)


def test_calibration_sigma_is_the_aligned_projection_sigma_on_the_plane(cell):
    """The corner's calibration sigma is what ``doorloc calibrate`` reports as the rotation-aligned projection
    sigma at that pixel, times the scale; the raw (unaligned) principal-point sigma is mostly a rotation
    that the cell check takes up."""
    pm = PlaneMap(cell.posed_camera, 0.0)
    corner_px = pm.to_image(np.array([[0.0, 0.0]]))[0]
    scale = pm.scale_mm_per_px(np.zeros(2))
    cand = Candidate("t", 0, 5, (0,), False)
    w, h = cell.camera.image_size
    gu, gv = np.meshgrid(np.linspace(0, w - 1, 9), np.linspace(0, h - 1, 7))
    pixels = np.concatenate([corner_px[None], corner_px[None] + 1.0, np.stack([gu.ravel(), gv.ravel()], 1)])
    for cov in (
        np.diag([0.0, 0.0, 0.5**2, 0.0, 0.0]),
        np.diag([2.0**2, 2.0**2, 0.0, 0.0, 0.0]),
        np.diag([0.0, 0.0, 0.0, 0.0, 1e-3**2]),
        _covariance(),
    ):
        sx, sz, syaw = calibration_pose_sigma(cell.posed_camera, 0.0, corner_px, 0.0, cov, NAMES, 0.05, scale)
        major = projection_uncertainty(cell.camera, cand, cov, pixels, aligned=True)[0]
        # x and z are the plane's axes, the major axis may lie between them (and fx != fy)
        assert 0.7 * major * scale <= max(sx, sz) <= 1.05 * major * scale
        assert syaw >= 0.0
    # the principal point alone: far less than its raw 0.5 px once the rotation is taken out
    sx, sz, _ = calibration_pose_sigma(
        cell.posed_camera, 0.0, corner_px, 0.0, np.diag([0, 0, 0.25, 0, 0]), NAMES, 0.05, scale
    )
    assert 0 < max(sx, sz) < 0.5 * 0.5 * scale
    # names in another order describe the same covariance
    perm = [2, 0, 4, 1, 3]
    cov = _covariance() + 0.05 * np.ones((5, 5))
    a = calibration_pose_sigma(cell.posed_camera, 0.0, corner_px, 0.5, cov, NAMES, 0.05, scale)
    b = calibration_pose_sigma(
        cell.posed_camera,
        0.0,
        corner_px,
        0.5,
        cov[np.ix_(perm, perm)],
        tuple(NAMES[i] for i in perm),
        0.05,
        scale,
    )
    np.testing.assert_allclose(a, b, rtol=1e-9)
    # no covariance: the documented floor
    sx0, sz0, _ = calibration_pose_sigma(cell.posed_camera, 0.0, corner_px, 0.0, None, (), 0.05, scale)
    assert sx0 == sz0 == pytest.approx(0.05 * scale)


def test_locate_carries_the_calibration_covariance_into_the_answer(cell, tmp_path):
    door = DoorSize(900, 50, 2100)
    img = render_door(cell, door, DoorPose(2.0, -3.0, 0.4)).image
    save_calibration(
        CalibrationFile(cell.camera, 0.2, [], "cam", {}, _covariance(), NAMES), tmp_path / "cam.yaml"
    )
    cell_path = tmp_path / "cell.yaml"
    doc = {
        "camera": {
            "calibration": "cam.yaml",
            "extrinsics": {
                "rvec": cell.extrinsics.rvec.tolist(),
                "tvec_mm": cell.extrinsics.tvec_mm.tolist(),
            },
        },
        "envelope": {"x_mm": 10, "z_mm": 10, "yaw_deg": 2},
    }
    cell_path.write_text(yaml.safe_dump(doc))
    with_cov = load_cell(cell_path)
    assert with_cov.calibration_covariance is not None and with_cov.calibration_covariance_names == NAMES
    r = locate(img, with_cov, door)
    # (the rendered camera exact: its calibration, its optics and its linear response; a sharp door's
    # unmeasured response would otherwise carry ~0.027 mm, locate.response_unmeasured_factor)
    exact = replace(
        cell.locate, calibration_sigma_px=0.0, optics_edge_sigma_px=0.0, response_unmeasured_factor=1.0
    )
    r0 = locate(img, cell, door, config=exact)
    assert r.ok and r0.ok and r.uncertainty is not None and r0.uncertainty is not None
    cal = r.diagnostics["uncertainty_terms"]["calibration"]
    assert max(cal[:2]) > 0.005 and r.uncertainty.x_mm >= cal[0] and r.uncertainty.z_mm >= cal[1]
    assert r0.diagnostics["uncertainty_terms"]["calibration"] == [0.0, 0.0, 0.0]
    assert r0.uncertainty.x_mm < 0.01
    # the same answer, only the claim differs
    assert r.x_mm == pytest.approx(r0.x_mm, abs=1e-9)


def test_uncertain_when_the_uncertainty_exceeds_the_cells_tolerance(cell):
    door = DoorSize(900, 50, 2100)
    eff = Effects(grain_contrast=0.08, grain_period_mm=3.0, blur_sigma_px=1.2, read_noise_dn=2.0)
    img = render_door(cell, door, DoorPose(1.0, 1.0, 0.2), effects=eff, seed=3).image
    ok = locate(img, cell, door)
    assert ok.ok and ok.uncertainty is not None
    tight = replace(cell.locate, max_uncertainty_mm=0.5 * min(ok.uncertainty.x_mm, ok.uncertainty.z_mm))
    r = locate(img, cell, door, config=tight)
    assert not r.ok and r.error_code == "uncertain"
    assert "1 sigma" in (r.error or "") and "mm" in (r.error or "")


@pytest.mark.parametrize("noise", [0.3, 3.0])
def test_jpeg_block_artifacts_are_told_from_noise(cell, noise):
    """(A flat, noise-free face comes through JPEG nearly unchanged: no artifacts to see, nor a bias.)"""
    door = DoorSize(900, 50, 2100)
    pose = DoorPose(1.0, -2.0, 0.3)
    eff = Effects(read_noise_dn=noise, blur_sigma_px=1.0, vignetting=0.2, gradient_u=0.1)
    plain = render_door(cell, door, pose, effects=eff, seed=5).image
    jpeg = render_door(cell, door, pose, effects=replace(eff, jpeg_quality=88), seed=5).image
    r_plain = locate(plain, cell, door)
    r_jpeg = locate(jpeg, cell, door)
    assert r_plain.diagnostics["jpeg_block_ratio"] < JPEG_BLOCK_RATIO < r_jpeg.diagnostics["jpeg_block_ratio"]
    assert r_jpeg.uncertainty is not None and r_plain.uncertainty is not None
    assert r_jpeg.uncertainty.z_mm > r_plain.uncertainty.z_mm


@pytest.mark.parametrize(
    "pose, thickness, eff, seed",
    [
        # bench_surfaces.py --seed 9200: grain_018 (grain through JPEG 88); the far arris took a tilt from
        # it that the joint fit gave the yaw, 6.4 sigma off while its tilt was left out of the yaw's doubt
        # (thin_016, the other such door, is outvoted now: the test below)
        (
            DoorPose(7.6452, 8.5722, -0.6255),
            31.675,
            Effects(
                albedo_hinge=0.4547, albedo_side=0.3312, albedo_background=0.2865, gradient_u=0.158,
                gradient_v=-0.0176, vignetting=0.3681, grain_contrast=0.0587, grain_period_mm=7.5268,
                blur_sigma_px=0.7299, read_noise_dn=0.3345, jpeg_quality=88,
            ),
            9200018,
        ),
    ],
)  # fmt: skip
def test_the_far_arris_tilt_counts_in_the_yaw_where_it_votes_on_the_direction(
    cell, pose, thickness, eff, seed
):
    door = DoorSize(900, thickness, 2100)
    img = render_door(cell, door, pose, effects=eff, seed=seed).image
    r = locate(img, cell, door, config=replace(cell.locate, calibration_sigma_px=0.0))
    assert r.ok and r.uncertainty is not None and not r.diagnostics["far_face_visible"]
    err = abs(r.yaw_deg - pose.yaw_deg)
    assert err > 0.005  # the case: a tilt far beyond the fit's own noise
    assert err <= 3.5 * r.uncertainty.yaw_deg, (err, r.uncertainty.yaw_deg)


def test_a_far_arris_tilted_by_grain_is_outvoted_by_the_lines_in_less_doubt(cell):
    """bench_surfaces.py --seed 9200, thin_016: grain along a thin door, light from the side. The far arris
    took a tilt from the grain that the joint fit, weighing the lines by their points' spread alone, gave the
    yaw: 0.0079 deg off (6.3 sigma before its tilt counted in the yaw's doubt, 1.3 after). Voted by each
    line's whole doubt, the direction rests on the lines in less doubt: within 0.005 deg, and within 2
    sigma."""
    pose = DoorPose(8.5152, 6.8421, -1.5662)
    door = DoorSize(900, 30.947, 2100)
    eff = Effects(
        albedo_hinge=0.4169, albedo_side=0.2323, albedo_background=0.2293, light_ambient=0.9816,
        light_directional=0.3999, light_azimuth_deg=47.422, light_elevation_deg=2.136,
        gradient_u=-0.0907, gradient_v=0.2224, vignetting=0.2249, grain_contrast=0.0958,
        grain_period_mm=7.1154, blur_sigma_px=0.6597, full_well_e=20000.0, read_noise_dn=0.5851,
        jpeg_quality=95,
    )  # fmt: skip
    img = render_door(cell, door, pose, effects=eff, seed=9203016).image
    r = locate(img, cell, door, config=replace(cell.locate, calibration_sigma_px=0.0))
    assert r.ok and r.uncertainty is not None and not r.diagnostics["far_face_visible"]
    err = abs(r.yaw_deg - pose.yaw_deg)
    assert err < 0.005, err
    assert err <= 2.0 * r.uncertainty.yaw_deg, (err, r.uncertainty.yaw_deg)


@settings(max_examples=60, deadline=None)
@given(
    slope=st.floats(1e-4, 2.0),
    first=st.integers(0, 800),
    n=st.integers(3, 900),
    every=st.integers(1, 5),
    seed=st.integers(0, 1000),
)
def test_the_jpeg_tilt_is_the_rms_least_squares_slope_of_a_block_and_pixel_periodic_error(
    slope, first, n, every, seed
):
    """jpeg_tilt_sigma against the least-squares slopes of sinusoidal edge errors (each RMS
    JPEG_EDGE_DOUBT_PX; periods 8 / slope and 1 / slope, independent) on the line's scan lines (some of them
    dropped, as outliers are), over their phases."""
    rng = np.random.default_rng(seed)
    scan = np.arange(first, first + n * every, every)
    scan = scan[rng.random(scan.size) > 0.2] if scan.size > 10 else scan
    d = scan - scan.mean()
    phases = np.linspace(0.0, 2 * np.pi, 64, endpoint=False)
    variance = 0.0
    for period in (8.0, 1.0):
        k = 2 * np.pi * slope / period
        err = np.sqrt(2.0) * JPEG_EDGE_DOUBT_PX * np.sin(k * scan[None, :] + phases[:, None])
        slopes = (err - err.mean(axis=1, keepdims=True)) @ d / (d @ d)
        variance += float(np.mean(slopes**2))
    assert jpeg_tilt_sigma(slope, scan) == pytest.approx(math.sqrt(variance), rel=1e-6, abs=1e-15)


def _jpeg_edge_errors(
    step_dn: float, quality: int, slope: float, blur_px: float = 0.4, start_px: float = 20.3
) -> np.ndarray:
    """A straight edge (2048 scan lines, ``slope`` px across per px along, ``start_px`` across on the
    first) of ``step_dn`` grey levels over a Gaussian blur and the pixels' area, read by the area estimator
    as a JPEG of ``quality`` stores it, less the same read of the unquantised image: the quantisation's
    error per scan line, px."""
    rows = np.arange(2048.0)
    across = start_px + slope * (rows + 0.5)

    def area(u):  # the integral of the normal CDF
        return u * 0.5 * (1 + erf(u / math.sqrt(2))) + np.exp(-u * u / 2) / math.sqrt(2 * math.pi)

    c = np.arange(64.0)[None, :] - across[:, None]
    grey = 40.0 + step_dn * (area((c + 1) / blur_px) - area(c / blur_px)) * blur_px
    u8 = np.rint(grey).astype(np.uint8)
    centre = across - 0.5

    def read(img):
        return subpixel_edges(img, "row", rows.astype(int), centre, 4, 4).along

    return read(jpeg_roundtrip(u8, quality)) - read(u8)


@pytest.mark.parametrize("quality", [60, 75, 80, 88, 95])
@pytest.mark.parametrize("step_dn", [10.0, 20.0, 80.0, 160.0])
def test_the_jpeg_offset_doubt_covers_the_quantisations_error_at_every_contrast(step_dn, quality):
    """Over an edge's phases in its block (a line at a slope that sweeps 32 px across), the RMS of the
    quantisation's error is within jpeg_edge_doubt_px of the edge's step at the file's quality, and within
    quality 80's (what an image whose file was not seen is given) from quality 80 on; on a dark door on a
    dark background (step 10-20) it is beyond the old fixed doubt, ``JPEG_EDGE_DOUBT_PX``: the doubt grows
    as the step falls."""
    err = _jpeg_edge_errors(step_dn, quality, slope=32.0 / 2048)
    # a line's fit averages the rows of a block, whose errors differ with the rows' place in the 2-D block
    rms = float(np.sqrt(np.nanmean(np.nanmean(err.reshape(-1, 8), axis=1) ** 2)))
    known = jpeg_edge_doubt_px(step_dn, jpeg_edge_grey_dn(quality))
    assert rms <= known, (rms, known)
    if quality >= 80:
        assert rms <= jpeg_edge_doubt_px(step_dn), (rms, jpeg_edge_doubt_px(step_dn))
    if quality == 80 and step_dn <= 20.0:
        assert rms > JPEG_EDGE_DOUBT_PX, rms
    assert jpeg_edge_doubt_px(step_dn) == pytest.approx(max(JPEG_EDGE_DOUBT_PX, JPEG_EDGE_GREY_DN / step_dn))


@given(st.integers(1, 99))
def test_the_jpeg_grey_levels_fall_as_the_quality_rises(quality):
    """A finer quantization never moves an edge more; an unknown quality is taken as 80."""
    assert jpeg_edge_grey_dn(quality) >= jpeg_edge_grey_dn(quality + 1) > 0
    assert jpeg_edge_grey_dn(None) == jpeg_edge_grey_dn(0) == jpeg_edge_grey_dn(80) == JPEG_EDGE_GREY_DN


#: bench_jpeg_doors.py's door 5149: plain, 0.027 deg from square, a step of 37 grey levels, JPEG 80, no noise
FAINT_JPEG_DOOR = (
    DoorSize(900, 39.63983919248882, 2100),
    DoorPose(-0.1908736530905557, -8.936478802934412, 0.027467941178610122),
    Effects(
        albedo_hinge=0.3185104470894824,
        albedo_side=0.1887759177482996,
        albedo_background=0.17175643281648692,
        gradient_u=0.11326192224306836,
        vignetting=0.008001761429532284,
        blur_sigma_px=0.569895416022191,
        jpeg_quality=80,
    ),
)


def test_a_noise_free_jpeg_door_is_doubted_by_its_files_quality(cell):
    """Without noise a JPEG's flat blocks stay flat and the block detector sees nothing, while its edges
    carry the quantisation: this plain door (quality 80, 0.027 deg from square) is answered over 4 sigma
    off in yaw from the array alone, and within 3 sigma where its file's quality is told."""
    door, pose, eff = FAINT_JPEG_DOOR
    img = render_door(cell, door, pose, effects=eff, seed=5149).image
    cfg = replace(cell.locate, calibration_sigma_px=0.0, optics_edge_sigma_px=0.0)
    blind = locate(img, cell, door, config=cfg)
    told = locate(img, cell, door, config=cfg, jpeg_quality=80)
    assert blind.ok and told.ok and blind.uncertainty is not None and told.uncertainty is not None
    assert blind.diagnostics["jpeg_block_ratio"] < JPEG_BLOCK_RATIO
    assert blind.diagnostics["jpeg_quality"] is None and told.diagnostics["jpeg_quality"] == 80
    assert abs(blind.yaw_deg - pose.yaw_deg) > 4.0 * blind.uncertainty.yaw_deg
    assert abs(told.yaw_deg - pose.yaw_deg) <= 3.0 * told.uncertainty.yaw_deg, (
        told.yaw_deg - pose.yaw_deg,
        told.uncertainty,
    )
    assert "jpeg" in {b["source"] for b in told.diagnostics["uncertainty_budget"]}


def test_the_jpeg_tilt_covers_a_nearly_aligned_edges_drift_through_its_pixels_phase():
    """A 512-px edge at 0.06 deg to the blocks (0.001 px across per px along) keeps one block phase and
    drifts through half a pixel's: over edges placed at 24 phases, the least-squares tilt of the
    quantisation's error is within 2 jpeg_tilt_sigma for 95 % of them, where the block's period alone
    covers about half of them."""
    slope, step, n = 1e-3, 15.0, 512
    d = np.arange(n) - (n - 1) / 2.0
    tilts = []
    for start in np.linspace(20.0, 28.0, 24, endpoint=False):
        err = _jpeg_edge_errors(step, 80, slope=slope, start_px=start)[:n]
        ok = np.isfinite(err)
        tilts.append(abs(float(np.polyfit(d[ok], err[ok], 1)[0])))
    doubt = jpeg_edge_doubt_px(step)
    claimed = jpeg_tilt_sigma(slope, d, doubt)
    k = 2 * math.pi * slope / 8.0
    block_only = doubt * math.hypot(float(d @ np.sin(k * d)), float(d @ np.cos(k * d))) / float(d @ d)
    assert np.mean(np.array(tilts) <= 2.0 * claimed) >= 0.95, (max(tilts), claimed)
    assert np.mean(np.array(tilts) <= 2.0 * block_only) < 0.75, (max(tilts), block_only)


def test_residuals_alike_within_jpeg_blocks_give_the_tilt_their_block_means_allow():
    """A line's residuals that share one error per 8-px block (JPEG's) tilt it by what the blocks' means
    allow, which a fit taking them as independent puts about sqrt(8) times too low: over 200 lines the
    tilt claimed with the fit's own standard error is the RMS of their least-squares slopes within 20 %;
    on independent residuals it claims little beyond the fit's."""
    from doorloc.vision.doubts import _block_correlated_tilt

    scan = np.arange(96.0, 896.0)  # (the blocks lie on the image's grid of 8)
    d = scan - scan.mean()
    slopes, claimed, alone = [], [], []
    for seed in range(200):
        rng = np.random.default_rng(seed)
        res = np.repeat(rng.normal(0.0, 0.05, scan.size // 8), 8) + rng.normal(0.0, 0.01, scan.size)
        slopes.append(float(d @ res / (d @ d)))
        claimed.append(_block_correlated_tilt(scan, res))
        alone.append(_block_correlated_tilt(scan, rng.normal(0.0, 0.05, scan.size)))
    rms = math.sqrt(float(np.mean(np.square(slopes))))
    fit_se = 0.05 / math.sqrt(float(d @ d))  # (the residuals' scatter is about 0.05 px either way)
    assert rms == pytest.approx(math.sqrt(float(np.mean(np.square(claimed))) + fit_se**2), rel=0.2)
    assert float(np.median(alone)) < 0.5 * fit_se


def test_a_jpeg_door_nearly_aligned_with_the_block_grid_claims_its_yaw(cell):
    """An edge at a small angle to JPEG's 8-px block grid drifts through the blocks' phases along it, and
    the quantisation's error drifts with it: a tilt. With only an offset doubt this plain door at yaw 0.16
    deg (quality 88) was answered 6.2 sigma off in yaw."""
    door = DoorSize(900, 86.43365785298869, 2100)
    pose = DoorPose(-8.495777763711912, 9.257291568864556, 0.16004482038587664)
    eff = Effects(
        albedo_hinge=0.4281605076004363,
        albedo_background=0.205844561526072,
        gradient_u=0.0282258391809993,
        vignetting=0.20240681863043322,
        blur_sigma_px=0.6406707006198075,
        read_noise_dn=0.37358735870761706,
        jpeg_quality=88,
    )
    r = locate(
        render_door(cell, door, pose, effects=eff, seed=20).image,
        cell,
        door,
        config=replace(cell.locate, calibration_sigma_px=0.0),
    )
    assert r.ok and r.uncertainty is not None
    assert r.diagnostics["jpeg_block_ratio"] > JPEG_BLOCK_RATIO
    assert abs(r.yaw_deg - pose.yaw_deg) <= 3.0 * r.uncertainty.yaw_deg, (
        r.yaw_deg - pose.yaw_deg,
        r.uncertainty,
    )


def test_a_sharp_dark_jpeg_door_nearly_square_to_the_blocks_claims_its_yaw(cell):
    """A plain door 0.056 deg from square, sharp (blur 0.42 px), its side nearly as dark as the
    background, as a quality-80 JPEG: each edge keeps one phase in its blocks and the quantisation moves
    it by grey levels over a small step. With a fixed 0.03 px doubt and the block's period alone it was
    answered 6.0 sigma off in yaw and 4.1 in x."""
    door = DoorSize(900, 85.06582594967459, 2100)
    pose = DoorPose(-9.107973555089687, 8.756321357930826, -0.05636713971353435)
    eff = Effects(
        albedo_hinge=0.27967715008322624,
        albedo_side=0.10364020059454843,
        albedo_background=0.08917411754465089,
        light_ambient=0.7474163196290106,
        light_directional=0.10736471818533144,
        light_azimuth_deg=-53.75105212984765,
        light_elevation_deg=44.278836917617184,
        gradient_u=0.11751980009649865,
        gradient_v=-0.026925518350678024,
        vignetting=0.2701076149887968,
        grain_contrast=0.0012856290820543181,
        grain_period_mm=4.57700755859291,
        blur_sigma_px=0.4177983899133926,
        full_well_e=20000.0,
        read_noise_dn=1.0519193077229199,
        jpeg_quality=80,
    )
    r = locate(
        render_door(cell, door, pose, effects=eff, seed=61002009).image,
        cell,
        door,
        config=replace(cell.locate, calibration_sigma_px=0.0, optics_edge_sigma_px=0.0),
    )
    assert r.ok and r.uncertainty is not None
    assert r.diagnostics["jpeg_block_ratio"] > JPEG_BLOCK_RATIO
    for err, sigma in (
        (r.x_mm - pose.x_mm, r.uncertainty.x_mm),
        (r.z_mm - pose.z_mm, r.uncertainty.z_mm),
        (r.yaw_deg - pose.yaw_deg, r.uncertainty.yaw_deg),
    ):
        assert abs(err) <= 3.0 * sigma, (err, sigma)


@pytest.mark.parametrize("seed", [5149, 5926])
def test_a_faint_jpeg_door_at_one_pixel_phase_claims_the_drift_of_its_error(cell, seed):
    """A plain door 0.027 deg from square (its long arrises sweep 0.4 px of phase), a step of 37 grey levels,
    JPEG 80. The quantisation's error drifts along each arris with the grey levels beside it (0.14 px to one
    side over a third of the far arris, 0.2 px to the other over its last), a tilt the block and pixel
    periods barely give a line at one phase: its yaw was 0.027 deg off at 3.9 and 8.1 sigma with these two
    noise draws."""
    door, pose, eff = FAINT_JPEG_DOOR
    eff = replace(eff, full_well_e=20000.0, read_noise_dn=1.1034195682475574)
    r = locate(
        render_door(cell, door, pose, effects=eff, seed=seed).image,
        cell,
        door,
        config=replace(cell.locate, calibration_sigma_px=0.0, optics_edge_sigma_px=0.0),
    )
    assert r.ok and r.uncertainty is not None
    assert r.diagnostics["jpeg_block_ratio"] > JPEG_BLOCK_RATIO
    assert abs(r.yaw_deg - pose.yaw_deg) <= 3.0 * r.uncertainty.yaw_deg, (
        r.yaw_deg - pose.yaw_deg,
        r.uncertainty,
    )
    assert abs(r.x_mm - pose.x_mm) <= 3.0 * r.uncertainty.x_mm


@settings(max_examples=60, deadline=None)
@given(length=st.floats(50.0, 2000.0), sweep=st.floats(0.0, 4.0), doubt=st.floats(0.01, 0.5))
def test_the_jpeg_drift_is_whole_at_one_phase_and_gone_past_its_sweep(length, sweep, doubt):
    """Full (JPEG_DRIFT_TILT offset doubts over the line's length) while the phase sweeps under 1 px,
    nothing from JPEG_DRIFT_SWEEP_PX on, linear between; the slope's sign does not matter."""
    scan = np.linspace(0.0, length, 200)
    full = JPEG_DRIFT_TILT * doubt / length
    share = min(1.0, max(0.0, JPEG_DRIFT_SWEEP_PX - sweep))
    for slope in (sweep / length, -sweep / length):
        assert jpeg_drift_tilt(slope, scan, doubt) == pytest.approx(full * share, rel=1e-9, abs=1e-15)
    assert jpeg_drift_tilt(float("nan"), scan, doubt) == 0.0
