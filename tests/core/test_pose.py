"""The door->cell transform: the SPEC's equations, inverse, and rigidity."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from doorloc.pose import DoorPose, cell_to_door, door_to_cell, yaw_rotation_matrix

poses = st.builds(DoorPose, st.floats(-10, 10), st.floats(-10, 10), st.floats(-2, 2))
points = st.lists(
    st.tuples(st.floats(0, 100), st.floats(0, 1350), st.floats(0, 3000)), min_size=1, max_size=20
)


@settings(max_examples=100, deadline=None)
@given(pose=poses, pts=points, face_y=st.floats(-300, 300))
def test_matches_spec_equations(pose, pts, face_y):
    p = np.array(pts)
    out = door_to_cell(p, pose, face_y)
    a = math.radians(pose.yaw_deg)
    for (px, py, pz), (X, Y, Z) in zip(p, out, strict=True):
        assert math.isclose(X, pose.x_mm + px * math.cos(a) - pz * math.sin(a), abs_tol=1e-9)
        assert math.isclose(Y, py + face_y, abs_tol=1e-9)
        assert math.isclose(Z, pose.z_mm + px * math.sin(a) + pz * math.cos(a), abs_tol=1e-9)


@settings(max_examples=100, deadline=None)
@given(pose=poses, pts=points, face_y=st.floats(-300, 300))
def test_inverse_and_rigid(pose, pts, face_y):
    p = np.array(pts)
    q = door_to_cell(p, pose, face_y)
    np.testing.assert_allclose(cell_to_door(q, pose, face_y), p, atol=1e-9)
    R = yaw_rotation_matrix(pose.yaw_deg)
    np.testing.assert_allclose(q - q[:1], (p - p[:1]) @ R.T, atol=1e-9)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert math.isclose(np.linalg.det(R), 1.0, abs_tol=1e-12)


def test_positive_yaw_turns_door_x_towards_cell_z():
    q = door_to_cell([[10.0, 0.0, 0.0]], DoorPose(0, 0, 1.0))
    assert q[0, 2] > 0
