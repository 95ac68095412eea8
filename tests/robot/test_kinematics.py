"""Kinematics of the bundled IRB6600-175/2.55 against the thesis's tables and an independent DH product."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from doorloc.robot.kinematics import N_BRANCHES, Kinematics
from doorloc.robot.model import RobotFileError, RobotModel, bundled_robots, load_robot

ROBOT = load_robot()
KIN = Kinematics.of(ROBOT)

#: thesis Table 4.6 (deg), rows: bottom hinge W max, bottom W min, top W max, top W min
TABLE_4_6 = np.array(
    [
        [-13.58, 69.54, 34.97, -14.01, -104.10, -93.48],
        [13.58, 69.54, 34.97, 14.01, -104.10, -86.52],
        [-13.58, 6.89, -44.31, 21.68, 39.46, -107.06],
        [13.58, 6.89, -44.31, -21.68, 39.46, -72.94],
    ]
)
#: the matching corners of Table 4.5's region (base frame, mm), flange +Z along base +X
TABLE_4_5_CORNERS = np.array([[1400, -290, 0], [1400, 290, 0], [1400, -290, 2700], [1400, 290, 2700]], float)
#: the flange orientation Table 4.6's angles give (flange +Z along base +X, +X along base -Y)
R_TABLE_4_6 = np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]], float)


def _corner_poses() -> np.ndarray:
    T = np.tile(np.eye(4), (4, 1, 1))
    T[:, :3, :3] = R_TABLE_4_6
    T[:, :3, 3] = TABLE_4_5_CORNERS
    return T


def _dh_written_out(q_deg: np.ndarray) -> np.ndarray:
    """Table 2.1 written out link by link with scipy rotations: an implementation independent of kinematics.py."""
    rows = [
        (q_deg[0], 780, 320, -90),
        (q_deg[1] - 90, 0, 1075, 0),
        (q_deg[2], 0, 200, -90),
        (q_deg[3], 1142, 0, 90),
        (q_deg[4], 0, 0, -90),
        (q_deg[5] + 180, 200, 0, 0),
    ]
    T = np.eye(4)
    for theta, d, a, alpha in rows:
        rz, tz, tx, rx = np.eye(4), np.eye(4), np.eye(4), np.eye(4)
        rz[:3, :3] = Rotation.from_euler("z", theta, degrees=True).as_matrix()
        tz[2, 3] = d
        tx[0, 3] = a
        rx[:3, :3] = Rotation.from_euler("x", alpha, degrees=True).as_matrix()
        T = T @ rz @ tz @ tx @ rx
    return T


def test_bundled_robot_file_states_its_sources():
    assert "irb6600-175-2.55" in bundled_robots()
    assert ROBOT.joint_limits_deg[1] == (-65.0, 85.0) and ROBOT.joint_limits_deg[2] == (-180.0, 70.0)
    assert len(ROBOT.joint_limit_sources) == 6 and "thesis" in ROBOT.joint_limit_sources[1]
    assert ROBOT.stiffness.joint_nm_per_rad()[:2] == pytest.approx([2.4427e6, 2.1666749e6])
    # the characteristic length is a2 + sqrt(a3^2 + d4^2) + d6 (docs/robot.md)
    assert ROBOT.characteristic_length_mm == pytest.approx(1075 + math.hypot(200, 1142) + 200, abs=0.1)


def test_robot_file_is_strict(tmp_path):
    doc = ROBOT.model_dump()
    doc["payload_kg"] = 175
    with pytest.raises(Exception, match="payload_kg"):
        RobotModel.model_validate(doc)
    bad = tmp_path / "r.yaml"
    bad.write_text("name: x\nmodel: x\ndh: []\n")
    with pytest.raises(RobotFileError, match="dh"):
        load_robot(bad)
    with pytest.raises(RobotFileError, match="unknown robot"):
        load_robot("irb9999")


def test_forward_matches_an_independent_dh_product():
    rng = np.random.default_rng(3)
    q = rng.uniform(-180, 180, (50, 6))
    ours = KIN.forward(np.radians(q))
    for qi, T in zip(q, ours, strict=True):
        np.testing.assert_allclose(T, _dh_written_out(qi), atol=1e-9)


def test_table_4_6_angles_land_on_table_4_5_corners():
    T = KIN.forward(np.radians(TABLE_4_6))
    err = np.linalg.norm(T[:, :3, 3] - TABLE_4_5_CORNERS, axis=1)
    assert err.max() < 0.25, err  # the table's angles are truncated to 0.01 deg
    np.testing.assert_allclose(T[:, :3, :3], np.broadcast_to(R_TABLE_4_6, (4, 3, 3)), atol=3e-4)


def test_inverse_of_the_exact_corners_gives_table_4_6_in_its_configuration():
    q, exists = KIN.inverse(_corner_poses())
    want_conf = KIN.confdata(np.radians(TABLE_4_6))
    conf = KIN.confdata(q)
    for i in range(4):
        match = [b for b in range(N_BRANCHES) if exists[i, b] and (conf[i, b] == want_conf[i]).all()]
        assert len(match) == 1
        assert np.abs(np.degrees(q[i, match[0]]) - TABLE_4_6[i]).max() < 0.01


def test_confdata_at_home_and_for_table_4_6():
    assert KIN.confdata(np.zeros(6)).tolist() == [0, 0, 0, 0]
    # bottom hinges need joint 5 negative (cfx 1), top hinges positive (cfx 0); cf1 -1 for the negative joint 1
    assert KIN.confdata(np.radians(TABLE_4_6)).tolist() == [
        [-1, -1, -2, 1],
        [0, 0, -1, 1],
        [-1, 0, -2, 0],
        [0, -1, -1, 0],
    ]


joint = st.floats(-math.pi, math.pi, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(st.tuples(joint, st.floats(-1.13, 1.48), st.floats(-3.14, 1.22), joint, st.floats(-2.09, 2.09), joint))
def test_forward_of_inverse_is_the_pose_in_every_configuration(q):
    q = np.array(q)
    T = KIN.forward(q)
    sols, exists = KIN.inverse(T)
    assert exists.sum() >= 4  # a pose the arm reached has at least the front (or back) shoulder's 4
    for b in np.flatnonzero(exists):
        T2 = KIN.forward(sols[b])
        assert np.linalg.norm(T2[:3, 3] - T[:3, 3]) < 1e-6
        angle = Rotation.from_matrix(T2[:3, :3].T @ T[:3, :3]).magnitude()
        assert math.degrees(angle) < 1e-6
    # the joint vector we started from is one of the solutions (up to whole turns)
    d = np.abs(np.mod(sols - q + np.pi, 2 * np.pi) - np.pi).max(axis=1)
    assert d.min() < 1e-6 or abs(math.sin(q[4])) < 1e-6


def test_branch_index_is_abb_cfx():
    rng = np.random.default_rng(11)
    q = rng.uniform(-math.pi, math.pi, (500, 6))
    q[:, 1], q[:, 2] = rng.uniform(-1.1, 1.45, 500), rng.uniform(-3.1, 1.2, 500)
    sols, exists = KIN.inverse(KIN.forward(q))
    cfx = KIN.confdata(sols)[..., 3]
    assert (cfx[exists] == np.broadcast_to(np.arange(N_BRANCHES), cfx.shape)[exists]).all()


def test_jacobian_matches_finite_differences():
    rng = np.random.default_rng(7)
    tcp = np.array([-100.0, 0.0, 250.0])
    h = 1e-6
    for q in rng.uniform(-2, 2, (20, 6)):
        J = KIN.jacobian(q, tcp)
        T0 = KIN.forward(q)
        p0 = T0[:3, 3] + T0[:3, :3] @ tcp
        for i in range(6):
            dq = np.zeros(6)
            dq[i] = h
            T1 = KIN.forward(q + dq)
            p1 = T1[:3, 3] + T1[:3, :3] @ tcp
            np.testing.assert_allclose((p1 - p0) / h, J[:3, i], atol=2e-3)
            w = Rotation.from_matrix(T1[:3, :3] @ T0[:3, :3].T).as_rotvec() / h
            np.testing.assert_allclose(w, J[3:, i], atol=1e-6)


def test_inverse_is_vectorised_over_any_batch_shape():
    T = np.broadcast_to(_corner_poses()[0], (2, 3, 4, 4))
    q, exists = KIN.inverse(T)
    assert q.shape == (2, 3, 8, 6) and exists.shape == (2, 3, 8)
    assert KIN.confdata(q).shape == (2, 3, 8, 4)


def test_out_of_reach_pose_has_no_solution():
    T = _corner_poses()[0].copy()
    T[0, 3] = 4000.0
    _, exists = KIN.inverse(T)
    assert not exists.any()
