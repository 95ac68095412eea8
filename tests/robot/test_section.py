"""The cell file's robot: section: one strict model for the SPEC keys and the RAPID keys."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from doorloc.cell import CellFileError, load_cell, parse_cell
from doorloc.recipes.rapid import RobotSetup, rapid_module
from doorloc.robot.section import Placement, RobotSection, RobotSectionError, robot_section_from_doc

REPO = Path(__file__).resolve().parents[2]
THESIS = yaml.safe_load((REPO / "fixtures" / "cell_thesis.yaml").read_text())


def _cell_with(robot) -> dict:
    doc = dict(THESIS)
    doc["robot"] = robot
    return doc


def test_rapid_setup_is_the_robot_section():
    assert RobotSetup is RobotSection


@pytest.mark.parametrize(
    "robot, key",
    [
        ({"modle": "irb6600-175-2.55"}, "robot.modle"),
        ({"base": {"pos": [0, 0, 0]}}, "robot.base.pos"),
        ({"tool": {"pos_mm": [0, 0, 250], "rot": [1, 0, 0, 0]}}, "robot.tool.rot"),
    ],
)
def test_a_typo_in_robot_is_a_cell_file_error_naming_the_key(robot, key):
    with pytest.raises(CellFileError, match=f"unknown key '{key}'"):
        parse_cell(_cell_with(robot), REPO / "fixtures")


def test_bad_values_are_named():
    with pytest.raises(CellFileError, match="robot.base.quat.*unit quaternion"):
        parse_cell(_cell_with({"base": {"pos_mm": [0, 0, 0], "quat": [1, 1, 0, 0]}}), REPO / "fixtures")
    with pytest.raises(CellFileError, match="give the tool once"):
        parse_cell(_cell_with({"tool": {"pos_mm": [0, 0, 1]}, "tool_tcp_mm": [0, 0, 1]}), REPO / "fixtures")
    with pytest.raises(RobotSectionError, match="must be a mapping"):
        robot_section_from_doc([1, 2], "c.yaml")


def test_tool_is_rapid_tframe_and_base_fixes_the_work_object():
    s = robot_section_from_doc(THESIS["robot"])
    assert s.tool_tcp_mm == (-100.0, 0.0, 250.0) and s.tool_rot == (0.5, 0.5, -0.5, 0.5)
    # cell origin seen from the base: the inverse of the base placement
    assert s.wobj_uframe_mm == pytest.approx((1550.0, 35.0, -150.0)) and s.wobj_uframe_rot == pytest.approx(
        (1, 0, 0, 0)
    )
    mod = rapid_module(_recipe(), [], s)
    assert "PERS tooldata tSpindle:=[TRUE,[[-100,0,250],[0.5,0.5,-0.5,0.5]]" in mod
    assert "[[1550,35,-150],[1,0,0,0]]" in mod


def test_older_keys_still_spell_the_tool_and_the_work_object():
    s = robot_section_from_doc({"tool_tcp_mm": [0, 10, 300], "wobj_uframe_mm": [100, 0, 0]})
    assert s.tool == Placement(pos_mm=(0, 10, 300), quat=s.tool_rot)
    assert s.base.pos_mm == pytest.approx((-100, 0, 0)) and s.model is None
    with pytest.raises(RobotSectionError, match="disagree"):
        robot_section_from_doc({"base": {"pos_mm": [-1550, -35, 150]}, "wobj_uframe_mm": [0, 0, 0]})
    same = robot_section_from_doc({"base": {"pos_mm": [-1550, -35, 150]}, "wobj_uframe_mm": [1550, 35, -150]})
    assert same.base.pos_mm == (-1550, -35, 150)


def test_thesis_cell_names_the_irb6600():
    cell = load_cell(REPO / "fixtures" / "cell_thesis.yaml")
    s = robot_section_from_doc(cell.robot_section)
    assert s.model == "irb6600-175-2.55" and s.base.quat == (1.0, 0.0, 0.0, 0.0)


def _recipe():
    from doorloc.recipes.models import DoorRecipe, Hinge

    return DoorRecipe(
        door_id="D-1",
        width_mm=900,
        height_mm=2100,
        thickness_mm=50,
        hinges=[Hinge(z_mm=250, length_mm=100, width_mm=30, x_mm=10, depth_mm=3, corner_radius_mm=8)],
        tool_diameter_mm=16,
        spindle_rpm=18000,
        feed_mm_s=25,
    )
