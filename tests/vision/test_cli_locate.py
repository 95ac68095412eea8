"""`doorloc locate`: JSON on stdout, exit 0 located / 1 refused / 2 bad input, overlay written atomically."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from doorloc.app.cli import app
from doorloc.cell import DoorSize, load_cell
from doorloc.pose import DoorPose
from doorloc.sim.door import render_door
from doorloc.vision.imageio import ImageDecodeError, decode_image, read_image


@pytest.fixture(scope="module")
def door_png(tmp_path_factory, thesis_cell_path):
    cell = load_cell(thesis_cell_path)
    img = render_door(cell, DoorSize(900, 50, 2100), DoorPose(2.0, -1.0, 0.4)).image
    p = tmp_path_factory.mktemp("img") / "door.png"
    cv2.imwrite(str(p), img)
    return p


def test_locate_prints_result_and_writes_overlay(door_png, thesis_cell_path, tmp_path):
    out = tmp_path / "sub" / "overlay.png"
    r = CliRunner().invoke(
        app,
        [
            "locate",
            str(door_png),
            "--cell",
            str(thesis_cell_path),
            "--door-thickness",
            "50",
            "--overlay",
            str(out),
        ],
    )
    assert r.exit_code == 0, r.output
    res = json.loads(r.stdout)
    assert res["ok"] is True and res["image"] == str(door_png)
    assert (
        abs(res["x_mm"] - 2.0) < 0.005
        and abs(res["z_mm"] + 1.0) < 0.005
        and abs(res["yaw_deg"] - 0.4) < 0.002
    )
    for key in ("thickness_mm", "scale_mm_per_px", "corner_px", "error", "elapsed_ms", "lines"):
        assert key in res
    ov = cv2.imread(str(out))
    assert ov is not None and ov.shape == (1080, 1920, 3)
    assert not list(out.parent.glob(".overlay.png.*"))  # no temporary file left behind


def test_refusal_exits_1_with_reason(door_png, thesis_cell_path):
    r = CliRunner().invoke(
        app, ["locate", str(door_png), "--cell", str(thesis_cell_path), "--door-thickness", "70"]
    )
    assert r.exit_code == 1
    res = json.loads(r.stdout)
    assert res["ok"] is False and res["error_code"] == "thickness_mismatch" and res["x_mm"] is None


@pytest.mark.parametrize("case", ["missing", "garbage", "bad_cell", "bad_door"])
def test_bad_input_exits_2_with_one_sentence(case, door_png, thesis_cell_path, tmp_path):
    img, cell = str(door_png), str(thesis_cell_path)
    extra = []
    if case == "missing":
        img = str(tmp_path / "nope.png")
    elif case == "garbage":
        p = tmp_path / "x.png"
        p.write_bytes(b"not an image at all")
        img = str(p)
    elif case == "bad_cell":
        p = tmp_path / "cell.yaml"
        p.write_text("camera: {}\n")
        cell = str(p)
    else:
        extra = ["--door-thickness", "-5"]
    r = CliRunner().invoke(app, ["locate", img, "--cell", cell, *extra])
    assert r.exit_code == 2
    assert "doorloc: error:" in r.stderr and "Traceback" not in r.output


def test_imageio_decodes_and_refuses(door_png):
    img = read_image(door_png)
    assert img.shape == (1080, 1920) and img.dtype == np.uint8
    assert np.array_equal(decode_image(door_png.read_bytes()), img)
    with pytest.raises(ImageDecodeError, match="no image data"):
        decode_image(b"")
    with pytest.raises(ImageDecodeError, match="not a readable image"):
        decode_image(b"\x89PNG garbage")


def test_door_id_takes_the_size_from_the_recipe_store(door_png, thesis_cell_path, tmp_path):
    from doorloc.recipes.models import DoorRecipe, Hinge
    from doorloc.recipes.store import RecipeStore

    url = f"sqlite:///{tmp_path / 'recipes.db'}"
    hinge = Hinge(z_mm=250, length_mm=100, width_mm=30, x_mm=10, depth_mm=3.5, corner_radius_mm=8)
    with RecipeStore(url) as store:
        for door_id, thickness in (("D-50", 50.0), ("D-70", 70.0)):
            store.put(
                DoorRecipe(
                    door_id=door_id,
                    width_mm=900,
                    height_mm=2100,
                    thickness_mm=thickness,
                    arris_mm=0.0,
                    hinges=[hinge],
                    tool_diameter_mm=16,
                    spindle_rpm=18000,
                    feed_mm_s=25,
                )
            )
    base = ["locate", str(door_png), "--cell", str(thesis_cell_path), "--db", url]
    ok = CliRunner().invoke(app, [*base, "--door-id", "D-50"])
    assert ok.exit_code == 0, ok.output
    answer = json.loads(ok.stdout)
    # A named door gets its hinge targets, in the cell frame near the hinge's z, as the HTTP answer does.
    assert answer["door_id"] == "D-50" and answer["targets_note"] is None
    assert len(answer["targets"]) >= 6 and {t["hinge"] for t in answer["targets"]} == {1}
    assert all(240 < t["z_mm"] < 360 for t in answer["targets"])
    wrong = CliRunner().invoke(app, [*base, "--door-id", "D-70"])
    assert wrong.exit_code == 1 and json.loads(wrong.stdout)["error_code"] == "thickness_mismatch"
    assert json.loads(wrong.stdout)["targets"] == []
    unknown = CliRunner().invoke(app, [*base, "--door-id", "NOPE"])
    assert unknown.exit_code == 2 and "no door recipe" in unknown.stderr
