"""TCP deflection under the milling wrench: ``tau = J^T W``, ``dq = K_theta^-1 tau``, ``dd = J dq``.

The thesis's off-line compensation (section 2.2, appendix A.16/A.17), with the complementary stiffness
neglected as the thesis shows it may be (section 3.4, Table 4.1's joint stiffness only).

**Wrench.** Table 4.8 gives the mean milling wrench per path segment (left line, top turn, right line,
bottom turn) but not its frame. doorloc takes it **in the tool frame at the TCP** (the frame of the
target's ``quat``: +Y the spindle axis into the hinge face, +X across the door thickness, +Z up the
door at yaw 0), as the load the cut puts on the tool. That is the frame a spindle-mounted force sensor
measures in, it turns with the door's yaw, and in the bundled thesis cell (base axes parallel to the
cell axes) it coincides at yaw 0 with the robot base frame in which the thesis's appendix code applies
it (``Jacobian' * F``). Moments are about the TCP.

**Segments.** A pocket point takes the wrench of the segment that ends at it (the first pocket point:
the segment that starts at it): along Z on the low-X side the *left line*, on the high-X side the
*right line*; along X or round a corner (a 45-degree chord) above the pocket centre the *top turn*,
below it the *bottom turn* (the thesis's P1/P2/P7, P3, P4/P5, P6 assignment). Approach and retract points carry no wrench.

**Combination with the recipe's corrections.** ``dd`` is where the TCP goes under load; the
compensating correction is ``-dd`` (base frame). A recipe's per-point force-displacement corrections
(:class:`doorloc.recipes.models.PointCorrection`) are the same physical term measured or entered by
hand and already inside the targets; :func:`compensation_cell` therefore returns zero for the points of
a hinge whose recipe carries corrections, and ``-dd`` turned into the cell frame for the others: the
two are never added twice.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from doorloc.robot.kinematics import Kinematics
from doorloc.robot.model import RobotModel

__all__ = [
    "TABLE_4_8_WRENCH",
    "SEGMENTS",
    "segment_of_points",
    "tcp_deflection_mm",
    "deflection_of_jacobian",
    "wrench_tool_to_base",
    "compensation_cell",
]

#: thesis Table 4.8, mean milling wrench per segment: [FX, FY, FZ] N, [MX, MY, MZ] Nm (tool frame, see above)
TABLE_4_8_WRENCH: dict[str, tuple[float, float, float, float, float, float]] = {
    "left_line": (-209.0, 29.0, 12.0, -5.0, -43.0, 3.0),
    "top_turn": (-100.0, 13.0, 25.0, -3.0, -26.0, 2.0),
    "right_line": (-62.0, 3.0, -11.0, -1.0, -8.0, 2.0),
    "bottom_turn": (-13.0, 2.0, -22.0, -1.0, 4.0, 0.0),
}
SEGMENTS = tuple(TABLE_4_8_WRENCH)


def segment_of_points(points_xz: np.ndarray) -> list[str]:
    """Segment name per pocket point of one hinge path (door or cell X-Z coordinates, mm).

    Parameters
    ----------
    points_xz : ndarray, shape (n, 2)
        The pocket points P1..Pn in path order, ``(x, z)``.
    """
    p = np.asarray(points_xz, dtype=float)
    if len(p) < 2:
        return ["left_line"] * len(p)
    centre = 0.5 * (p.min(axis=0) + p.max(axis=0))
    steps = np.diff(p, axis=0)
    arriving = np.vstack([steps[:1], steps])  # P1 takes the segment leaving it
    out = []
    for pt, d in zip(p, arriving, strict=True):
        if abs(d[1]) > abs(d[0]):  # a 45-degree chord of a corner arc belongs to the turn
            out.append("left_line" if pt[0] < centre[0] else "right_line")
        else:
            out.append("top_turn" if pt[1] > centre[1] else "bottom_turn")
    return out


def tcp_deflection_mm(
    robot: RobotModel, kin: Kinematics, q: np.ndarray, tcp_flange_mm: np.ndarray, wrench_base: np.ndarray
) -> np.ndarray:
    """TCP displacement under a static wrench, base frame, mm.

    Parameters
    ----------
    q : ndarray, shape (..., 6)
        Joint angles, rad.
    tcp_flange_mm : ndarray, shape (3,)
        TCP in the flange frame, mm.
    wrench_base : ndarray, shape (..., 6)
        Force (N) and moment about the TCP (Nm), base frame.

    Returns
    -------
    ndarray, shape (..., 3)
        ``dd = J_v K^-1 J^T W`` in mm (J at the TCP).
    """
    return deflection_of_jacobian(robot, kin.jacobian(q, tcp_flange_mm), wrench_base)


def deflection_of_jacobian(robot: RobotModel, J_mm: np.ndarray, wrench_base: np.ndarray) -> np.ndarray:
    """:func:`tcp_deflection_mm` from a TCP Jacobian already computed (``(..., 6, 6)``, mm/rad rows 0-2)."""
    J = J_mm.copy()
    J[..., :3, :] /= 1000.0  # m/rad, so that J^T W is in Nm
    tau = np.einsum("...ji,...j->...i", J, np.asarray(wrench_base, dtype=float))
    dq = tau / robot.stiffness.joint_nm_per_rad()
    return 1000.0 * np.einsum("...ij,...j->...i", J[..., :3, :], dq)


def wrench_tool_to_base(wrench_tool: np.ndarray, tool_rot_base: Rotation) -> np.ndarray:
    """Force and moment given in the tool frame, expressed in the base frame (same point, the TCP)."""
    w = np.asarray(wrench_tool, dtype=float)
    return np.concatenate([tool_rot_base.apply(w[..., :3]), tool_rot_base.apply(w[..., 3:])], axis=-1)


def compensation_cell(
    deflection_base_mm: np.ndarray, base_rot_cell: Rotation, hinge_has_corrections: np.ndarray
) -> np.ndarray:
    """Correction to add to each target (cell frame, mm): ``-dd``, zero where the recipe has its own.

    Parameters
    ----------
    deflection_base_mm : ndarray, shape (n, 3)
    base_rot_cell : Rotation
        Orientation of the robot base frame in the cell frame.
    hinge_has_corrections : ndarray of bool, shape (n,)
        True for the points of hinges whose recipe carries force-displacement corrections.
    """
    comp = -base_rot_cell.apply(np.asarray(deflection_base_mm, dtype=float).reshape(-1, 3))
    comp[np.asarray(hinge_has_corrections, dtype=bool)] = 0.0
    return comp
