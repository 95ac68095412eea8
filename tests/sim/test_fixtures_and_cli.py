"""The committed rendered fixtures still mean what they say; `doorloc render` writes a complete set.

The fixtures were rendered with OpenCV 4.x (fixtures/rendered/REGENERATE.md); the lock installs 5.x,
whose resampling rounds a few pixels differently. So a re-render is compared by what matters: every
pixel within a small grey-level difference, and the same pose when the pipeline locates both images.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from doorloc.app.cli import app
from doorloc.cell import load_cell
from doorloc.sim.dataset import grid_poses, read_truth_csv
from doorloc.sim.door import render_door, true_corner_px
from doorloc.vision.locate import locate

ROOT = Path(__file__).parents[2]
FIX = ROOT / "fixtures" / "rendered"


#: a re-render may differ from the stored image by this many grey levels (8-bit) at any pixel
MAX_GREY_LEVEL_DIFF = 2
#: the poses located in the stored and the re-rendered image agree this closely (mm, deg)
SAME_POSE_MM, SAME_POSE_DEG = 0.002, 0.0005
#: and the re-rendered image still shows the door where its truth row says (mm, deg): the images exist
#: to test locate to hundredths of a millimetre, far inside the 0.5 mm milling tolerance
TRUTH_POSE_MM, TRUTH_POSE_DEG = 0.1, 0.01


# (effects 12, not 13: under the committed cell, whose response_gamma is not the camera's, every third
# effects frame is refused as uncertain by the unmeasured response's doubt, 13 among them; this test needs
# an answer to compare)
@pytest.mark.parametrize(
    "folder,index", [("grid", 0), ("grid", 80), ("effects", 12), ("distractors", 3), ("widths", 2)]
)
def test_fixture_images_rerender_within_two_grey_levels_and_locate_the_same(folder, index):
    cell = load_cell(FIX / folder / "cell.yaml")
    rows = read_truth_csv(FIX / folder / "truth.csv")
    r = rows[index]
    rd = render_door(cell, r.door, r.pose, effects=r.effects, seed=r.seed)
    stored = cv2.imread(str(FIX / folder / r.image), cv2.IMREAD_UNCHANGED)
    assert stored.shape == rd.image.shape == (1080, 1920)
    assert stored.dtype == rd.image.dtype == np.uint8
    diff = np.abs(stored.astype(np.int16) - rd.image.astype(np.int16))
    assert diff.max() <= MAX_GREY_LEVEL_DIFF, (
        f"{int((diff > MAX_GREY_LEVEL_DIFF).sum())} pixels differ by more"
    )
    assert np.allclose(r.corner_px, true_corner_px(cell, r.door, r.pose), atol=1e-9)

    from_stored = locate(stored, cell, r.door)
    from_rerender = locate(rd.image, cell, r.door)
    assert from_stored.ok and from_rerender.ok, (from_stored.error, from_rerender.error)
    assert from_rerender.x_mm == pytest.approx(from_stored.x_mm, abs=SAME_POSE_MM)
    assert from_rerender.z_mm == pytest.approx(from_stored.z_mm, abs=SAME_POSE_MM)
    assert from_rerender.yaw_deg == pytest.approx(from_stored.yaw_deg, abs=SAME_POSE_DEG)
    assert from_rerender.x_mm == pytest.approx(r.pose.x_mm, abs=TRUTH_POSE_MM)
    assert from_rerender.z_mm == pytest.approx(r.pose.z_mm, abs=TRUTH_POSE_MM)
    assert from_rerender.yaw_deg == pytest.approx(r.pose.yaw_deg, abs=TRUTH_POSE_DEG)


def test_grid_fixture_covers_the_envelope_corners_and_thicknesses():
    rows = read_truth_csv(FIX / "grid" / "truth.csv")
    poses = {(r.pose.x_mm, r.pose.z_mm, r.pose.yaw_deg) for r in rows}
    assert poses == {
        (p.x_mm, p.z_mm, p.yaw_deg) for p in grid_poses(load_cell(FIX / "grid" / "cell.yaml").envelope)
    }
    assert {r.door.thickness_mm for r in rows} == {30.0, 50.0, 100.0}
    assert sum(f.stat().st_size for f in FIX.rglob("*")) < 4_000_000


def test_cli_render_writes_images_truth_and_cell(tmp_path):
    out = tmp_path / "set"
    res = CliRunner().invoke(
        app,
        [
            "render",
            str(out),
            "--cell",
            str(ROOT / "fixtures" / "cell_thesis.yaml"),
            "--poses",
            "random",
            "--count",
            "2",
            "--seed",
            "5",
            "--thickness",
            "35,60",
            "--effect",
            "blur_sigma_px=0.5",
            "--effect",
            "gamma=2.2",
        ],
    )
    assert res.exit_code == 0, res.output
    rows = read_truth_csv(out / "truth.csv")
    assert [r.image for r in rows] == [f"img_{k:04d}.png" for k in range(4)]
    assert [r.door.thickness_mm for r in rows] == [35.0, 35.0, 60.0, 60.0]
    assert rows[0].effects.blur_sigma_px == 0.5
    assert all((out / r.image).is_file() for r in rows)
    cell = load_cell(out / "cell.yaml")
    assert np.allclose(rows[1].corner_px, true_corner_px(cell, rows[1].door, rows[1].pose))
    # the cell it writes describes the rendered camera (it used to say 1.0 whatever the response)
    assert rows[0].effects.gamma == 2.2 and cell.response_gamma == 2.2
    # a second run into the same folder is refused without --force and leaves the set alone
    before = (out / "truth.csv").read_bytes()
    res = CliRunner().invoke(app, ["render", str(out), "--cell", str(ROOT / "fixtures" / "cell_thesis.yaml")])
    assert res.exit_code == 2 and "already holds" in res.output
    assert (out / "truth.csv").read_bytes() == before


@pytest.mark.parametrize(
    "args,message",
    [
        (["--effect", "gamma=abc"], "gamma"),
        (["--effect", "nope=1"], "unknown effect"),
        (["--thickness", "thick"], "--thickness"),
        (["--poses", "spiral"], "--poses"),
        (["--thickness", "0"], "thickness_mm"),
    ],
)
def test_cli_render_bad_arguments_are_refused_with_a_sentence(tmp_path, args, message):
    out = tmp_path / "set"
    res = CliRunner().invoke(
        app, ["render", str(out), "--cell", str(ROOT / "fixtures" / "cell_thesis.yaml"), *args]
    )
    assert res.exit_code == 2
    assert message in res.output
    assert not (out / "truth.csv").exists()
