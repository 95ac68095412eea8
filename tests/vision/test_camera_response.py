"""A camera whose photometric model (its calibration's, from ``doorloc check-model --boards``) says what a
power law cannot: a response with a shoulder, a pedestal or curvature, which locate maps the levels through,
and a point spread that moves every edge against the corners' frame, which locate takes off. The cell
carries the model, and the door is placed as a power-law camera's would be."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from doorloc.calib.camera import CameraModel
from doorloc.calib.io import CalibrationFile, save_calibration
from doorloc.cell import DoorSize, load_cell, save_cell
from doorloc.photometric.model import PhotometricModel
from doorloc.pose import DoorPose
from doorloc.sim.door import render_door
from doorloc.sim.effects import Effects
from doorloc.sim.photometric import CameraRendering, apply_camera
from doorloc.vision.locate import locate
from doorloc.vision.luminance import camera_levels, luminance_plane

CELL = load_cell(Path(__file__).parents[2] / "fixtures" / "cell_thesis.yaml")
#: a shoulder from 55 % of full scale, as the public OpenCV photographs' camera has one from about 62 %
SHOULDER = PhotometricModel(shoulder=0.55)


@settings(max_examples=40, deadline=None)
@given(
    gamma=st.floats(0.8, 2.6),
    black=st.floats(0.0, 0.1),
    shoulder=st.floats(0.4, 1.0),
    curvature=st.floats(-0.2, 0.2),
    stated=st.floats(1.0, 2.4),
    eight_bit=st.booleans(),
)
def test_the_mapped_levels_carry_the_cameras_light(gamma, black, shoulder, curvature, stated, eight_bit):
    """Through the table, a level read with the power law the cell states gives the light the camera's own
    response gives it (up to a constant: its full scale), to the table's 16-bit rounding; the levels keep
    their order and full scale stays full scale (a clipped pixel stays clipped)."""
    model = PhotometricModel(gamma=gamma, black_level=black, shoulder=shoulder, curvature=curvature)
    top = 255 if eight_bit else 65535
    table = model.power_law_levels(stated, top)
    assert table.dtype == np.uint16 and table.size == top + 1 and table[-1] == 65535
    assert np.all(np.diff(table.astype(np.int64)) >= 0)
    g = np.arange(top + 1) / top
    light = model.light_from_grey(g) / model.light_from_grey(np.array([1.0]))[0]
    read = (table / 65535.0) ** stated
    # 16-bit rounding, carried through the power law: half a code times its slope, the slope's most over
    # that half code (the power law of 1-2.4 is convex: at the code's upper end; at the rounded code itself
    # it fell half a percent short on a level rounded by nearly half a code, gamma 2.5 stated 1.1)
    tol = stated * np.maximum((table + 0.5) / 65535.0, 1e-3) ** (stated - 1.0) * (0.5 / 65535.0) + 1e-12
    assert np.all(np.abs(read - np.clip(light, 0.0, 1.0)) <= tol + 1e-9)


def test_a_camera_the_power_law_describes_is_not_remapped():
    """Without a response beyond the power law (the cell's ``camera_photometry`` None) the image's levels are
    the camera's, untouched (no copy)."""
    img = np.arange(64, dtype=np.uint8).reshape(8, 8)
    lum = luminance_plane(img)
    assert camera_levels(lum, None, 2.2) is lum
    assert not PhotometricModel(gamma=2.2).beyond_power_law
    assert SHOULDER.beyond_power_law


@pytest.mark.parametrize("dtype,top", [(np.uint8, 255), (np.uint16, 65535)])
def test_a_camera_that_clips_below_full_scale_says_at_which_level_of_the_plane(dtype, top):
    """A model's ``clip_level`` is the level the plane holds clipped light at (0-255 scale): the camera's
    own where its levels are kept, their image through the table where they are mapped; none without a
    clip."""
    img = np.linspace(0, top, 64 * 48).astype(dtype).reshape(48, 64)
    lum = luminance_plane(img)
    assert camera_levels(lum, PhotometricModel(gamma=2.2), 2.2).clip_grey is None
    kept = camera_levels(lum, PhotometricModel(gamma=2.2, clip_level=240 / 255), 2.2)
    assert kept.plane is lum.plane and kept.clip_grey == pytest.approx(240.0, abs=0.01)
    clipping_shoulder = dataclasses.replace(SHOULDER, clip_level=240 / 255)
    mapped = camera_levels(lum, clipping_shoulder, 1.5)
    code = round(240 / 255 * top)
    assert mapped.clip_grey == pytest.approx(float(SHOULDER.power_law_levels(1.5, top)[code]) * 255 / 65535)


@pytest.mark.parametrize("dtype,top", [(np.uint8, 255), (np.uint16, 65535)])
def test_an_image_is_mapped_through_the_table_at_either_depth(dtype, top):
    """8- and 16-bit images go through the same table (its 8-bit path is OpenCV's LUT) into 16-bit levels."""
    img = np.linspace(0, top, 64 * 48).astype(dtype).reshape(48, 64)
    out = camera_levels(luminance_plane(img), SHOULDER, 1.5)
    assert out.plane.dtype == np.uint16 and out.scale_to_8bit == pytest.approx(255 / 65535)
    np.testing.assert_array_equal(out.plane, SHOULDER.power_law_levels(1.5, top)[img])


def test_a_cell_takes_the_response_its_calibration_carries_and_keeps_it_when_saved(tmp_path):
    """`doorloc check-model --boards` writes the camera's photometric model into its calibration file: a cell
    on that file carries it where it says what locate uses (a response beyond a power law, a clip below full
    scale, edges moved by the point spread), and a cell saved with its camera inline keeps it (``camera.photometric_model``); a
    model that is a power law alone (the print's spread is the board's, not the camera's) leaves the cell's
    ``response_gamma`` the whole response."""
    ext = "  extrinsics: {rvec: [1.5707963268, 0, 0], tvec_mm: [-30, 40, 350]}\n"
    for name, model, carried in (
        ("shoulder", PhotometricModel(gamma=1.1, shoulder=0.6, psf_tail=0.05), True),
        ("shift", PhotometricModel(gamma=2.2, edge_shift_v_px=-0.19), True),
        ("clip", PhotometricModel(gamma=2.2, clip_level=0.94), True),
        ("power", PhotometricModel(gamma=2.2, print_spread_mm=0.1), False),
    ):
        save_calibration(
            CalibrationFile(CELL.camera, photometric_model=model.to_dict()), tmp_path / f"{name}.yaml"
        )
        (tmp_path / f"cell_{name}.yaml").write_text(f"camera:\n  calibration: {name}.yaml\n" + ext)
        cell = load_cell(tmp_path / f"cell_{name}.yaml")
        if not carried:
            assert cell.camera_photometry is None
            continue
        assert cell.camera_photometry == model
        save_cell(cell, tmp_path / "inline.yaml")
        back = load_cell(tmp_path / "inline.yaml")
        assert back.camera_photometry is not None
        assert back.camera_photometry.locate_parameters() == model.locate_parameters()
    (tmp_path / "bad.yaml").write_text(
        "camera:\n  calibration: shoulder.yaml\n  photometric_model: {knee: 0.5}\n" + ext
    )
    with pytest.raises(ValueError, match="knee"):
        load_cell(tmp_path / "bad.yaml")


@pytest.mark.parametrize("seed,pose", [(1, (-6.0, 5.5, -1.2)), (2, (8.0, 2.0, 1.5))])
def test_a_door_through_a_shoulder_camera_is_placed_through_its_response(seed, pose):
    """A sharp door whose face the camera stores at 85 % of full scale, on its shoulder. With the cell carrying
    the response the door is placed within 2 of its sigmas and to a hundredth, the image's own response check
    finds the mapped levels linear (the cell's power law), and the answer says which response it was read with.
    Read with the power law alone, the check sees the shoulder as a power law of about 1.4 and uses it: a
    finite shoulder between a door's two levels is one a power law can stand in for (before the shoulder
    reached its white level at a finite light, the form it had left such a door 0.1 mm off at 10 sigma)."""
    door, truth = DoorSize(900, 50.0, 2100), DoorPose(*pose)
    radiance = render_door(
        CELL, door, truth, effects=Effects(albedo_hinge=0.5, albedo_background=0.12), seed=seed
    ).radiance
    exposure = 0.92 / float(np.percentile(radiance, 99.5))
    img = apply_camera(
        radiance, SHOULDER, CameraRendering(blur_px=1.2, exposure=exposure, read_noise=1.0), seed
    )
    told = locate(img, dataclasses.replace(CELL, camera_photometry=SHOULDER), door)
    assert told.ok, told.error
    u = told.uncertainty
    e = (told.x_mm - truth.x_mm, told.z_mm - truth.z_mm, told.yaw_deg - truth.yaw_deg)
    assert abs(e[0]) <= min(2 * u.x_mm, 0.01) and abs(e[1]) <= min(2 * u.z_mm, 0.01)
    assert abs(e[2]) <= 2 * u.yaw_deg
    assert told.model.camera_photometry == SHOULDER.locate_parameters()
    seen = told.diagnostics["camera_response"]
    assert seen["used"] == "cell" and abs(seen["fitted"] - 1.0) <= 3 * seen["sigma"], seen
    # the same photograph read with the power law alone: its check sees a response the cell does not state
    plain = locate(img, CELL, door)
    assert plain.model.camera_photometry is None
    seen = plain.diagnostics["camera_response"]
    assert seen["used"] == "image" and seen["fitted"] - 1.0 > 10 * seen["sigma"], seen
    assert plain.ok and abs(plain.x_mm - truth.x_mm) <= 2 * plain.uncertainty.x_mm


def test_edges_moved_by_the_point_spread_are_taken_back():
    """A point spread that is not point-symmetric moves every edge by a vector against the corners' frame the
    calibration was made in (Bouguet's photographs read v -0.19 +- 0.02 px): rendered so (the principal point
    moved by the shift, which moves every edge's image by it), the door read without the shift is off by the
    shift's worth in z; with the cell carrying it, within 2 of its sigmas and 0.005 mm."""
    shift = PhotometricModel(edge_shift_u_px=0.05, edge_shift_v_px=-0.25)
    cam = CELL.camera
    K = cam.camera_matrix.copy()
    K[0, 2] += 0.05
    K[1, 2] -= 0.25
    seen = dataclasses.replace(CELL, camera=CameraModel(K, cam.dist_coeffs, cam.image_size))
    door, truth = DoorSize(900, 50.0, 2100), DoorPose(4.0, -3.0, 0.8)
    img = render_door(seen, door, truth, effects=Effects(blur_sigma_px=1.0, read_noise_dn=1.0), seed=3).image
    told = locate(img, dataclasses.replace(CELL, camera_photometry=shift), door)
    assert told.ok, told.error
    u = told.uncertainty
    assert abs(told.x_mm - truth.x_mm) <= min(2 * u.x_mm, 0.005)
    assert abs(told.z_mm - truth.z_mm) <= min(2 * u.z_mm, 0.005)
    assert abs(told.yaw_deg - truth.yaw_deg) <= 2 * u.yaw_deg
    assert told.model.camera_photometry == shift.locate_parameters()
    plain = locate(img, CELL, door)
    assert plain.ok, plain.error
    assert abs(plain.z_mm - told.z_mm) > 0.03  # 0.25 px at about 0.21 mm a pixel


def test_what_the_cameras_optics_may_move_is_in_every_answers_doubt():
    """The model's measured error on the camera's real edges (``residual_edge_px``: `check-model --boards`'s
    held-out RMS of the photographs' median edge offset) is a term of its own in the uncertainty budget
    (``camera``): that many pixels on every edge, at the door's scale. A camera nobody measured carries the
    cell's ``locate.optics_edge_sigma_px`` (0.13 px by default) instead (``optics``; so does a camera model without a
    residual, one that states only a clip): measuring it with a residual under
    that narrows the answer's sigma; a camera known exactly (0) carries neither. The answer is the same."""
    door, truth = DoorSize(900, 50.0, 2100), DoorPose(2.0, 1.0, 0.5)
    img = render_door(CELL, door, truth, effects=Effects(blur_sigma_px=1.0, read_noise_dn=1.0), seed=4).image
    measured = locate(
        img, dataclasses.replace(CELL, camera_photometry=PhotometricModel(residual_edge_px=0.05)), door
    )
    plain = locate(img, CELL, door)
    exact = locate(img, CELL, door, config=dataclasses.replace(CELL.locate, optics_edge_sigma_px=0.0))
    # a model that measured no edges (it states a clip above this door's light) leaves the optics unmeasured
    clip = locate(img, dataclasses.replace(CELL, camera_photometry=PhotometricModel(clip_level=0.99)), door)
    assert measured.ok and plain.ok and exact.ok and clip.ok
    unmeasured = CELL.locate.optics_edge_sigma_px
    assert unmeasured > 0.05
    for r, source, px in (
        (measured, "camera", 0.05),
        (plain, "optics", unmeasured),
        (clip, "optics", unmeasured),
    ):
        terms = {t["source"]: t for t in r.diagnostics["uncertainty_budget"]}
        assert {"camera", "optics"} & set(terms) == {source}
        assert terms[source]["x_mm"] == pytest.approx(px * r.scale_mm_per_px, rel=0.05)
        assert terms[source]["z_mm"] == pytest.approx(px * r.scale_mm_per_px, rel=0.05)
        # the same camera's error on both arrises: the thickness takes it twice
        assert terms[source]["thickness_mm"] == pytest.approx(2 * px * r.scale_mm_per_px, rel=0.05)
    assert not {"camera", "optics"} & {t["source"] for t in exact.diagnostics["uncertainty_budget"]}
    assert exact.uncertainty.x_mm < measured.uncertainty.x_mm < plain.uncertainty.x_mm
    assert exact.uncertainty.z_mm < measured.uncertainty.z_mm < plain.uncertainty.z_mm
    assert measured.x_mm == plain.x_mm == exact.x_mm and measured.z_mm == plain.z_mm == exact.z_mm


def test_the_renderer_draws_a_cells_camera_model_and_locate_reads_it_back():
    """A cell that carries its camera's model renders doors as that camera photographs them (the response on
    its shoulder, every edge moved by the spread's shift), so synthetic sets carry what the camera does; the
    same cell locates them to a few thousandths, and a cell without the model is thrown off by it."""
    model = PhotometricModel(shoulder=0.55, edge_shift_u_px=0.05, edge_shift_v_px=-0.25)
    cell = dataclasses.replace(CELL, camera_photometry=model)
    door, truth = DoorSize(900, 50.0, 2100), DoorPose(-3.0, 2.5, -0.6)
    fx = Effects(albedo_hinge=0.5, albedo_background=0.15, blur_sigma_px=1.1, read_noise_dn=1.0)
    img = render_door(cell, door, truth, effects=fx, seed=5).image
    assert not np.array_equal(img, render_door(CELL, door, truth, effects=fx, seed=5).image)
    told = locate(img, cell, door)
    assert told.ok, told.error
    u = told.uncertainty
    assert abs(told.x_mm - truth.x_mm) <= min(2 * u.x_mm, 0.005)
    assert abs(told.z_mm - truth.z_mm) <= min(2 * u.z_mm, 0.005)
    plain = locate(img, CELL, door)
    if plain.ok:
        assert abs(plain.z_mm - told.z_mm) > 0.03


@pytest.mark.parametrize("shift_v_px", [-0.19, 0.19])
def test_the_largest_edge_shift_measured_on_a_real_camera_stays_within_one_and_a_half_sigma(shift_v_px):
    """Bouguet's camera moves its edges 0.19 px along the image's rows against its board's corners (the
    largest such shift measured on the public cameras' photographs). A door seen through it by a cell that
    does not describe the camera, and whose image shows nothing else wrong, is off by that shift at the
    door's scale; the default ``locate.optics_edge_sigma_px`` keeps it within 1.5 sigma, so that on a real
    door, with its other doubts and errors beside it, it stays within 2 (at the four shifts' RMS, 0.1 px,
    it was 1.85 sigma here and 85 % of such doors' z within 2 sigma on bench_camera_doors.py's draws)."""
    cam = CELL.camera
    K = cam.camera_matrix.copy()
    K[1, 2] += shift_v_px  # every edge's image moved along v, as the point spread's asymmetry moves it
    seen = dataclasses.replace(CELL, camera=CameraModel(K, cam.dist_coeffs, cam.image_size))
    cell = dataclasses.replace(CELL, locate=dataclasses.replace(CELL.locate, calibration_sigma_px=0.0))
    door, truth = DoorSize(900, 60.0, 2100), DoorPose(-3.0, 4.0, 0.8)
    img = render_door(seen, door, truth, effects=Effects(blur_sigma_px=1.0, read_noise_dn=1.0), seed=2).image
    r = locate(img, cell, door)
    assert r.ok
    z_err = r.z_mm - truth.z_mm
    assert abs(z_err) == pytest.approx(0.19 * r.scale_mm_per_px, rel=0.2)  # the shift is what is off
    assert abs(z_err) <= 1.5 * r.uncertainty.z_mm
    assert abs(r.x_mm - truth.x_mm) <= 1.5 * r.uncertainty.x_mm


def test_a_pose_uncertain_from_unmeasured_optics_says_how_to_measure_them():
    """A cell that takes its camera's optics as known only within 0.6 px (0.12 mm at this door's scale,
    over the 0.1 mm it allows) refuses the door ``uncertain``, naming the doubt and the command that lifts
    it; the same cell with the camera measured (its model's residual 0.05 px) answers it."""
    door, truth = DoorSize(900, 50.0, 2100), DoorPose(-1.0, 2.0, -0.3)
    img = render_door(CELL, door, truth, effects=Effects(blur_sigma_px=1.0, read_noise_dn=1.0), seed=6).image
    loose = dataclasses.replace(CELL, locate=dataclasses.replace(CELL.locate, optics_edge_sigma_px=0.6))
    r = locate(img, loose, door)
    assert (
        r.error_code == "uncertain"
        and "optics_edge_sigma_px" in r.error
        and "check-model --boards" in r.error
    )
    measured = locate(
        img, dataclasses.replace(loose, camera_photometry=PhotometricModel(residual_edge_px=0.05)), door
    )
    assert measured.ok, measured.error


@pytest.mark.parametrize("seed", [152000, 152002, 152003])
def test_a_faint_door_square_to_a_linear_camera_keeps_the_cells_exponent(seed):
    """A linear camera stated so, a door 0.02 deg from square whose face is 1.7 times the background's light,
    blur 1.1 px, one grey level of noise. Its reference edge keeps one pixel phase; with its phases counted
    point by point (the noise scattering a few into every quarter) it was read as at many, 2.2-2.3 +- 0.13,
    which replaced the cell's exponent: x 5-8 sigma off with each of these noise draws."""
    door = DoorSize(900, 81.02613501325082, 2100)
    pose = DoorPose(-2.636236009008992, -1.9100954930259029, 0.019911491588194996)
    eff = Effects(
        albedo_hinge=0.3958262001897376,
        albedo_background=0.23760017517559445,
        albedo_side=0.2274316774814451,
        vignetting=0.09812089298463036,
        gradient_u=-0.010916874857050951,
        blur_sigma_px=1.079874504177981,
        read_noise_dn=1.0,
    )
    cfg = dataclasses.replace(CELL.locate, calibration_sigma_px=0.0, optics_edge_sigma_px=0.0)
    r = locate(render_door(CELL, door, pose, effects=eff, seed=seed).image, CELL, door, config=cfg)
    assert r.ok and r.uncertainty is not None, r.error
    assert r.diagnostics["camera_response"]["used"] == "cell", r.diagnostics["camera_response"]
    assert abs(r.x_mm - pose.x_mm) <= 3.0 * r.uncertainty.x_mm, (r.x_mm - pose.x_mm, r.uncertainty)
    assert abs(r.z_mm - pose.z_mm) <= 3.0 * r.uncertainty.z_mm, (r.z_mm - pose.z_mm, r.uncertainty)
