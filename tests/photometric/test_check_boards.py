"""`doorloc check-model --boards` on rendered board photographs: a photometric effect drawn at random (seed
printed) is hidden in them and must be named with a held-out gain; a control must answer []; bad input exits 2
with a sentence and writes nothing."""

from __future__ import annotations

import json
import os
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from doorloc.app.cli import app
from doorloc.calib.camera import CameraModel
from doorloc.calib.detect import Chessboard
from doorloc.calib.io import CalibrationFile, load_calibration, save_calibration
from doorloc.photometric.check import check_boards
from doorloc.photometric.model import PhotometricModel
from doorloc.photometric.report import report_markdown
from doorloc.sim.boards import Checkerboard
from doorloc.sim.photometric import random_board_views
from doorloc.vision.response_shoulder import doubted_knee

CAMERA = CameraModel.from_values(
    [[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], [-0.2, 0.05, 0, 0, 0], (640, 480)
)
VIEWS = 6

#: effects whose strength moves edges by well over the noise of six photographs, each drawn in its range
HIDDEN = {
    "response_gamma": lambda r: {"gamma": r.uniform(1.8, 2.4)},
    "response_shoulder": lambda r: {"shoulder": r.uniform(0.6, 0.75)},
    "print_spread": lambda r: {"print_spread_mm": r.choice([-1, 1]) * r.uniform(0.15, 0.25)},
    # exposures run 0.55-1.05 of full scale: the brighter photographs' light squares pass the clip (seed
    # 4245: clip 0.718, one photograph of six clipped, named)
    "sensor_clipping": lambda r: {"clip_level": r.uniform(0.6, 0.72)},
}


def _boards(folder: Path, model: PhotometricModel, seed: int) -> Path:
    folder.mkdir()
    for name, img in random_board_views(CAMERA, Checkerboard(9, 6, 25.0), model, VIEWS, seed):
        cv2.imwrite(str(folder / name), img)
    cal = folder.parent / "camera.yaml"
    save_calibration(CalibrationFile(CAMERA), cal)
    return cal


def _run(folder: Path, cal: Path, out: Path):
    return CliRunner().invoke(
        app,
        [
            "check-model",
            "--boards",
            str(folder),
            "--pattern",
            "9x6",
            "--square",
            "25",
            "--calibration",
            str(cal),
            "--out",
            str(out),
        ],
    )


@pytest.mark.slow
def test_hidden_effect_is_named_and_gains_on_held_out_photographs(tmp_path):
    # a fixed default draw: a weak shoulder (0.74, seed 251596) is missed, which bench_boards_model
    # counts; CI must not pass or fail by the draw. DOORLOC_TEST_SEED tries another.
    seed = int(os.environ.get("DOORLOC_TEST_SEED", 4242))
    rng = np.random.default_rng(seed)
    name = list(HIDDEN)[int(rng.integers(len(HIDDEN)))]
    values = HIDDEN[name](rng)
    print(f"seed {seed}: hidden {name} {values}")
    cal = _boards(tmp_path / "boards", PhotometricModel(**values), seed)
    res = _run(tmp_path / "boards", cal, tmp_path / "report")
    assert res.exit_code == 0, res.output
    rep = json.loads((tmp_path / "report" / "report.json").read_text())
    assert name in rep["causes"], (seed, rep["causes"])
    off = rep["heldout_edge_offset_rms_px"]
    assert off["after"] < 0.5 * off["before"], (seed, off)
    assert all(i["heldout"] for i in rep["images"]) and len(rep["images"]) == VIEWS
    ext = load_calibration(tmp_path / "report" / rep["extended_model"])
    assert ext.photometric_model is not None and "check-model --boards" in (
        ext.photometric_model_provenance or ""
    )
    # what the model leaves on the held-out photographs' edges goes with it, as locate's measured doubt: their
    # medians' RMS or, where larger, that by edge direction (noise taken off), which on these renders (no
    # effect that changes with the direction) adds little
    residual = ext.photometric_model["residual_edge_px"]
    assert off["after"] * (1 - 1e-3) <= residual <= off["after"] + 0.02, (seed, residual, off)
    assert (tmp_path / "report" / "report.md").read_text().startswith("# Model check")
    # six photographs are too few for the free tone curve (one median each, two per parameter): the report says so
    assert "needs 12 photographs, 6 given" in rep["not_tried"]["response_tone"]
    assert (
        "Not tried, too few photographs:\n- response_tone:" in (tmp_path / "report" / "report.md").read_text()
    )


@pytest.mark.slow
def test_control_answers_nothing(tmp_path):
    # a fixed default draw: a weak shoulder (0.74, seed 251596) is missed, which bench_boards_model
    # counts; CI must not pass or fail by the draw. DOORLOC_TEST_SEED tries another.
    seed = int(os.environ.get("DOORLOC_TEST_SEED", 4242))
    print(f"seed {seed}: control")
    cal = _boards(tmp_path / "boards", PhotometricModel(), seed)
    res = _run(tmp_path / "boards", cal, tmp_path / "report")
    assert res.exit_code == 0, res.output
    rep = json.loads((tmp_path / "report" / "report.json").read_text())
    assert rep["causes"] == [], (seed, rep["causes"])
    assert rep["heldout_edge_offset_rms_px"]["before"] < 0.03
    # read noise 0.5-1.5 grey levels and the 8-bit rounding: the plateaus' RMS reads it, and where the
    # model is the renderer's own the edge profiles are drawn within 1.5x of it (real cameras are not)
    assert 0.6 < rep["noise_rms"] < 1.6, rep["noise_rms"]
    assert rep["heldout_profile_rms"]["before"] < 1.5 * rep["noise_rms"], (
        rep["heldout_profile_rms"],
        rep["noise_rms"],
    )


def test_bad_input_exits_2_and_writes_nothing(tmp_path):
    cal = tmp_path / "camera.yaml"
    save_calibration(CalibrationFile(CAMERA), cal)
    empty = tmp_path / "empty"
    empty.mkdir()
    res = _run(empty, cal, tmp_path / "out1")
    assert res.exit_code == 2 and "no image files" in res.output
    assert not (tmp_path / "out1").exists()
    res = CliRunner().invoke(
        app,
        [
            "check-model",
            "--boards",
            str(empty),
            "--pattern",
            "nine",
            "--square",
            "25",
            "--out",
            str(tmp_path / "o"),
        ],
    )
    assert res.exit_code == 2 and "--pattern" in res.output
    bad = tmp_path / "bad.yaml"
    bad.write_text(cal.read_text() + "photometric_model:\n   gama: 2.0\n")
    res = _run(empty, bad, tmp_path / "out2")
    assert res.exit_code == 2 and "gama" in res.output
    assert not (tmp_path / "out2").exists()


def test_report_says_when_the_extended_model_draws_profiles_worse(tmp_path):

    cal = _boards(tmp_path / "boards", PhotometricModel(), 4242)
    check = check_boards(tmp_path / "boards", Chessboard(9, 6, 25.0), load_calibration(cal))
    named = replace(check, causes=["response_shoulder"])
    assert "draws these edges' profiles worse" not in report_markdown(named)
    worse = replace(
        named,
        photographs=[replace(p, profile_rms_after=1.2 * p.profile_rms_before) for p in check.photographs],
    )
    assert "draws these edges' profiles worse" in report_markdown(worse)
    # a model that names nothing has nothing to draw worse
    assert "draws these edges' profiles worse" not in report_markdown(replace(worse, causes=[]))


def test_report_says_to_use_the_extended_calibration_wherever_it_measured_something(tmp_path):
    """The extended calibration replaces locate's doubt for optics nobody measured by the residual the
    photographs measured, so the report's action names it even where no cause was found; with neither a
    cause nor a residual there is nothing to do."""
    cal = _boards(tmp_path / "boards", PhotometricModel(), 4243)
    check = check_boards(tmp_path / "boards", Chessboard(9, 6, 25.0), load_calibration(cal))

    def action(c):
        return next(ln for ln in report_markdown(c).splitlines() if ln.startswith("**Action:**"))

    measured = replace(check, causes=[], model=check.model.with_values(residual_edge_px=0.021))
    assert "camera_photometric.yaml" in action(measured) and "0.021 px" in action(measured)
    assert "optics_edge_sigma_px" in action(measured)
    named = replace(measured, causes=["response_shoulder"])
    assert "camera_photometric.yaml" in action(named) and "0.021 px" in action(named)
    assert "clip" not in action(named)
    # a clip found: locate reads it (a door at it is refused even where the image shows no noise)
    clipped = replace(named, causes=["sensor_clipping"], model=named.model.with_values(clip_level=240 / 255))
    assert "at this camera's clip (240 grey)" in action(clipped) and "0.021 px" in action(clipped)
    nothing = replace(check, causes=[], model=check.model.with_values(residual_edge_px=0.0))
    assert action(nothing) == "**Action:** none."


@pytest.mark.slow
def test_hidden_ghost_is_named_as_the_spreads_asymmetry(tmp_path):
    # a ghost (a fifth of the light 3-4 px away, a random direction) moves the edges against the corners:
    # psf_asymmetry must be named, its shift pointing the ghost's way. A fixed default draw; DOORLOC_TEST_SEED
    # tries another.

    seed = int(os.environ.get("DOORLOC_TEST_SEED", 4242))
    rng = np.random.default_rng(seed)
    d, phi = rng.uniform(3.0, 4.0), rng.uniform(0, 2 * np.pi)
    ghost = (float(rng.uniform(0.2, 0.3)), float(d * np.cos(phi)), float(d * np.sin(phi)))
    print(f"seed {seed}: ghost {ghost}")
    folder = tmp_path / "boards"
    folder.mkdir()
    for name, img in random_board_views(
        CAMERA, Checkerboard(9, 6, 25.0), PhotometricModel(), 8, seed, ghost=ghost
    ):
        cv2.imwrite(str(folder / name), img)
    c = check_boards(folder, Chessboard(9, 6, 25.0), CalibrationFile(CAMERA))
    assert "psf_asymmetry" in c.causes, (seed, c.causes)
    shift = np.array([c.model.edge_shift_u_px, c.model.edge_shift_v_px])
    # the edges move the ghost's way (by a share of it that the blur sets)
    assert shift @ np.array(ghost[1:]) / np.linalg.norm(ghost[1:]) > 0.5 * np.linalg.norm(shift), (
        seed,
        shift,
    )


@pytest.mark.slow
def test_a_bias_that_changes_direction_from_photograph_to_photograph_is_in_the_edge_residual(tmp_path):
    # each photograph with its own ghost (camera shake, fields out of register): no fixed shift explains the
    # edges, their median over all directions cancels much of it, and locate's per-edge doubt must carry it

    seed = int(os.environ.get("DOORLOC_TEST_SEED", 4242))
    rng = np.random.default_rng(seed)
    folder = tmp_path / "boards"
    folder.mkdir()
    for i in range(8):
        phi = rng.uniform(0, 2 * np.pi)
        ghost = (0.25, 3.5 * np.cos(phi), 3.5 * np.sin(phi))
        ((_, img),) = random_board_views(
            CAMERA, Checkerboard(9, 6, 25.0), PhotometricModel(), 1, seed * 100 + i, ghost=ghost
        )
        cv2.imwrite(str(folder / f"view{i:02d}.png"), img)
    c = check_boards(folder, Chessboard(9, 6, 25.0), CalibrationFile(CAMERA))
    median_rms = c.heldout_rms("offset")["after"]
    print(
        f"seed {seed}: causes {c.causes}, median RMS {median_rms:.3f}, residual {c.model.residual_edge_px:.3f} px"
    )
    # the photographs' medians keep only part of it (edges of each direction are not balanced in every view)
    assert c.model.residual_edge_px > max(0.1, 2 * median_rms)


@pytest.mark.slow
def test_hidden_interlaced_fields_are_named_and_measured(tmp_path):
    # an interlaced camera whose even rows sample the scene 0.12-0.25 px from the odd rows', mostly down the
    # columns (as Bouguet's photographs show, +0.2 px): interlaced_fields must be named, its mean offset read
    # within 0.03 px, and the held-out profile misfit must fall. A fixed default draw; DOORLOC_TEST_SEED
    # tries another.
    seed = int(os.environ.get("DOORLOC_TEST_SEED", 4242))
    rng = np.random.default_rng([seed, 31])
    v = float(rng.choice([-1.0, 1.0]) * rng.uniform(0.12, 0.25))
    u = float(rng.uniform(-0.3, 0.3) * abs(v))
    print(f"seed {seed}: fields out of register by ({u:+.3f}, {v:+.3f}) px")
    model = PhotometricModel(field_offset_u_px=u, field_offset_v_px=v)
    folder = tmp_path / "boards"
    folder.mkdir()
    for name, img in random_board_views(CAMERA, Checkerboard(9, 6, 25.0), model, VIEWS, seed):
        cv2.imwrite(str(folder / name), img)
    c = check_boards(folder, Chessboard(9, 6, 25.0), CalibrationFile(CAMERA))
    assert "interlaced_fields" in c.causes, (seed, c.causes)
    read = np.array([c.model.field_offset_u_px, c.model.field_offset_v_px])
    assert np.all(np.abs(read - [u, v]) < 0.03), (seed, read, (u, v))
    prof = c.heldout_rms("profile_rms")
    assert prof["after"] < prof["before"], (seed, prof)
    # the edges' medians are not moved by the fields: no edge-moving cause is named for them
    assert not set(c.causes) & {"response_gamma", "print_spread", "psf_asymmetry"}, (seed, c.causes)


def _jpeg_boards(folder: Path, seed: int, quality: int, as_jpeg_files: bool, **views) -> Path:
    """Board photographs of the plain model through JPEG of ``quality``: written as JPEG files (their tables
    say the quality) or, decoded, as PNG files (the compression's marks without its tables)."""
    folder.mkdir()
    for name, img in random_board_views(
        CAMERA, Checkerboard(9, 6, 25.0), PhotometricModel(), VIEWS, seed, **views
    ):
        if as_jpeg_files:
            cv2.imwrite(
                str(folder / Path(name).with_suffix(".jpg")), img, [cv2.IMWRITE_JPEG_QUALITY, quality]
            )
        else:
            ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, quality])
            assert ok
            cv2.imwrite(str(folder / name), cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE))
    return folder


@pytest.mark.slow
def test_jpeg_boards_without_fields_are_not_read_as_interlaced(tmp_path):
    # JPEG's 8 x 8 blocks start on rows divisible by 8 and bend the rows beside their borders as fields out of
    # register would: boards without fields through JPEG 30 had interlaced_fields named, read on every row
    # (0.05 px); the offset is read on the blocks' inner rows. A fixed default draw; DOORLOC_TEST_SEED tries
    # another.
    seed = int(os.environ.get("DOORLOC_TEST_SEED", 19))
    print(f"seed {seed}: JPEG 30, no fields")
    folder = _jpeg_boards(tmp_path / "boards", seed, 30, as_jpeg_files=False)
    c = check_boards(folder, Chessboard(9, 6, 25.0), CalibrationFile(CAMERA))
    assert "interlaced_fields" not in c.causes, (seed, c.causes)
    assert c.fields is not None and c.fields.rms_px < 0.03, (seed, c.fields.rms_px)


@pytest.mark.slow
def test_jpeg_photographs_are_judged_against_their_twins(tmp_path):
    # a control stored as JPEG of quality 50 (OpenCV's public photographs' own): the plateaus' spread calls the
    # renderer's own model wrong, each photograph's twin (its pose, noise and the quality its file's tables
    # say) does not. A fixed default draw; DOORLOC_TEST_SEED tries another.
    seed = int(os.environ.get("DOORLOC_TEST_SEED", 23))
    print(f"seed {seed}: JPEG 50, no effect")
    folder = _jpeg_boards(tmp_path / "boards", seed, 50, as_jpeg_files=True, read_noise=(2.0, 3.0))
    cal = tmp_path / "camera.yaml"
    save_calibration(CalibrationFile(CAMERA), cal)
    res = _run(folder, cal, tmp_path / "report")
    assert res.exit_code == 0, res.output
    rep = json.loads((tmp_path / "report" / "report.json").read_text())
    assert {i["twin"]["jpeg_quality"] for i in rep["images"]} == {50}
    over_noise = rep["heldout_profile_rms"]["before"] / rep["noise_rms"]
    over_twin = rep["heldout_profile_over_twin"]["before"]
    print(f"profile misfit over the plateaus' spread {over_noise:.2f}, over the twins' {over_twin:.2f}")
    assert over_noise > 1.2
    assert 0.85 < over_twin < 1.15
    md = (tmp_path / "report" / "report.md").read_text()
    assert "JPEG quality 50" in md and "--effect jpeg_quality=50" in md


@pytest.mark.slow
def test_the_model_records_how_far_up_the_photographs_read_the_response(tmp_path):
    """A power-law camera's boards photographed dim (light squares at 0.45-0.55 of full scale) say nothing of
    a shoulder above them: the model records the level they reached, and a door brighter than that keeps the
    shoulder's doubt (:func:`doorloc.vision.response_shoulder.doubted_knee`); photographed bright, the level
    follows them up."""
    reached = {}
    for name, exposure in (("dim", (0.45, 0.55)), ("bright", (0.9, 1.0))):
        folder = tmp_path / name
        folder.mkdir()
        for image_name, img in random_board_views(
            CAMERA, Checkerboard(9, 6, 25.0), PhotometricModel(), VIEWS, 4242, exposure=exposure
        ):
            cv2.imwrite(str(folder / image_name), img)
        check = check_boards(folder, Chessboard(9, 6, 25.0), CalibrationFile(CAMERA))
        assert check.causes == [] and check.model.shoulder == 1.0, check.causes
        reached[name] = check.model.response_measured_to
    assert 0.4 < reached["dim"] < 0.56 and 0.85 < reached["bright"] <= 1.0, reached
    dim = PhotometricModel(response_measured_to=reached["dim"])
    assert doubted_knee(0.7, dim) == 0.7 and doubted_knee(0.4, dim) == pytest.approx(reached["dim"])


@pytest.mark.slow
def test_a_power_law_is_named_so_where_a_curved_response_fits_it_no_better(tmp_path):
    # a pure power law (bench_boards_model.py's hidden response_gamma, seed 35097: 2.18) that the curved
    # response's two parameters fit as well held out (within one standard error: the data cannot tell them
    # apart) is named by the simpler form, the other listed as not told apart; it was named
    # response_curvature, whose extra parameter read 0 within its sigma
    seed = 35097
    gamma = float(np.random.default_rng(seed).uniform(1.6, 2.4))
    folder = tmp_path / "boards"
    folder.mkdir()
    for name, img in random_board_views(
        CAMERA, Checkerboard(9, 6, 25.0), PhotometricModel(gamma=gamma), 8, seed
    ):
        cv2.imwrite(str(folder / name), img)
    c = check_boards(folder, Chessboard(9, 6, 25.0), CalibrationFile(CAMERA))
    assert c.causes == ["response_gamma"], (seed, c.causes, c.alternatives)
    assert "response_curvature" in c.alternatives["response_gamma"], c.alternatives
    assert abs(c.model.gamma - gamma) < 0.05 and c.model.curvature == 0.0, (c.model.gamma, gamma)


def test_a_12_bit_cameras_photographs_are_read_at_its_depth(tmp_path):
    """A 12-bit camera that stores its levels from 0 in 16-bit photographs (v as round(v * 4095 / 255)): the
    check reads their depth off them (or the calibration's ``stored_bits``) and places their edges on the
    levels the 8-bit photographs hold, where on 65535's scale it read 16 of 255 levels; the extended
    calibration it writes states the depth, for locate."""
    from types import SimpleNamespace

    from doorloc.photometric.check import measure_boards
    from doorloc.photometric.report import extended_calibration

    eight = tmp_path / "eight"
    cal = _boards(eight, PhotometricModel(gamma=2.2), 4246)
    twelve = tmp_path / "twelve"
    twelve.mkdir()
    for f in sorted(eight.iterdir()):
        img = cv2.imread(str(f), cv2.IMREAD_UNCHANGED)
        cv2.imwrite(str(twelve / f.name), np.rint(img * (4095 / 255)).astype(np.uint16))
    board = Chessboard(9, 6, 25.0)
    a = measure_boards(eight, board, load_calibration(cal))
    b = measure_boards(twelve, board, load_calibration(cal))
    stated = measure_boards(twelve, board, replace(load_calibration(cal), stored_bits=12))
    assert a.stored_bits is None and b.stored_bits == stated.stored_bits == 12
    assert len(a.photographs) == len(b.photographs) == VIEWS
    for pa, pb in zip(a.photographs, b.photographs, strict=True):
        assert np.array_equal(pa.gray, pb.gray)
        # (corners are found on each image stretched to its own brightest level: a scan line more or less)
        assert np.nanmedian(pb.edges.offset_px) == pytest.approx(np.nanmedian(pa.edges.offset_px), abs=0.005)
    check = SimpleNamespace(stored_bits=12, model=PhotometricModel(gamma=2.2), photographs=[], causes=[])
    ext = extended_calibration(check, load_calibration(cal), "doorloc check-model", "2026-12-07")
    assert ext.stored_bits == 12
    # (a check that read no depth keeps the one its calibration states)
    unread = SimpleNamespace(**{**vars(check), "stored_bits": None})
    assert extended_calibration(unread, ext, "doorloc check-model", "2026-12-07").stored_bits == 12


@pytest.mark.slow
def test_16_bit_photographs_are_read_on_one_fixed_scale(tmp_path):
    # the same photographs stored in 16 bits (each level v as 257 v, full scale to full scale) are the same
    # photographs: the check reads them on the scale locate reads a 16-bit image on (255 / 65535), not each
    # stretched to its own brightest level (a gain per photograph that bends the response read through
    # it) and truncated; Bouguet's twenty so stored had lost their shoulder and read 0.029 px for 0.023
    rng = np.random.default_rng(4245)
    values = {"gamma": float(rng.uniform(1.8, 2.4)), "shoulder": 0.7}
    eight = tmp_path / "eight"
    cal = _boards(eight, PhotometricModel(**values), 4245)
    sixteen = tmp_path / "sixteen"
    sixteen.mkdir()
    for f in sorted(eight.iterdir()):
        img = cv2.imread(str(f), cv2.IMREAD_UNCHANGED)
        assert img.dtype == np.uint8
        cv2.imwrite(str(sixteen / f.name), img.astype(np.uint16) * 257)
    a = check_boards(eight, Chessboard(9, 6, 25.0), load_calibration(cal))
    b = check_boards(sixteen, Chessboard(9, 6, 25.0), load_calibration(cal))
    assert a.causes == b.causes and a.causes, (a.causes, b.causes)
    for pa, pb in zip(a.photographs, b.photographs, strict=True):
        assert pa.offset_before_px == pytest.approx(pb.offset_before_px, abs=1e-3)
        assert pa.offset_after_px == pytest.approx(pb.offset_after_px, abs=1e-3)
    # (corners are found on each image stretched to its own brightest level, so they may differ by a few
    # thousandths of a pixel: the fits agree well within their sigma)
    name = a.causes[0]
    for p, v in a.parameters[name].items():
        assert abs(getattr(a.model, p) - getattr(b.model, p)) < 0.5 * v["sigma"], (p, a.model, b.model, v)
