"""Reach check of whole doors with the bundled thesis cell, and each refusal reason."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from doorloc.cell import load_cell
from doorloc.pose import DoorPose
from doorloc.recipes.importer import load_recipe_file
from doorloc.recipes.models import PointCorrection
from doorloc.recipes.targets import Target, targets_for_pose
from doorloc.robot.deflection import (
    TABLE_4_8_WRENCH,
    compensation_cell,
    segment_of_points,
    tcp_deflection_mm,
)
from doorloc.robot.kinematics import Kinematics
from doorloc.robot.model import RobotModel, load_robot
from doorloc.robot.reach import (
    ReachSetup,
    check_reach,
    compensated_targets,
    inverse_condition,
    reach_for_door,
    setup_for_cell,
    thesis_cell_path,
)
from doorloc.robot.section import robot_section_from_doc

REPO = Path(__file__).resolve().parents[2]
CELL = load_cell(REPO / "fixtures" / "cell_thesis.yaml")
#: the thesis's extreme doors: widths 190 and 1350 mm, a hinge at the bottom and one at the top of Table 4.5
DOORS = load_recipe_file(REPO / "fixtures" / "recipes" / "thesis_extremes.csv")
ROBOT = load_robot()
KIN = Kinematics.of(ROBOT)
ANGLE_HEAD = [0.5, 0.5, -0.5, 0.5]  # cutter axis (tool +Y) along flange -X, tool +X along flange +Z


def _setup(**section) -> ReachSetup:
    return ReachSetup.of(ROBOT, robot_section_from_doc({"model": "irb6600-175-2.55", **section}))


def _reports(setup: ReachSetup, pose: DoorPose = DoorPose()) -> dict:
    return {r.door_id: reach_for_door(setup, r, pose, CELL.face_y(r.door_size())) for r in DOORS}


def test_bundled_cell_is_the_fixture_cell():
    assert load_cell(thesis_cell_path()).robot_section == CELL.robot_section


def test_thesis_extreme_doors_are_feasible_with_the_bundled_cell():
    setup = setup_for_cell(CELL)
    assert setup is not None
    for pose in (DoorPose(), DoorPose(10, 10, 2), DoorPose(-10, -10, -2)):  # the whole placement envelope
        for door_id, rep in _reports(setup, pose).items():
            assert rep.feasible, (door_id, pose, rep.reason)
            assert len(rep.targets) == 19 and all(t.feasible and t.reason is None for t in rep.targets)
            assert all(t.inv_condition >= ROBOT.min_inv_condition for t in rep.targets)
            for t in rep.targets:
                lo = np.array(ROBOT.joint_limits_deg)[:, 0] + ROBOT.joint_margin_deg
                hi = np.array(ROBOT.joint_limits_deg)[:, 1] - ROBOT.joint_margin_deg
                assert np.all((np.array(t.joints_deg) >= lo) & (np.array(t.joints_deg) <= hi))


def test_reported_joints_put_the_tcp_on_the_target():
    setup = setup_for_cell(CELL)
    tool = setup.section.tool.matrix()
    for t in _reports(setup, DoorPose(3, -4, 1.5))["THESIS-1350"].targets:
        T = KIN.forward(np.radians(t.joints_deg)) @ tool
        assert np.linalg.norm(T[:3, 3] - t.tcp_base_mm) < 1e-6
        q = Rotation.from_matrix(T[:3, :3]).as_quat(scalar_first=True)
        assert abs(abs(np.dot(q, t.quat_base)) - 1) < 1e-12
        assert t.quat_base[0] >= 0
    # the flange of the hinge paths lies in Table 4.5's region (what the base placement was chosen for)
    rep = _reports(setup, DoorPose(3, -4, 0))["THESIS-1350"]
    flange = [KIN.forward(np.radians(t.joints_deg))[:3, 3] for t in rep.targets if t.name[3] == "P"]
    x, y = np.array(flange)[:, 0], np.array(flange)[:, 1]
    assert 1290 < x.min() and x.max() < 1410 and -300 < y.min() and y.max() < -170


def test_one_configuration_per_hinge_path():
    rep = _reports(setup_for_cell(CELL))["THESIS-190"]
    for hinge in (1, 2):
        confs = {tuple(t.confdata) for t in rep.targets if t.hinge == hinge}
        cfx = {c[3] for c in confs}
        assert len(cfx) == 1, confs
    # like Table 4.6: joint 5 negative at the bottom hinge (cfx 1), positive at the top (cfx 0)
    assert rep.targets[0].confdata[3] == 1 and rep.targets[-1].confdata[3] == 0


def test_doors_500_mm_further_from_the_robot_are_refused_with_the_reason():
    for door_id, rep in _reports(setup_for_cell(CELL), DoorPose(500, 0, 0)).items():
        assert not rep.feasible and rep.error_code == "unreachable", door_id
        assert rep.reason.startswith("unreachable: target H2_APP ")
        bad = [t for t in rep.targets if not t.feasible]
        assert {t.hinge for t in bad} == {2} and all(t.joints_deg is None for t in bad)
        assert all(t.feasible for t in rep.targets if t.hinge == 1)


def test_a_04_m_tool_on_a_cell_placed_for_the_bare_flange_fails_on_joint_5():
    # the thesis placed its region for the flange (no tool); put the base so, then mount a 0.4 m angle head
    bare = {"base": {"pos_mm": [-1300, 65, 150]}}
    assert all(
        r.feasible for r in _reports(_setup(**bare, tool={"pos_mm": [0, 0, 0], "quat": ANGLE_HEAD})).values()
    )
    for door_id, rep in _reports(_setup(**bare, tool={"pos_mm": [0, 0, 400], "quat": ANGLE_HEAD})).items():
        assert not rep.feasible and rep.error_code == "joint_limit", door_id
        assert "target H1_APP needs joint 5 at" in rep.reason
        assert [t.name for t in rep.targets if not t.feasible] == [
            t.name for t in rep.targets if t.hinge == 1
        ]
    # the bundled cell stands 250 mm further back for its own tool, so a 0.4 m head still fits there
    bundled = CELL.robot_section
    longer = {"base": bundled["base"], "tool": {"pos_mm": [-100, 0, 400], "quat": ANGLE_HEAD}}
    assert all(r.feasible for r in _reports(_setup(**longer)).values())


def _target_at(name: str, q_deg: list[float]) -> Target:
    T = KIN.forward(np.radians(q_deg))
    q = Rotation.from_matrix(T[:3, :3]).as_quat(scalar_first=True)
    q = q if q[0] >= 0 else -q
    return Target(name=name, x_mm=T[0, 3], y_mm=T[1, 3], z_mm=T[2, 3], quat=tuple(q), hinge=1)


BARE = {"base": {"pos_mm": [0, 0, 0]}, "tool": {"pos_mm": [0, 0, 0], "quat": [1, 0, 0, 0]}}


def test_configuration_flip_between_neighbours_is_refused():
    doc = ROBOT.model_dump()
    doc["joint_limits_deg"] = [list(v) for v in doc["joint_limits_deg"]]
    doc["joint_limits_deg"][3] = [-90, 90]  # joint 4 cannot follow q4 80 -> 100 deg: the wrist must flip
    robot = RobotModel.model_validate(doc)
    setup = ReachSetup.of(robot, robot_section_from_doc({"model": "x", **BARE}))
    rep = check_reach(
        setup, [_target_at("A", [0, 20, -10, 80, 40, 0]), _target_at("B", [0, 20, -10, 100, 40, 0])]
    )
    assert rep.error_code == "configuration_flip" and "from A to B" in rep.reason
    # each alone is fine
    assert check_reach(setup, [_target_at("A", [0, 20, -10, 80, 40, 0])]).feasible
    assert check_reach(setup, [_target_at("B", [0, 20, -10, 100, 40, 0])]).feasible


def test_near_singularity_is_refused_and_names_joint_5():
    setup = ReachSetup.of(ROBOT, robot_section_from_doc({"model": "x", **BARE}))
    rep = check_reach(setup, [_target_at("S", [0, 20, -10, 0, 1, 0])])
    assert rep.error_code == "near_singularity" and "joint 5 at 1.0 deg" in rep.reason
    assert rep.targets[0].inv_condition < ROBOT.min_inv_condition
    assert check_reach(setup, [_target_at("S", [0, 20, -10, 0, 5, 0])]).feasible


def test_inverse_condition_is_one_over_frobenius_condition_and_zero_at_a_singularity():
    J = KIN.jacobian(np.radians([0, 20, -10, 0, 40, 0]))
    Jn = J.copy()
    Jn[:3] /= ROBOT.characteristic_length_mm
    want = 6 / (np.linalg.norm(Jn) * np.linalg.norm(np.linalg.inv(Jn)))
    assert inverse_condition(J, ROBOT.characteristic_length_mm) == pytest.approx(want)
    assert inverse_condition(KIN.jacobian(np.zeros(6)), ROBOT.characteristic_length_mm) < 1e-9  # q5 = 0


def test_segments_follow_the_thesis_assignment():
    # 9-point path: bottom edge, right side up, top edge, left side down (counter-clockwise as the camera sees)
    xz = np.array(
        [(10, 0), (20, 0), (30, 10), (30, 40), (20, 50), (10, 50), (0, 40), (0, 10), (10, 0)], float
    )
    assert segment_of_points(xz) == [
        "bottom_turn",
        "bottom_turn",
        "bottom_turn",
        "right_line",
        "top_turn",
        "top_turn",
        "top_turn",
        "left_line",
        "bottom_turn",
    ]
    # the 6-point path: P1 mid bottom, corners, back to P1
    xz6 = np.array([(15, 0), (30, 0), (30, 50), (0, 50), (0, 0), (15, 0)], float)
    assert segment_of_points(xz6) == [
        "bottom_turn",
        "bottom_turn",
        "right_line",
        "top_turn",
        "left_line",
        "bottom_turn",
    ]


def test_deflection_of_table_4_8_wrench_is_a_fraction_of_a_millimetre_and_linear():
    q = np.radians([-13.58, 69.54, 34.97, -14.01, -104.10, -93.48])
    tcp = np.array([-100.0, 0.0, 250.0])
    w = np.array(TABLE_4_8_WRENCH["left_line"])
    dd = tcp_deflection_mm(ROBOT, KIN, q, tcp, w)
    assert 0.05 < np.linalg.norm(dd) < 1.0
    np.testing.assert_allclose(tcp_deflection_mm(ROBOT, KIN, q, tcp, 2 * w), 2 * dd)
    # against the formula written out: J_v K^-1 J^T W with J in metres
    J = KIN.jacobian(q, tcp)
    J[:3] /= 1000
    want = 1000 * J[:3] @ np.diag(1 / ROBOT.stiffness.joint_nm_per_rad()) @ J.T @ w
    np.testing.assert_allclose(dd, want, rtol=1e-12)


def test_reach_reports_deflection_only_where_the_tool_cuts():
    rep = _reports(setup_for_cell(CELL))["THESIS-190"]
    for t in rep.targets:
        mag = math.hypot(*t.deflection_mm)
        assert (mag == 0.0) == t.name.endswith(("APP", "RET")), t.name


def test_compensation_is_minus_the_deflection_unless_the_recipe_has_corrections():
    dd = np.array([[0.1, -0.2, 0.3], [0.4, 0.0, 0.0]])
    comp = compensation_cell(dd, Rotation.identity(), np.array([False, True]))
    np.testing.assert_allclose(comp, [[-0.1, 0.2, -0.3], [0, 0, 0]])


def test_work_window_holds_the_table_4_6_flange_positions():
    from doorloc.robot.window import draw_window, window_points

    setup = setup_for_cell(CELL)
    win = window_points(setup, 0.0)
    for r, z in ((math.hypot(1400, 290), 0.0), (math.hypot(1400, 290), 2700.0)):
        assert np.hypot(win[:, 0] - r, win[:, 1] - z).min() < 30.0
    assert np.hypot(win[:, 0] - 4000, win[:, 1] - 0).min() > 1000  # far out of reach
    img = draw_window(setup, _reports(setup)["THESIS-190"])
    assert img.ndim == 3 and (img == (220, 245, 220)).all(axis=2).sum() > 10_000  # the filled window


def test_a_tool_frame_with_the_spindle_on_z_gives_the_same_answer():
    from doorloc.app.answer import DoorChoice
    from doorloc.app.services import answer_image
    from doorloc.cell import parse_cell
    from doorloc.vision.result import LocateResult

    to_z = Rotation.from_quat(
        [math.sqrt(0.5), -math.sqrt(0.5), 0, 0], scalar_first=True
    )  # TOOL_Z_ALONG_CELL_Y
    quat_z = (Rotation.from_quat(ANGLE_HEAD, scalar_first=True) * to_z).as_quat(scalar_first=True).tolist()
    doc = yaml.safe_load((REPO / "fixtures" / "cell_thesis.yaml").read_text())
    doc["robot"] = {
        **doc["robot"],
        "spindle_axis": "z",
        "tool": {"pos_mm": [-100.0, 0.0, 250.0], "quat": quat_z},
    }
    cell_z = parse_cell(doc, REPO / "fixtures", "cell_z.yaml")

    def locate(image, cell, door, *, image_name="", config=None, trace=None, jpeg_quality=0):
        return LocateResult(
            image=image_name,
            ok=True,
            x_mm=2.0,
            z_mm=-3.0,
            yaw_deg=1.0,
            thickness_mm=100.0,
            scale_mm_per_px=0.2,
            corner_px=[1.0, 2.0],
            elapsed_ms=1.0,
        )

    door = DOORS[1]
    answers = [
        answer_image(
            np.zeros((4, 4), np.uint8), c, DoorChoice.from_recipe(door), image_name="x", locate_fn=locate
        ).fields
        for c in (CELL, cell_z)
    ]
    assert all(a["ok"] and a["reach"]["feasible"] for a in answers)
    for ty, tz in zip(answers[0]["reach"]["targets"], answers[1]["reach"]["targets"], strict=True):
        np.testing.assert_allclose(ty["joints_deg"], tz["joints_deg"], atol=1e-9)
    direct = reach_for_door(
        setup_for_cell(cell_z), door, DoorPose(2.0, -3.0, 1.0), cell_z.face_y(door.door_size())
    )
    np.testing.assert_allclose(
        [t.joints_deg for t in direct.targets],
        [t["joints_deg"] for t in answers[0]["reach"]["targets"]],
        atol=1e-9,
    )


def test_compensated_targets_move_pocket_points_by_minus_the_deflection():
    setup = setup_for_cell(CELL)
    door = DOORS[0]
    face_y = CELL.face_y(door.door_size())
    plain, rep = compensated_targets(setup, door, DoorPose(), face_y)
    nominal = reach_for_door(setup, door, DoorPose(), face_y)
    raw = targets_for_pose(door, DoorPose(), face_y, base_orientation=setup.section.base_orientation())
    for t, r, tr in zip(plain, raw, nominal.targets, strict=True):
        moved = np.subtract((t.x_mm, t.y_mm, t.z_mm), (r.x_mm, r.y_mm, r.z_mm))
        np.testing.assert_allclose(
            moved, -np.array(tr.deflection_mm), atol=1e-12
        )  # base axes = cell axes here
        assert (np.abs(moved).max() == 0.0) == t.name.endswith(("APP", "RET"))
    # a hinge with its own force-displacement corrections is not compensated twice
    h1 = door.hinges[0].model_copy(
        update={"corrections": tuple(PointCorrection(dx_mm=0.1) for _ in range(6))}
    )
    own = door.model_copy(update={"hinges": (h1, door.hinges[1])})
    with_own, _ = compensated_targets(setup, own, DoorPose(), face_y)
    raw_own = targets_for_pose(own, DoorPose(), face_y, base_orientation=setup.section.base_orientation())
    assert all(t == r for t, r in zip(with_own, raw_own, strict=True) if t.hinge == 1)
    assert any(t != r for t, r in zip(with_own, raw_own, strict=True) if t.hinge == 2)


def test_a_wrist_swing_between_neighbours_is_a_flip():
    setup = ReachSetup.of(ROBOT, robot_section_from_doc({"model": "x", **BARE}))
    a, b = _target_at("A", [0, 20, -10, 0, 20, 0]), _target_at("B", [0, 20, -10, 90, 20, -90])
    assert check_reach(setup, [a]).feasible and check_reach(setup, [b]).feasible
    rep = check_reach(setup, [a, b])
    assert (
        rep.error_code == "configuration_flip" and "between A and B" in rep.reason and "joint" in rep.reason
    )
