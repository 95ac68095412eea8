"""RAPID exports: single-precision numbers, 80-character lines that parse back, a golden module."""

from __future__ import annotations

import importlib.util
import os
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from doorloc.pose import DoorPose
from doorloc.recipes.importer import load_recipe_file
from doorloc.recipes.rapid import (
    RAPID_LINE_MAX,
    RobotSetup,
    parse_rapid_text,
    rapid_module,
    rapid_num,
    rapid_text,
    robot_setup_from_cell_file,
)
from doorloc.recipes.targets import Target, targets_for_pose

_spec = importlib.util.spec_from_file_location(
    "hinge_strategies", Path(__file__).with_name("hinge_strategies.py")
)
strategies = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(strategies)
_spec = importlib.util.spec_from_file_location(
    "golden_compare", Path(__file__).with_name("golden_compare.py")
)
golden_compare = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(golden_compare)

GOLDEN = Path(__file__).with_name("golden")
GOLDEN_POSE = DoorPose(1.25, -3.5, 0.8)
NUM = re.compile(r"^-?\d+(\.\d+)?$")


@pytest.mark.parametrize(
    ("value", "text"),
    [
        (0.0, "0"),
        (-0.0, "0"),
        (25.0, "25"),
        (1234.56789, "1234.568"),
        (-0.0174524064, "-0.01745241"),
        (3010.1234, "3010.123"),
        (1e-9, "0.000000001"),
        (-1.5, "-1.5"),
        (9999999.4, "9999999"),
    ],
)
def test_rapid_num(value, text):
    assert rapid_num(value) == text


@given(st.floats(-1e6, 1e6, allow_nan=False))
def test_rapid_num_is_plain_decimal_with_7_significant_digits(v):
    s = rapid_num(v)
    assert NUM.match(s), s
    assert len(s.replace("-", "").replace(".", "").lstrip("0")) <= 7
    assert abs(float(s) - v) <= 5e-7 * abs(v) + 5e-10


def test_rapid_num_refuses_nan():
    with pytest.raises(ValueError):
        rapid_num(float("nan"))


@settings(max_examples=200, deadline=None)
@given(
    strategies.recipes(),
    st.builds(DoorPose, x_mm=st.floats(-10, 10), z_mm=st.floats(-10, 10), yaw_deg=st.floats(-2, 2)),
    st.floats(-400.0, 400.0),
)
def test_text_lines_fit_80_chars_and_parse_back(recipe, pose, face_y):
    targets = targets_for_pose(recipe, pose, face_y)
    text = rapid_text(targets)
    lines = text.splitlines()
    assert lines[0] == str(len(targets))
    assert all(len(ln) <= RAPID_LINE_MAX for ln in lines)
    assert all(NUM.match(f) for ln in lines[1:] for f in ln.split(";")[1:])  # '.' decimals, no exponent
    back = parse_rapid_text(text)
    assert [b.name for b in back] == [t.name for t in targets]
    assert [b.hinge for b in back] == [t.hinge for t in targets]
    for b, t in zip(back, targets, strict=True):
        assert max(abs(b.x_mm - t.x_mm), abs(b.y_mm - t.y_mm), abs(b.z_mm - t.z_mm)) <= 0.001
        np.testing.assert_allclose(b.quat, t.quat, atol=1e-7)


def test_text_refuses_a_line_over_80_characters():
    t = Target(
        name="H1_" + "X" * 29,
        x_mm=-1234.5678,
        y_mm=-1234.5678,
        z_mm=-1234.5678,
        quat=(0.1234567, -0.01234567, -0.01234567, -0.01234567),
        hinge=1,
    )
    with pytest.raises(ValueError, match="longer than 80"):
        rapid_text([t])


def test_text_refuses_names_rapid_cannot_hold():
    t = Target(name="1bad name", x_mm=0, y_mm=0, z_mm=0, quat=(1, 0, 0, 0), hinge=1)
    with pytest.raises(ValueError, match="not a RAPID identifier"):
        rapid_text([t])


def test_module_structure(recipe_factory):
    r = recipe_factory(door_id="AB-12/3")
    ts = targets_for_pose(r, DoorPose(0.5, 0.5, -1.0), 12.0)
    mod = rapid_module(r, ts)
    lines = mod.splitlines()
    assert lines[0] == "MODULE Door_AB_12_3" and lines[-1] == "ENDMODULE"
    decl = [ln for ln in lines if ln.strip().startswith("CONST robtarget")]
    moves = [ln.strip() for ln in lines if ln.strip().startswith("MoveL")]
    assert len(decl) == len(moves) == len(ts)
    assert all(ln.endswith(",[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];") for ln in decl)
    assert "CONST speeddata vMill:=[25,500,5000,1000];" in mod
    # fine where the tool stops: pocket corners, the end of each plunge and the retract; z0 along edges
    zones = {m.split(",")[0].removeprefix("MoveL "): m.split(",")[2] for m in moves}
    assert zones["H1_APP"] == "z5" and zones["H1_P1"] == "fine" and zones["H1_P6"] == "z0"
    assert all(zones[f"H1_P{k}"] == "fine" for k in range(2, 6))
    assert all(zones[f"H2_P{k}"] == "fine" for k in range(1, 10))
    assert zones["H2_RET"] == "fine"


def test_robot_setup_from_cell_file(tmp_path):
    cell = tmp_path / "cell.yaml"
    cell.write_text("fixture: {face_y_mm: 0}\nrobot:\n  tool_name: tRouter\n  tool_tcp_mm: [0, 10, 300]\n")
    robot = robot_setup_from_cell_file(cell)
    assert robot.tool_name == "tRouter" and robot.tool_tcp_mm == (0.0, 10.0, 300.0)
    assert robot.wobj_name == RobotSetup().wobj_name
    assert robot.tool_rot == pytest.approx((0.7071068, 0.7071068, 0, 0)) and robot.spindle_axis == "y"
    cell.write_text("robot:\n  spindle_axis: z\n")
    robot = robot_setup_from_cell_file(cell)
    assert robot.tool_rot == (1.0, 0.0, 0.0, 0.0) and robot.base_orientation() == pytest.approx(
        (0.7071068, -0.7071068, 0, 0)
    )
    cell.write_text("robot:\n  tool_name: 'bad name'\n")
    with pytest.raises(ValueError):
        robot_setup_from_cell_file(cell)


def test_golden_rapid_files():
    (recipe,) = load_recipe_file(GOLDEN / "golden_recipe.csv")
    targets = targets_for_pose(recipe, GOLDEN_POSE, 0.0)
    produced = {
        "GOLDEN-1.mod": rapid_module(recipe, targets, RobotSetup(), pose=GOLDEN_POSE, face_y_mm=0.0),
        "GOLDEN-1.txt": rapid_text(targets),
    }
    if os.environ.get("DOORLOC_UPDATE_GOLDEN") == "1":
        for name, text in produced.items():
            (GOLDEN / name).write_text(text, encoding="utf-8")
    for name, text in produced.items():
        golden_compare.assert_same_values((GOLDEN / name).read_text(encoding="utf-8"), text, name)


def test_golden_comparison_catches_a_moved_target_and_a_changed_word():
    golden = (GOLDEN / "GOLDEN-1.txt").read_text(encoding="utf-8")
    golden_compare.assert_same_values(
        golden, golden.replace("22.64532", "22.64533"), "last digit"
    )  # 4e-7 relative
    with pytest.raises(AssertionError):
        golden_compare.assert_same_values(golden, golden.replace("22.64532", "22.64632"), "moved 1 um")
    with pytest.raises(AssertionError):
        golden_compare.assert_same_values(golden, golden.replace("H1_APP", "H1_APX"), "renamed")
