"""A camera whose response bends below full scale (a shoulder), in a cell that describes it by a power law:
a door whose levels reach the shoulder, where the image cannot check the response, is answered within its
sigma or refused, never confidently off (the doubt of :mod:`doorloc.vision.response_shoulder`)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from doorloc.cell import DoorSize, load_cell
from doorloc.photometric.model import PhotometricModel
from doorloc.pose import DoorPose
from doorloc.sim.door import render_door
from doorloc.sim.effects import Effects
from doorloc.sim.photometric import CameraRendering, apply_camera
from doorloc.vision.config import LocateConfig
from doorloc.vision.locate import locate
from doorloc.vision.luminance import LuminancePlane
from doorloc.vision.response_shoulder import (
    doubted_knee,
    plain_edges_rule_out,
    shoulder_doubted,
    shoulder_ruled_out,
    shouldered_camera,
    strip_misfit,
    widened_by_shoulder,
)
from doorloc.vision.result import LocateResult, PoseUncertainty

CELL = load_cell(Path(__file__).parents[2] / "fixtures" / "cell_thesis.yaml")
#: OpenCV's left camera's response as check-model reads it on its board photographs (linear to a shoulder
#: from 0.69 of full scale, ending at 0.973): the cell states the power law nearest it, 1.0
SHOULDERED = PhotometricModel(gamma=1.0, shoulder=0.69, white_level=0.973)


def _answer(x: float, z: float, sigma: float, checked: bool = False, absorbed: bool = False) -> LocateResult:
    res = LocateResult(image="door", ok=True, x_mm=x, z_mm=z, yaw_deg=0.5, thickness_mm=40.0)
    res.uncertainty = PoseUncertainty(x_mm=sigma, z_mm=sigma, yaw_deg=0.002)
    response = {"checked": checked or absorbed, "absorbed": absorbed, "cell_gamma": 1.0}
    res.diagnostics = {
        "camera_response": response | ({"first_fit": 2.64} if absorbed else {}),
        "uncertainty_budget": [],
    }
    return res


def test_the_shouldered_camera_keeps_the_power_law_below_its_knee():
    cam = shouldered_camera(2.2, 0.7)
    g = np.linspace(0.05, 0.7, 27)
    assert np.allclose(cam.light_from_grey(g), g**2.2)
    top = np.linspace(0.72, 1.0, 8)
    # above the knee a stored level stands for more light than the power law says (compressed highlights)
    assert np.all(cam.light_from_grey(top) > top**2.2)


#: a camera measured on board photographs that found its response a power law up to 0.9 of full scale
MEASURED_TO_090 = PhotometricModel(gamma=2.2, residual_edge_px=0.05, response_measured_to=0.9)


def test_the_doubted_knee_follows_what_the_cells_model_measured():
    assert doubted_knee(0.7, None) == 0.7  # the cell states its exponent only
    assert doubted_knee(1.0, None) == 1.0  # the cell says its camera keeps its power law
    # a model that found the response's top bending measured it there
    assert doubted_knee(0.7, SHOULDERED) == 1.0
    assert doubted_knee(0.7, PhotometricModel(gamma=2.2, clip_level=0.95)) == 1.0
    assert doubted_knee(0.7, PhotometricModel(gamma=2.2, white_level=0.96, shoulder=1.0)) == 1.0
    # one that found a power law measured it as far as its photographs reached
    assert doubted_knee(0.7, MEASURED_TO_090) == 0.9
    assert doubted_knee(0.7, MEASURED_TO_090.with_values(response_measured_to=0.5)) == 0.7
    assert doubted_knee(0.7, MEASURED_TO_090.with_values(response_measured_to=1.0)) == 1.0
    assert doubted_knee(1.0, MEASURED_TO_090) == 1.0
    # located again through the measured model with a shoulder from that level, not the cell's power law
    bent = shouldered_camera(1.0, 0.9, MEASURED_TO_090)
    assert bent.gamma == 2.2 and bent.shoulder == 0.9 and bent.residual_edge_px == 0.05


@pytest.mark.parametrize(
    "peak,checked,measured,knee,doubted",
    [
        (220, False, None, 0.7, True),
        (170, False, None, 0.7, False),  # nothing above the knee: the mapping would change nothing
        (220, True, None, 0.7, False),  # the image's plain edges read the response
        (220, False, SHOULDERED, 0.7, False),  # the cell carries the camera's measured shoulder
        (220, False, MEASURED_TO_090, 0.7, False),  # ... or its power law measured above the image's levels
        (240, False, MEASURED_TO_090, 0.7, True),  # ... but not as far as this image reaches
        (220, False, None, 1.0, False),  # the cell says its camera keeps its power law
    ],
)
def test_which_answers_take_the_doubt(peak, checked, measured, knee, doubted):
    plane = np.full((16, 16), 90, np.uint8)
    plane[4, 4] = peak
    lum = LuminancePlane(plane, 1.0)
    knee = doubted_knee(knee, measured)
    assert shoulder_doubted(_answer(1.0, 2.0, 0.02, checked), lum, knee, 1.0) is doubted
    # a plain door whose edges read the cell's exponent, or could not be read: never
    assert not shoulder_doubted(_answer(1.0, 2.0, 0.02, checked), lum, knee, 0.0)
    # whose edges read another exponent, which replaced the cell's: as an arris door whose edges could not
    # be read (the exponent may be the shoulder's stand-in)
    for arris_mm in (0.0, 1.0):
        absorbed = _answer(1.0, 2.0, 0.02, absorbed=True)
        # (the checked case above is doubted too: an absorbed reading is a checked one)
        assert shoulder_doubted(absorbed, lum, knee, arris_mm) is (doubted or checked)
    assert not shoulder_doubted(LocateResult.refusal("door", "uncertain", "no"), lum, knee, 1.0)
    # 16-bit levels on their own scale
    assert (
        shoulder_doubted(
            _answer(1.0, 2.0, 0.02, checked),
            LuminancePlane(plane.astype(np.uint16) * 257, 255 / 65535),
            knee,
            1.0,
        )
        is doubted
    )


def test_the_move_widens_the_answer_or_refuses_it():
    cfg = LocateConfig()
    small = widened_by_shoulder(_answer(1.0, 2.0, 0.02), _answer(1.03, 1.96, 0.02), 0.7, None, cfg)
    assert small.ok and small.uncertainty is not None
    assert small.uncertainty.x_mm == pytest.approx(np.hypot(0.02, 0.03))
    assert small.uncertainty.z_mm == pytest.approx(np.hypot(0.02, 0.04))
    term = small.diagnostics["uncertainty_budget"][-1]
    assert term["source"] == "response_shoulder" and term["x_mm"] == pytest.approx(0.03)
    assert small.diagnostics["response_shoulder"]["move_z_mm"] == pytest.approx(-0.04)
    large = widened_by_shoulder(_answer(1.0, 2.0, 0.02), _answer(1.12, 2.0, 0.02), 0.7, None, cfg)
    assert not large.ok and large.error_code == "uncertain"
    assert "above 0.7 of full scale" in large.error and "doorloc calibrate --optics" in large.error
    # a cell whose model measured a power law only as far as a lower level: measure it again, brighter
    again = widened_by_shoulder(_answer(1.0, 2.0, 0.02), _answer(1.12, 2.0, 0.02), 0.7, None, cfg, 0.6)
    assert "read the camera's response up to 0.60 of full scale only" in again.error
    assert large.diagnostics["measured"]["x_mm"] == 1.0
    assert "plain edges" not in large.error
    # where the plain edges' exponent replaced the cell's, the refusal says which they read
    read = widened_by_shoulder(
        _answer(1.0, 2.0, 0.02, absorbed=True), _answer(1.12, 2.0, 0.02), 0.7, None, cfg
    )
    assert "plain edges read the exponent 2.64 in place of the cell's 1.00" in read.error
    # a shouldered reading that was refused leaves the answer as it was, and says so
    kept = widened_by_shoulder(_answer(1.0, 2.0, 0.02), None, 0.7, None, cfg)
    assert (
        kept.ok and kept.uncertainty.x_mm == 0.02 and kept.diagnostics["response_shoulder"]["refused"] is None
    )


@pytest.mark.parametrize(
    "key,plain,bent,ruled_out",
    [
        # power-law cameras (arris bench 53002, 55009): the chamfers' grey-level misfit at the cell's exponent
        ("chamfer_grey_misfit", 1.8012, 2.4587, True),
        ("chamfer_grey_misfit", 0.9544, 1.8307, True),
        # OpenCV's camera's shoulder (bench_camera_doors 81000 door_017): about as well either way
        ("chamfer_grey_misfit", 1.457, 1.5546, False),
        # strips the plain reading does not describe (door_012, 2.9 times the noise) rule nothing out
        ("chamfer_grey_misfit", 2.8981, 4.0, False),
        # a lit rounding's arcs (arris bench 52022), and roundings whose arcs fit every exponent alike
        ("arc_misfit_over_free", 1.015, 1.6302, True),
        ("arc_misfit_over_free", 1.0, 1.0, False),
        ("arc_misfit_over_free", 1.2, 2.0, False),
    ],
)
def test_the_strips_rule_the_shoulder_out_where_their_misfit_rises(key, plain, bent, ruled_out):
    figure = shoulder_ruled_out((key, plain), (key, bent))
    assert (figure is not None) is ruled_out
    if ruled_out:
        assert figure == {"ruled_out_by": key, "misfit_ratio": round(bent / plain, 3)}
    # a reading whose strips say nothing, or another kind of evidence: nothing ruled out
    assert shoulder_ruled_out(None, (key, bent)) is None and shoulder_ruled_out((key, plain), None) is None
    assert shoulder_ruled_out((key, plain), ("other", bent)) is None
    # a ruled-out shoulder leaves the answer as it was, the figure in its diagnostics
    out = widened_by_shoulder(_answer(1.0, 2.0, 0.02), _answer(1.2, 2.0, 0.02), 0.7, figure, LocateConfig())
    assert out.ok is ruled_out
    if ruled_out:
        assert out.uncertainty.x_mm == 0.02 and out.diagnostics["response_shoulder"]["ruled_out_by"] == key


def test_the_plain_edges_rule_the_shoulder_out_where_they_read_another_exponent_through_it():
    # read through the shoulder, the edges read the cell's exponent: the shoulder may be what they show
    kept = _answer(1.0, 2.0, 0.02, checked=True)
    assert plain_edges_rule_out(kept) is None
    # they read another and it replaced the cell's there too: the shoulder at the cell's exponent is not
    # what they show (tests/vision/test_camera_response.py's door through a shoulder from 0.55: 2.61)
    assert plain_edges_rule_out(_answer(1.0, 2.0, 0.02, absorbed=True)) == {
        "ruled_out_by": "plain_edges_exponent",
        "exponent_read": 2.64,
    }
    # and the answer then stands as it was
    cfg = LocateConfig()
    ruled = plain_edges_rule_out(_answer(1.12, 2.0, 0.02, absorbed=True))
    stands = widened_by_shoulder(
        _answer(1.0, 2.0, 0.02, absorbed=True), _answer(1.12, 2.0, 0.02), 0.7, ruled, cfg
    )
    assert stands.ok and stands.uncertainty.x_mm == 0.02
    assert stands.diagnostics["response_shoulder"]["ruled_out_by"] == "plain_edges_exponent"


def _fit(grey_misfit: float = math.nan, arcs: float | None = None) -> SimpleNamespace:
    """What :func:`strip_misfit` reads of a strip fit: its grey-level misfit, and a rounding's misfit under
    lights (here the same ratio from every direction)."""
    under = None if arcs is None else (lambda d: np.full(len(d), arcs))
    return SimpleNamespace(grey_misfit=grey_misfit, misfit_under_lights=under)


def test_the_strips_misfit_is_read_per_kind_of_arris():
    chamfers = [_fit(1.5), _fit(2.0), _fit(3.0)]
    kind, value = strip_misfit(chamfers, chamfered=True)
    assert kind == "chamfer_grey_misfit" and value == pytest.approx((1.5 * 2.0 * 3.0) ** (1 / 3))
    assert strip_misfit([_fit(1.5), _fit()], chamfered=True) is None  # a strip not scored
    assert strip_misfit([], chamfered=True) is None
    kind, value = strip_misfit([_fit(arcs=1.3), _fit(arcs=1.3), _fit()], chamfered=False)
    assert kind == "arc_misfit_over_free" and value == pytest.approx(1.3, rel=1e-6)
    assert strip_misfit([_fit(2.0)], chamfered=False) is None  # no rounding's shading to score


def _read_without_and_with_the_doubt(
    door: DoorSize,
    pose: DoorPose,
    scene: Effects,
    camera: PhotometricModel,
    rendering: CameraRendering,
    seed: int,
    measured: PhotometricModel | None = None,
) -> tuple[LocateResult, LocateResult]:
    """The door rendered through ``camera`` (``rendering.exposure``: the level its 99.5th percentile reaches,
    a fraction of full scale) and located in a cell stating the power law 1.0 (or carrying the photometric
    model ``measured``), without the shoulder's doubt
    and with it. Asserts what the doubt is for: without it answered and off by more than 2 of its sigmas in
    x; with it located again through a shoulder from 0.7 and within 2 sigma, or refused `uncertain` naming
    the shoulder. ``scene`` is the door and its light only: the blur, noise and compression are the camera's
    (``rendering``), so the renderer's own stay at their defaults (off)."""
    assert scene.blur_sigma_px == scene.full_well_e == scene.read_noise_dn == scene.jpeg_quality == 0
    rd = render_door(CELL, door, pose, effects=scene, seed=seed)
    exposure = rendering.exposure / float(np.percentile(rd.radiance, 99.5))
    img = apply_camera(rd.radiance, camera, dataclasses.replace(rendering, exposure=exposure), seed=seed)
    cell = dataclasses.replace(
        CELL, response_gamma=1.0, response_gamma_sigma=None, camera_photometry=measured
    )
    cfg = dataclasses.replace(cell.locate, calibration_sigma_px=0.0)
    without = locate(img, cell, door, config=dataclasses.replace(cfg, response_shoulder_knee=1.0))
    res = locate(img, cell, door, config=cfg)
    assert without.ok and without.uncertainty is not None
    assert abs(without.x_mm - pose.x_mm) > 2 * without.uncertainty.x_mm
    assert res.diagnostics["response_shoulder"]["knee"] == 0.7
    if res.ok:
        assert res.uncertainty is not None
        assert abs(res.x_mm - pose.x_mm) <= 2 * res.uncertainty.x_mm
        assert abs(res.z_mm - pose.z_mm) <= 2 * res.uncertainty.z_mm
    else:
        assert res.error_code == "uncertain" and "shoulder" in res.error
    return without, res


def _chamfer_door_012() -> tuple[DoorSize, DoorPose, Effects]:
    """bench_camera_doors.py --model <OpenCV's report> --n 24 --seed 81000, door_012: a 1.11 mm chamfer."""
    door = DoorSize(900, 58.329, 2100, 1.108, "chamfer")
    pose = DoorPose(x_mm=9.655, z_mm=-3.007, yaw_deg=-1.178)
    scene = Effects(
        albedo_hinge=0.3859,
        albedo_side=0.3015,
        albedo_background=0.0900,
        light_ambient=0.8405,
        light_directional=0.0764,
        light_azimuth_deg=-57.17,
        light_elevation_deg=2.91,
        grain_contrast=0.0495,
        grain_period_mm=3.865,
        shadow_z_mm=29.91,
        arris_profile="chamfer",
    )
    return door, pose, scene


def test_a_chamfer_in_a_cameras_shoulder_is_not_confidently_off():
    # door_012 through its camera's response alone, exposed to 0.92 of full scale; without the doubt it was
    # answered 0.18 mm off at 2.6 sigma (the whole model: 0.181 mm, 2.6 sigma)
    without, res = _read_without_and_with_the_doubt(
        *_chamfer_door_012(), SHOULDERED, CameraRendering(1.548, 0.9174, 2.012), seed=81000012
    )
    assert not without.diagnostics["camera_response"]["absorbed"]
    if not res.ok:
        assert "plain edges" not in res.error


def test_a_power_law_measured_below_the_doors_levels_keeps_the_doubt_above_them():
    # the same chamfer, in a cell whose camera model found a power law on board photographs whose bright
    # squares reached 0.6 of full scale (below the shoulder at 0.69): the model says nothing of the levels the
    # door reaches, so the doubt stands from the cell's knee, and a refusal says how to measure them
    measured = PhotometricModel(gamma=1.0, residual_edge_px=0.13, response_measured_to=0.6)
    _, res = _read_without_and_with_the_doubt(
        *_chamfer_door_012(), SHOULDERED, CameraRendering(1.548, 0.9174, 2.012), 81000012, measured
    )
    if not res.ok:
        assert "read the camera's response up to 0.60 of full scale only" in res.error


def test_a_plain_door_whose_edges_read_a_shoulder_as_an_exponent_is_not_confidently_off():
    # bench_camera_doors.py --model <OpenCV's report> --n 32 --seed 75000, door_007: a plain door exposed to
    # 0.95 of full scale (its brightest pixel 0.90) through the camera's whole model (its shoulder, white
    # level, point-spread tail and blur): its edges read an exponent of 2.8 for the cell's 1.0, which replaced
    # it, and without the doubt it was answered 0.14 mm off at 5 sigma; through a shoulder at the cell's
    # exponent it is 0.01 mm off
    whole = PhotometricModel(
        gamma=1.0, shoulder=0.6905, white_level=0.9728, psf_tail=0.05, psf_tail_px=6.0, blur_field=1.7579
    )
    door = DoorSize(900, 76.031, 2100, 0.0, "chamfer")
    pose = DoorPose(x_mm=6.335, z_mm=-1.057, yaw_deg=0.219)
    scene = Effects(
        albedo_hinge=0.5395,
        albedo_side=0.4167,
        albedo_background=0.1365,
        light_ambient=0.7718,
        light_directional=0.2044,
        light_azimuth_deg=51.81,
        light_elevation_deg=0.19,
        grain_contrast=0.0122,
        grain_period_mm=3.346,
        shadow_z_mm=63.86,
    )
    without, res = _read_without_and_with_the_doubt(
        door, pose, scene, whole, CameraRendering(1.796, 0.9459, 1.580), seed=75000007
    )
    # the image's exponent replaced the cell's
    assert without.diagnostics["camera_response"]["absorbed"]
    if not res.ok:
        assert "plain edges read the exponent" in res.error


def test_the_knee_is_a_level_of_full_scale_set_in_the_cell_file(tmp_path):
    with pytest.raises(ValueError, match="response_shoulder_knee"):
        LocateConfig(response_shoulder_knee=0.0)
    with pytest.raises(ValueError, match="response_shoulder_knee"):
        LocateConfig(response_shoulder_knee=1.2)
    assert LocateConfig().response_shoulder_knee == 0.7
    text = (Path(__file__).parents[2] / "fixtures" / "cell_thesis.yaml").read_text()
    cell_file = tmp_path / "cell.yaml"
    cell_file.write_text(text + "\nlocate:\n  response_shoulder_knee: 1.0\n")
    assert load_cell(cell_file).locate.response_shoulder_knee == 1.0
