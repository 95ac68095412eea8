"""`doorloc reach`: exit codes, JSON fields (SPEC section 9), table and the work-window PNG."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import pytest
from typer.testing import CliRunner

from doorloc.app.cli import app

REPO = Path(__file__).resolve().parents[2]
RUNNER = CliRunner()


@pytest.fixture(scope="module")
def db(tmp_path_factory) -> str:
    url = f"sqlite:///{tmp_path_factory.mktemp('db') / 'r.db'}"
    r = RUNNER.invoke(
        app, ["recipes", "import", str(REPO / "fixtures" / "recipes" / "thesis_extremes.csv"), "--db", url]
    )
    assert r.exit_code == 0, r.output
    return url


def _reach(db: str, *args: str):
    return RUNNER.invoke(app, ["reach", "--db", db, *args])


def test_feasible_door_exits_0_with_the_spec_fields(db, tmp_path):
    png = tmp_path / "window.png"
    r = _reach(db, "--door-id", "THESIS-1350", "--pose", "-10", "10", "2", "--plot", str(png))
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout)
    assert {"robot", "tool", "feasible", "reason", "targets"} <= set(out)
    assert out["robot"] == "IRB6600-175/2.55" and out["feasible"] is True and out["reason"] is None
    assert set(out["tool"]) == {"pos_mm", "quat"} and len(out["tool"]["quat"]) == 4
    t = out["targets"][0]
    assert {
        "name",
        "joints_deg",
        "confdata",
        "tcp_base_mm",
        "quat_base",
        "feasible",
        "reason",
        "inv_condition",
        "deflection_mm",
    } <= set(t)
    assert len(t["joints_deg"]) == 6 and len(t["confdata"]) == 4 and len(t["tcp_base_mm"]) == 3
    assert len(t["quat_base"]) == 4 and len(t["deflection_mm"]) == 3
    img = cv2.imread(str(png))
    assert img is not None and img.shape[0] > 400 and img.shape[1] > 400


def test_infeasible_door_exits_1_and_says_which_target(db):
    r = _reach(db, "--door-id", "THESIS-190", "--pose", "500", "0", "0", "--format", "table")
    assert r.exit_code == 1
    assert "NOT feasible: unreachable: target H2_APP" in r.stdout
    r = _reach(db, "--door-id", "THESIS-190", "--pose", "500", "0", "0")
    assert r.exit_code == 1 and json.loads(r.stdout)["error_code"] == "unreachable"


def test_bad_input_exits_2(db, tmp_path):
    r = _reach(db, "--door-id", "NOPE", "--pose", "0", "0", "0")
    assert r.exit_code == 2 and "no recipe for door 'NOPE'" in r.output
    cell = tmp_path / "cell.yaml"
    text = (
        (REPO / "fixtures" / "cell_thesis.yaml").read_text().replace("  model: irb6600", "  modle: irb6600")
    )
    cell.write_text(text)
    r = _reach(db, "--door-id", "THESIS-190", "--pose", "0", "0", "0", "--cell", str(cell))
    assert r.exit_code == 2 and "unknown key 'robot.modle'" in r.output
    cell.write_text(text.replace("  modle: irb6600-175-2.55", "  model: irb9999"))
    r = _reach(db, "--door-id", "THESIS-190", "--pose", "0", "0", "0", "--cell", str(cell))
    assert r.exit_code == 2 and "unknown robot 'irb9999'" in r.output
    r = _reach(db, "--door-id", "THESIS-190", "--pose", "0", "0")
    assert r.exit_code == 2


def test_reach_says_which_cell_and_robot_it_used(db, tmp_path):
    r = _reach(db, "--door-id", "THESIS-1350", "--pose", "-10,10,2")  # one word, as people paste a pose
    assert r.exit_code == 0, r.output
    assert "the bundled thesis cell" in r.stderr and "irb6600-175-2.55" in r.stderr and "--cell" in r.stderr
    assert json.loads(r.stdout)["feasible"] is True
    cell = tmp_path / "cell.yaml"
    cell.write_text((REPO / "fixtures" / "cell_thesis.yaml").read_text())
    r = _reach(db, "--door-id", "THESIS-1350", "--pose", "-10", "10", "2", "--cell", str(cell))
    assert r.exit_code == 0 and f"cell {cell}" in r.stderr and "bundled" not in r.stderr


def test_a_cell_without_a_robot_section_is_named_as_such(db, tmp_path):
    import yaml

    doc = yaml.safe_load((REPO / "fixtures" / "cell_thesis.yaml").read_text())
    doc.pop("robot")
    cell = tmp_path / "cell.yaml"
    cell.write_text(yaml.safe_dump(doc))
    r = _reach(db, "--door-id", "THESIS-190", "--pose", "0", "0", "0", "--cell", str(cell))
    assert r.exit_code == 2 and "has no robot: section" in r.stderr and "model:" in r.stderr
