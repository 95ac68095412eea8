"""Targets = door-frame path points moved by the pose; checked against the thesis's eq. 3.46-3.50."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from doorloc.cell import Fixture
from doorloc.pose import DoorPose, door_to_cell, yaw_rotation_matrix
from doorloc.recipes.models import DoorRecipe
from doorloc.recipes.paths import pocket_points_xz, recipe_path
from doorloc.recipes.targets import TOOL_Z_ALONG_CELL_Y, targets_for_pose, tool_quaternion

_spec = importlib.util.spec_from_file_location(
    "hinge_strategies", Path(__file__).with_name("hinge_strategies.py")
)
strategies = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(strategies)

# the placement envelope of the thesis cell (SPEC section 7)
poses = st.builds(DoorPose, x_mm=st.floats(-10, 10), z_mm=st.floats(-10, 10), yaw_deg=st.floats(-2, 2))


def thesis_eq_3_46_to_3_50(lx_l: float, lz_l: float, pc: float, yaw_deg: float) -> tuple[float, float]:
    """The thesis's point generation, written out as printed (section 3.8, figure 3.32).

    Lp = sqrt(LxL^2 + (LzL + PC)^2); alpha = acos(LxL / Lp); beta = alpha + Yaw;
    LxG = Lp cos(beta); LzG = Lp sin(beta). (acos returns alpha in [0, pi], right for LzL + PC >= 0,
    which holds for every point on a door.)
    """
    lp = math.sqrt(lx_l**2 + (lz_l + pc) ** 2)
    alpha = math.acos(lx_l / lp)
    beta = alpha + math.radians(yaw_deg)
    return lp * math.cos(beta), lp * math.sin(beta)


def quat_to_matrix(q) -> np.ndarray:
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


@settings(max_examples=300, deadline=None)
@given(strategies.recipes(), poses, st.floats(-400.0, 400.0))
def test_targets_agree_with_thesis_equations(recipe: DoorRecipe, pose: DoorPose, face_y: float):
    targets = targets_for_pose(recipe, pose, face_y)
    h = recipe.hinges[0]
    xz, _ = pocket_points_xz(h, recipe.tool_diameter_mm)
    corr = [(c.dx_mm, c.dy_mm, c.dz_mm) for c in h.corrections] or [(0.0, 0.0, 0.0)] * len(xz)
    # the thesis's PC is the point's correction along z, added before the rotation; x and y corrections
    # shift the local point the same way
    local = [(xz[0, 0], -10.0, xz[0, 1], 0.0, 0.0)]  # approach: in the air, no correction
    local += [(px + c[0], h.depth_mm + c[1], pz, c[2], 0.0) for (px, pz), c in zip(xz, corr, strict=True)]
    local.append((xz[-1, 0] + corr[-1][0], -10.0, xz[-1, 1], corr[-1][2], 0.0))
    assert len(targets) == len(local)
    for t, (lx, ly, lz, pc, _) in zip(targets, local, strict=True):
        lxg, lzg = thesis_eq_3_46_to_3_50(lx, lz, pc, pose.yaw_deg)
        assert abs(t.x_mm - (pose.x_mm + lxg)) < 1e-9
        assert abs(t.z_mm - (pose.z_mm + lzg)) < 1e-9
        assert abs(t.y_mm - (ly + face_y)) < 1e-9


@settings(max_examples=200, deadline=None)
@given(strategies.recipes(), poses, st.floats(-400.0, 400.0))
def test_targets_are_the_rigid_transform_of_the_door_frame_points(recipe, pose, face_y):
    targets = targets_for_pose(recipe, pose, face_y)
    door_pts = np.array([p.point_door for p in recipe_path(recipe)])
    cell = np.array([[t.x_mm, t.y_mm, t.z_mm] for t in targets])
    # a rigid motion: R @ p + t with R the pose's rotation, t the corner shift and the face depth
    expected = door_pts @ yaw_rotation_matrix(pose.yaw_deg).T + [pose.x_mm, face_y, pose.z_mm]
    np.testing.assert_allclose(cell, expected, rtol=0, atol=1e-9)
    np.testing.assert_allclose(cell, door_to_cell(door_pts, pose, face_y), rtol=0, atol=0)
    # distances between points are kept
    np.testing.assert_allclose(
        np.linalg.norm(np.diff(cell, axis=0), axis=1),
        np.linalg.norm(np.diff(door_pts, axis=0), axis=1),
        atol=1e-9,
    )


@settings(max_examples=300, deadline=None)
@given(st.floats(-2.0, 2.0))
def test_quaternion_unit_scalar_first_only_q1_q3_change(yaw):
    q = tool_quaternion(yaw)
    assert abs(math.fsum(v * v for v in q) - 1.0) < 1e-12
    assert q[0] >= 0 and q[1] == 0.0 and q[3] == 0.0
    # it is the door's rotation: tool frame = cell axes at yaw 0, turned with the door
    np.testing.assert_allclose(quat_to_matrix(q), yaw_rotation_matrix(yaw), atol=1e-12)
    # the spindle (tool +Y) stays normal to the hinge face, pointing into the door
    np.testing.assert_allclose(quat_to_matrix(q) @ [0, 1, 0], [0, 1, 0], atol=1e-12)


def test_quaternion_scalar_stays_nonnegative_for_large_yaw():
    for yaw in (-180.0, -179.0, 179.0, 180.0, 0.0):
        q = tool_quaternion(yaw)
        assert q[0] >= 0
        np.testing.assert_allclose(quat_to_matrix(q), yaw_rotation_matrix(yaw), atol=1e-12)


def test_every_target_carries_the_pose_quaternion_and_its_hinge(recipe_factory):
    r = recipe_factory()
    ts = targets_for_pose(r, DoorPose(1.0, -2.0, 1.5), 0.0)
    assert {t.quat for t in ts} == {tool_quaternion(1.5)}
    assert [t.hinge for t in ts] == [1] * 8 + [2] * 11
    assert ts[0].name == "H1_APP" and ts[-1].name == "H2_RET"


def test_face_depth_comes_from_the_fixture(recipe_factory):
    r = recipe_factory(width_mm=1100)
    fixture = Fixture(reference_width_mm=900, face_y_mm=5.0, face_shift_per_width=-0.5)
    face_y = fixture.face_y(r.width_mm)
    assert face_y == pytest.approx(-95.0)
    ts = targets_for_pose(r, DoorPose(), face_y)
    assert ts[1].y_mm == pytest.approx(r.hinges[0].depth_mm + face_y)  # the tool centre at the pocket bottom
    assert ts[0].y_mm == pytest.approx(-10.0 + face_y)  # approach 10 mm in front of the face


@settings(max_examples=100, deadline=None)
@given(st.floats(-2.0, 2.0))
def test_alternative_base_puts_the_spindle_on_tool_z(yaw):
    q = tool_quaternion(yaw, TOOL_Z_ALONG_CELL_Y)
    assert abs(math.fsum(v * v for v in q) - 1.0) < 1e-12 and q[0] >= 0
    r = quat_to_matrix(q)
    np.testing.assert_allclose(r @ [0, 0, 1], [0, 1, 0], atol=1e-12)  # spindle (tool +Z) into the face
    np.testing.assert_allclose(r, yaw_rotation_matrix(yaw) @ quat_to_matrix(TOOL_Z_ALONG_CELL_Y), atol=1e-12)
