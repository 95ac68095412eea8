"""check-model on rendered measured sets: a hidden effect is named and fixed, a control answers [].

The hidden effect is drawn from the catalogue with a seed that is printed. The default seed is fixed, so that
the suite gives the same answer on every machine (seed 900067 hides a 2 mm rounded arris, a case that once
made this test's own check of the nominal cell fail); ``DOORLOC_MODELCHECK_SEED=<seed>`` replays another draw
and ``DOORLOC_MODELCHECK_SEED=random`` draws a fresh one. ``bench/bench_modelcheck.py`` covers many draws.
"""

from __future__ import annotations

import json
import os
import secrets

import numpy as np
import pytest
from typer.testing import CliRunner

from doorloc.app.cli import app
from doorloc.cell import load_cell
from doorloc.modelcheck import check_model
from doorloc.modelcheck.dataset import read_dataset, too_few_located
from doorloc.modelcheck.forward import door_for
from doorloc.modelcheck.synth import SetSpec, draw_hidden_effect, render_measured_set
from doorloc.vision.imageio import read_image
from doorloc.vision.locate import locate

SPEC_FIELDS = {
    "causes",
    "parameters",
    "heldout_rms_before",
    "heldout_rms_after",
    "heldout_images",
    "extended_cell",
    "alternatives",
}


@pytest.fixture(scope="module")
def nominal(thesis_cell_path):
    return load_cell(thesis_cell_path)


@pytest.fixture(scope="module")
def hidden_seed() -> int:
    env = os.environ.get("DOORLOC_MODELCHECK_SEED", "900067")
    seed = secrets.randbelow(1_000_000) if env == "random" else int(env)
    print(f"\nhidden-effect seed: {seed} (replay with DOORLOC_MODELCHECK_SEED={seed})")
    return seed


def _heldout_errors(dataset_dir, cell, images) -> dict[str, np.ndarray | None]:
    """Per held-out image, the (x, z, yaw) error located with ``cell`` the way production would; None if refused."""
    ds = read_dataset(dataset_dir, cell)
    errs: dict[str, np.ndarray | None] = {}
    for it in ds.images:
        if it.image not in images:
            continue
        door = door_for(it, cell, measured_arris=False)
        r = locate(read_image(it.path), cell, door)
        errs[it.image] = (
            np.array(
                [r.x_mm - it.reference.x_mm, r.z_mm - it.reference.z_mm, r.yaw_deg - it.reference.yaw_deg]
            )
            if r.ok
            else None
        )
    return errs


def _rms(errs: dict[str, np.ndarray | None], images) -> np.ndarray:
    return np.sqrt(np.mean(np.square([errs[i] for i in images]), axis=0))


def test_hidden_effect_is_named_and_the_extended_cell_fixes_it(
    tmp_path_factory, nominal, thesis_cell_path, hidden_seed
):
    rng = np.random.default_rng(hidden_seed)
    name, values = draw_hidden_effect(rng)
    print(f"hidden effect: {name} = {values}")
    data = tmp_path_factory.mktemp("hidden")
    render_measured_set(data, nominal, {name: values}, SetSpec(n_images=40, seed=hidden_seed))
    out = tmp_path_factory.mktemp("report")
    res = CliRunner().invoke(
        app, ["check-model", str(data), "--cell", str(thesis_cell_path), "--out", str(out)]
    )
    assert res.exit_code == 0, res.output
    rep = json.loads((out / "report.json").read_text())
    assert SPEC_FIELDS <= set(rep)
    print(f"named: {rep['causes']}, gain {rep['heldout_gain']} (None: a held-out image refused)")
    # The right name first (the cause that explains most); with today's locate an arris's fit can leave
    # enough behind for a second, smaller cause (the benchmark counts that as a miss).
    assert rep["causes"] and rep["causes"][0] == name, (
        f"hidden {name} = {values}, named {rep['causes']} (seed {hidden_seed})"
    )
    assert len(rep["causes"]) == 1 or name == "arris", rep["causes"]
    # A 5x gain on the held-out poses, unless the nominal cell's poses are already within the images'
    # noise: locate measures a camera response on plain edges and absorbs it per image, so a hidden
    # response_gamma can leave nothing to gain (seed 971731: gamma 2.16 named, fitted 2.14 +- 0.006, held-out
    # lever 0.0073 -> 0.0066 mm against a noise of 0.011 mm). Then the extended cell must not be worse.
    # Where the extended cell brings them down to the noise, the noise caps the gain: 2x at least then
    # (seed 2038: response 2.39, which locate measured on 37 of 40 images; held-out x 0.027 -> 0.002 mm and
    # z 0.026 -> 0.001 mm, but the lever's yaw part stays at its noise: 4.0x).
    noise = float(np.hypot(rep["noise"]["x_mm"], rep["noise"]["z_mm"]))
    already_at_noise = rep["heldout_rms_before"]["lever_mm"] <= noise
    at_noise_after = rep["heldout_rms_after"]["lever_mm"] <= noise
    if already_at_noise:
        assert name == "response_gamma", "only a response is absorbed by locate itself"
        assert rep["heldout_rms_after"]["lever_mm"] <= rep["heldout_rms_before"]["lever_mm"] * 1.05
    else:
        assert rep["heldout_gain"] >= (2.0 if at_noise_after else 5.0), (rep["heldout_gain"], hidden_seed)
    assert name in rep["parameters"]
    assert not set(rep["heldout_images"]) & set(rep["train_images"])
    # The gain is real only if production uses it: the extended cell file, loaded like any cell file.
    ext = load_cell(out / rep["extended_cell"])
    assert ext.provenance["model_check"]["causes"] == rep["causes"]
    before_errs = _heldout_errors(data, nominal, rep["heldout_images"])
    after_errs = _heldout_errors(data, ext, rep["heldout_images"])
    # The extended cell answers every held-out image. The nominal cell may refuse some: a large hidden
    # effect (a 2 mm rounded arris the cell does not know) makes a door read thinner than its recipe, and
    # refusing it is the nominal cell's right answer. Its errors are compared where it did answer.
    assert all(e is not None for e in after_errs.values()), [i for i, e in after_errs.items() if e is None]
    both = [i for i, e in before_errs.items() if e is not None]
    if both:
        before, after = _rms(before_errs, both), _rms(after_errs, both)
        lever = lambda e: float(np.hypot(np.hypot(e[0], e[1]), 1000 * np.radians(e[2])))  # noqa: E731
        need = 1 if already_at_noise else (2 if at_noise_after else 5)
        assert lever(after) * need <= lever(before) * (1.05 if already_at_noise else 1), (
            before,
            after,
        )
    for p in ("residuals.png", "edge_residuals.png", "heldout.png", "report.md"):
        assert (out / p).is_file()
    # and the command line reads it like any cell file
    item = next(it for it in read_dataset(data, nominal).images if it.image == rep["heldout_images"][0])
    res = CliRunner().invoke(
        app,
        [
            "locate",
            str(item.path),
            "--cell",
            str(out / rep["extended_cell"]),
            "--door-width",
            str(item.door.width_mm),
            "--door-thickness",
            str(item.door.thickness_mm),
        ],
    )
    assert res.exit_code == 0, res.output
    got = json.loads(res.output)
    assert got["provenance"]["cell_sha256"] == ext.sha256


def test_control_without_effect_answers_no_cause(tmp_path_factory, nominal):
    data = tmp_path_factory.mktemp("control")
    render_measured_set(data, nominal, {}, SetSpec(n_images=40, seed=11))
    out = tmp_path_factory.mktemp("control_report")
    rep = check_model(data, nominal, out)
    assert rep.causes == [], rep.selection_steps
    assert rep.heldout_rms_after == rep.heldout_rms_before
    assert load_cell(out / "cell_extended.yaml").provenance["model_check"]["causes"] == []


def test_bad_data_sets_exit_2_with_a_sentence(tmp_path, thesis_cell_path, nominal):
    runner = CliRunner()
    args = ["--cell", str(thesis_cell_path), "--out", str(tmp_path / "rep")]
    empty = tmp_path / "empty"
    empty.mkdir()
    r = runner.invoke(app, ["check-model", str(empty), *args])
    assert r.exit_code == 2 and "truth.csv" in r.output
    few = tmp_path / "few"
    render_measured_set(few, nominal, {}, SetSpec(n_images=3, seed=1))
    r = runner.invoke(app, ["check-model", str(few), *args])
    assert r.exit_code == 2 and "at least" in r.output
    (few / "img_001.png").unlink()
    r = runner.invoke(app, ["check-model", str(few), *args])
    assert r.exit_code == 2 and "img_001.png" in r.output
    (few / "truth.csv").write_text("image,x_mm\nimg_000.png,1\n")
    r = runner.invoke(app, ["check-model", str(few), *args])
    assert r.exit_code == 2 and "lacks column" in r.output
    assert not (tmp_path / "rep" / "report.json").exists()


def test_images_refused_for_their_exposure_ask_for_new_images_not_a_new_cell(
    tmp_path, thesis_cell_path, nominal
):
    # a light that clips the hinge face on every image: locate refuses them all `overexposed` whatever the
    # cell; the message once blamed the cell ("check the camera and extrinsics first")
    from dataclasses import replace

    from doorloc.modelcheck.synth import MEASURED_PHOTOMETRY

    glare = replace(MEASURED_PHOTOMETRY, albedo_hinge=1.0, light_directional=0.4, light_azimuth_deg=0.0)
    render_measured_set(tmp_path / "data", nominal, {}, SetSpec(n_images=15, seed=3, photometry=glare))
    out = tmp_path / "rep"
    r = CliRunner().invoke(
        app, ["check-model", str(tmp_path / "data"), "--cell", str(thesis_cell_path), "--out", str(out)]
    )
    assert r.exit_code == 2, r.output
    assert "overexposed 15" in r.output and "retake" in r.output, r.output
    assert "extrinsics" not in r.output
    assert not (out / "report.json").exists()


def test_a_data_set_refused_on_its_geometry_points_at_the_cell():
    refusals = ["edge_missing: no hinge-face edge", "overexposed: the hinge face clips", "edge_missing: none"]
    msg = str(too_few_located(0, 3, refusals))
    assert "refused: edge_missing 2, overexposed 1" in msg
    assert "check the camera and extrinsics" in msg and "retake" not in msg


def test_an_effect_outside_the_catalogue_is_unexplained(tmp_path_factory, nominal):
    # a decentred lens (tangential distortion p1, p2): no catalogue entry makes its signature
    from dataclasses import replace

    from doorloc.calib.camera import CameraModel

    cam = nominal.camera
    true = replace(
        nominal, camera=CameraModel(cam.camera_matrix, np.array([0, 0, 0.004, -0.003, 0.0]), cam.image_size)
    )
    data = tmp_path_factory.mktemp("tangential")
    render_measured_set(data, true, {}, SetSpec(n_images=30, seed=5))
    rep = check_model(data, nominal, tmp_path_factory.mktemp("tangential_report"))
    assert rep.causes == ["unexplained"], rep.selection_steps
    assert rep.unexplained_test["structured"]


def test_an_arris_cell_carries_the_response_the_training_poses_allow(tmp_path_factory, nominal):
    # With the arris in the cell no edge can show the camera response, and the nominal cell never measured
    # it: without a bound from the data the extended cell doubted it over the default factor 2.2 and refused
    # its own held-out images `uncertain` (seed 1004: hidden 0.96 mm arris, 0.14-0.15 mm doubt).
    rng = np.random.default_rng(1004)
    name, values = draw_hidden_effect(rng)
    assert name == "arris"
    data = tmp_path_factory.mktemp("arris_response")
    render_measured_set(data, nominal, {name: values}, SetSpec(n_images=40, seed=1004))
    out = tmp_path_factory.mktemp("arris_response_report")
    rep = check_model(data, nominal, out)
    assert rep.causes[0] == "arris"
    bound = rep.response_bound
    assert bound["written"] and bound["source"] == "relocation"
    assert abs(bound["gamma"] - nominal.response_gamma) <= 2 * bound["sigma"]  # the renders' true response
    ext = load_cell(out / "cell_extended.yaml")
    assert ext.locate.response_unmeasured_factor == pytest.approx(bound["factor"], abs=1e-4)
    assert ext.locate.response_unmeasured_factor < nominal.locate.response_unmeasured_factor
    assert ext.response_gamma_sigma is not None and ext.response_gamma_sigma >= bound["sigma"]
    assert ext.provenance["model_check"]["response_bound"]["factor"] == bound["factor"]
    assert rep.heldout_refused_after == [] and rep.heldout_gain >= 5, (rep.heldout_gain, bound)


def test_a_bending_effect_is_refined_on_the_relocated_images(tmp_path_factory, nominal):
    # Radial distortion bends the edges; the analytic forward model's straight-line fit weighs the bend
    # otherwise than locate's robust fit, and fitted k1 0.171 +- 0.002 for a hidden 0.199 (benchmark seed
    # 13: held-out gain 6.6x). Refined on the training images located again, the value is the hidden one.
    k1 = 0.18
    data = tmp_path_factory.mktemp("radial")
    render_measured_set(data, nominal, {"radial_distortion": [k1]}, SetSpec(n_images=30, seed=13))
    rep = check_model(data, nominal, tmp_path_factory.mktemp("radial_report"))
    assert rep.causes == ["radial_distortion"], rep.selection_steps
    fit = rep.parameters["radial_distortion"]["k1"]
    refined = rep.refined_by_relocation
    assert refined["steps"] >= 1 and refined["cost_after"] < refined["cost_before"]
    analytic = refined["values"]["radial_distortion"]["analytic"][0]
    assert abs(fit["value"] - k1) < abs(analytic - k1) / 3, (fit, analytic)
    assert abs(fit["value"] - k1) <= max(3 * fit["sigma"], 0.002), fit
    assert rep.heldout_refused_after == [] and rep.heldout_gain >= 20, rep.heldout_gain
