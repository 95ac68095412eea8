"""Can the robot do it? Reach, joint limits, singularity and deflection for every target of a door.

A door's targets (cell frame, :func:`doorloc.recipes.targets.targets_for_pose`) are moved into the robot
base frame through the cell's robot base, the tool is taken off (flange = TCP x tool^-1) and the
closed-form inverse kinematics gives all 8 configurations of every target at once. A hinge path is
feasible when **one** configuration (one IK branch, joints 1/4/6 unwrapped along the path so they do
not jump a turn) serves every point of it with

- joints inside their limits less the robot file's ``joint_margin_deg``,
- the inverse condition number (Frobenius norm, position rows divided by the characteristic length,
  Jacobian at the TCP) at or above the robot file's ``min_inv_condition``,
- no joint moving more than ``max_joint_step_deg`` between neighbouring points.

Among the configurations that serve a path the most dexterous one is taken (largest smallest inverse
condition number; ties, e.g. the two wrist flips, go to the smaller wrist winding ``|q4| + |q6|``).
Hinges may use different configurations (the robot reconfigures in the air between them). The reason
for a refusal names the target and, where it is one, the joint:

- ``unreachable``: no configuration reaches the target at all (out of the arm's reach);
- ``joint_limit``: configurations exist, but each puts some joint beyond its limit (less the margin);
- ``near_singularity``: a configuration within the limits exists, but it is too close to a singularity;
- ``configuration_flip``: every point is reachable, but no single configuration serves two neighbouring
  points of the path, or in the one that does a joint swings more than the robot file's
  ``max_joint_step_deg`` between neighbours (the robot would flip its arm or wrist mid-cut).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict
from scipy.spatial.transform import Rotation

from doorloc.cell import Cell
from doorloc.pose import DoorPose
from doorloc.recipes.models import DoorRecipe
from doorloc.recipes.paths import DEFAULT_CLEARANCE_MM
from doorloc.recipes.targets import Target, targets_for_pose
from doorloc.robot.deflection import (
    TABLE_4_8_WRENCH,
    compensation_cell,
    deflection_of_jacobian,
    segment_of_points,
    wrench_tool_to_base,
)
from doorloc.robot.kinematics import N_BRANCHES, Kinematics
from doorloc.robot.model import DEFAULT_ROBOT, RobotModel, load_robot
from doorloc.robot.section import RobotSection, robot_section_from_doc

__all__ = [
    "Reason",
    "TargetReach",
    "ReachReport",
    "ReachSetup",
    "check_reach",
    "inverse_condition",
    "thesis_cell_path",
    "setup_for_cell",
    "reach_for_door",
    "compensated_targets",
    "report_table",
]

Reason = Literal["unreachable", "joint_limit", "near_singularity", "configuration_flip"]


@dataclass(frozen=True, slots=True)
class TargetReach:
    """One target as the robot would take it (SPEC section 9 fields).

    Attributes
    ----------
    name : str
    joints_deg : 6 floats or None
        Joint angles of the chosen configuration, deg (None: no configuration reaches the target).
    confdata : 4 ints or None
        ABB ``[cf1, cf4, cf6, cfx]``.
    tcp_base_mm : 3 floats
        TCP in the robot base frame, mm.
    quat_base : 4 floats
        Tool orientation in the base frame, scalar first ``[w, x, y, z]``, ``w >= 0``.
    feasible : bool
    reason : str or None
        ``<code>: <sentence>`` when not feasible.
    inv_condition : float or None
        Inverse condition number of the normalised Jacobian at the TCP, in (0, 1].
    deflection_mm : 3 floats or None
        TCP displacement under the segment's Table 4.8 wrench, base frame, mm (zero off the cut).
    """

    name: str
    hinge: int
    joints_deg: tuple[float, float, float, float, float, float] | None
    confdata: tuple[int, int, int, int] | None
    tcp_base_mm: tuple[float, float, float]
    quat_base: tuple[float, float, float, float]
    feasible: bool
    reason: str | None
    inv_condition: float | None
    deflection_mm: tuple[float, float, float] | None


class ReachReport(BaseModel):
    """Feasibility of all targets of one door (``doorloc reach --format json``, the locate answer's ``reach``)."""

    model_config = ConfigDict(frozen=True)

    robot: str
    tool: dict[str, list[float]]
    feasible: bool
    reason: str | None
    error_code: Reason | None
    targets: list[TargetReach]


@dataclass(frozen=True)
class ReachSetup:
    """Everything fixed for a cell: the robot, its kinematics, base and tool (built once, reused per door)."""

    robot: RobotModel
    kin: Kinematics
    section: RobotSection
    base_inv: np.ndarray  # (4, 4): cell -> base
    tool_inv: np.ndarray  # (4, 4): TCP -> flange
    tcp_flange_mm: np.ndarray  # (3,)
    base_rot_cell: Rotation

    @classmethod
    def of(cls, robot: RobotModel, section: RobotSection) -> ReachSetup:
        assert section.base is not None and section.tool is not None  # filled by RobotSection's validator
        base, tool = section.base.matrix(), section.tool.matrix()
        return cls(
            robot,
            Kinematics.of(robot),
            section,
            np.linalg.inv(base),
            np.linalg.inv(tool),
            np.asarray(section.tool.pos_mm, dtype=float),
            Rotation.from_quat(section.base.quat, scalar_first=True),
        )


def inverse_condition(J: np.ndarray, characteristic_length_mm: float) -> np.ndarray:
    """``1 / kappa_F`` of ``Jn = diag(I/Lc, I) J`` (thesis eq. 3.36-3.39), in [0, 1]; shape ``J.shape[:-2]``.

    ``kappa_F = ||Jn||_F ||Jn^-1||_F / 6`` (0 at a singularity).
    """
    Jn = J.copy()
    Jn[..., :3, :] /= characteristic_length_mm
    norm_sq = (Jn**2).sum(axis=(-1, -2))
    # a batched LU inverse is several times faster than a batched SVD here; exactly singular ones get 0
    try:
        inv_sq = (np.linalg.inv(Jn) ** 2).sum(axis=(-1, -2))
        singular = ~np.isfinite(inv_sq)
    except np.linalg.LinAlgError:
        singular = np.abs(np.linalg.det(Jn)) < 1e-12
        Jn[singular] = np.eye(6)
        inv_sq = (np.linalg.inv(Jn) ** 2).sum(axis=(-1, -2))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(singular, 0.0, 6.0 / np.sqrt(norm_sq * inv_sq))


def _hinge_groups(hinges: np.ndarray) -> list[np.ndarray]:
    """Index arrays of runs of consecutive targets with the same hinge number."""
    cuts = np.flatnonzero(np.diff(hinges)) + 1
    return np.split(np.arange(len(hinges)), cuts)


def _fmt(v: float) -> str:
    return f"{v:.1f}"


def check_reach(setup: ReachSetup, targets: Sequence[Target]) -> ReachReport:
    """Feasibility, joints, confdata, inverse condition and deflection of every target.

    Parameters
    ----------
    setup : ReachSetup
    targets : sequence of Target
        Cell frame, mm, scalar-first quaternions (path order, grouped by hinge).

    Returns
    -------
    ReachReport
        ``feasible`` is True when every hinge path is feasible; ``reason``/``error_code`` give the first
        problem in path order.
    """
    robot, kin = setup.robot, setup.kin
    tool = {"pos_mm": list(setup.section.tool.pos_mm), "quat": list(setup.section.tool.quat)}  # type: ignore[union-attr]
    if not targets:
        return ReachReport(
            robot=robot.name, tool=tool, feasible=True, reason=None, error_code=None, targets=[]
        )
    n = len(targets)
    pos = np.array([(t.x_mm, t.y_mm, t.z_mm) for t in targets], dtype=float)
    quat = np.array([t.quat for t in targets], dtype=float)
    groups = _hinge_groups(np.array([t.hinge for t in targets]))
    cell_tcp = np.zeros((n, 4, 4))
    cell_tcp[:, :3, :3] = Rotation.from_quat(quat, scalar_first=True).as_matrix()
    cell_tcp[:, :3, 3] = pos
    cell_tcp[:, 3, 3] = 1.0
    base_tcp = setup.base_inv @ cell_tcp
    q_all, exists = kin.inverse(base_tcp @ setup.tool_inv)  # (n, 8, 6), (n, 8)

    # joints 1, 4, 6 unwrapped along each hinge path so one branch's values run continuously
    for idx in groups:
        # (np.unwrap does the same, several times slower on these small arrays)
        block = q_all[idx][:, :, [0, 3, 5]]
        turns = np.round(np.diff(block, axis=0) / (2 * np.pi))
        block[1:] -= 2 * np.pi * np.cumsum(turns, axis=0)
        sub = q_all[idx]
        sub[:, :, [0, 3, 5]] = block
        q_all[idx] = sub

    lim = robot.limits_rad()
    margin = math.radians(robot.joint_margin_deg)
    beyond = np.maximum(lim[:, 0] + margin - q_all, q_all - (lim[:, 1] - margin))  # > 0: beyond by that much
    in_limits = (beyond <= 0).all(axis=-1) & exists
    frames = kin.frames(q_all)
    J = kin.jacobian_of_frames(frames, setup.tcp_flange_mm)
    cond = np.zeros(in_limits.shape)  # only configurations within the limits need it
    cond[in_limits] = inverse_condition(J[in_limits], robot.characteristic_length_mm)
    ok = in_limits & (cond >= robot.min_inv_condition)
    # a branch's index is its cfx (tested): cfx >= 2 puts the wrist centre behind axis 1 or the lower arm
    behind = np.arange(N_BRANCHES) >= 2

    chosen = np.zeros(n, dtype=int)
    target_reason: list[str | None] = [None] * n
    first_problem: tuple[Reason, str] | None = None
    for idx in groups:
        ok_path = ok[idx].all(axis=0) & _smooth(q_all[idx], robot)  # (8,)
        if ok_path.any():
            worst = np.round(cond[idx].min(axis=0), 9)
            winding = np.abs(q_all[idx][:, :, [3, 5]]).sum(axis=(0, 2))
            order = np.lexsort((winding, -worst, behind))
            chosen[idx] = next(b for b in order if ok_path[b])
            continue
        code, sentence = _why(idx, ok, exists, in_limits, beyond, cond, q_all, robot, targets)
        for j in idx:
            # a path no configuration serves: each point shows the best branch it has alone
            if ok[j].any() or in_limits[j].any():
                chosen[j] = int(np.argmax(np.where(ok[j], 2.0, 0.0) + np.where(in_limits[j], cond[j], -1.0)))
            else:  # the configuration that misses its limits least
                chosen[j] = int(
                    np.argmin(np.where(exists[j], np.clip(beyond[j], 0, None).max(axis=1), np.inf))
                )
            target_reason[j] = f"{code}: {sentence}"
        if first_problem is None:
            first_problem = (code, sentence)

    sel = np.arange(n)
    q = q_all[sel, chosen]
    confdata = kin.confdata_of_frames(frames[sel, chosen], q)
    cond_chosen = inverse_condition(J[sel, chosen], robot.characteristic_length_mm)
    # deflection under the segment's Table 4.8 wrench (pocket points only)
    wrench_tool = np.zeros((n, 6))
    for idx in groups:
        cut = [j for j in idx if targets[j].kind in ("corner", "edge")]
        if cut:
            wrench_tool[cut] = [TABLE_4_8_WRENCH[name] for name in segment_of_points(pos[cut][:, [0, 2]])]
    tool_rot_base = Rotation.from_matrix(base_tcp[:, :3, :3])
    dd = deflection_of_jacobian(robot, J[sel, chosen], wrench_tool_to_base(wrench_tool, tool_rot_base))

    quat_base = tool_rot_base.as_quat(scalar_first=True)
    quat_base[quat_base[:, 0] < 0] *= -1
    has_q = exists[sel, chosen].tolist()
    joints, conf = np.degrees(q).tolist(), confdata.tolist()
    tcp, qb, cond_l, dd_l = base_tcp[:, :3, 3].tolist(), quat_base.tolist(), cond_chosen.tolist(), dd.tolist()
    out = [
        TargetReach(
            name=t.name,
            hinge=t.hinge,
            joints_deg=tuple(joints[j]) if has_q[j] else None,
            confdata=tuple(conf[j]) if has_q[j] else None,
            tcp_base_mm=tuple(tcp[j]),
            quat_base=tuple(qb[j]),
            feasible=target_reason[j] is None,
            reason=target_reason[j],
            inv_condition=cond_l[j] if has_q[j] else None,
            deflection_mm=tuple(dd_l[j]) if has_q[j] else None,
        )
        for j, t in enumerate(targets)
    ]
    # built from arrays this function made and checked: model_construct skips validating them again
    if first_problem is None:
        return ReachReport.model_construct(
            robot=robot.name, tool=tool, feasible=True, reason=None, error_code=None, targets=out
        )
    code, sentence = first_problem
    return ReachReport.model_construct(
        robot=robot.name,
        tool=tool,
        feasible=False,
        reason=f"{code}: {sentence}",
        error_code=code,
        targets=out,
    )


def _why(
    idx: np.ndarray,
    ok: np.ndarray,
    exists: np.ndarray,
    in_limits: np.ndarray,
    beyond: np.ndarray,
    cond: np.ndarray,
    q_all: np.ndarray,
    robot: RobotModel,
    targets: Sequence[Target],
) -> tuple[Reason, str]:
    """The reason a hinge path has no single configuration: the first target, the code, a sentence."""
    for j in idx:
        name = targets[j].name
        if ok[j].any():
            continue
        if not exists[j].any():
            return "unreachable", f"target {name} is out of the arm's reach in every configuration"
        if not in_limits[j].any():
            # the configuration that misses its limits least names the joint
            b = int(np.argmin(np.where(exists[j], np.clip(beyond[j], 0, None).max(axis=1), np.inf)))
            joint = int(np.argmax(beyond[j, b]))
            lo, hi = robot.joint_limits_deg[joint]
            val = math.degrees(q_all[j, b, joint])
            return "joint_limit", (
                f"target {name} needs joint {joint + 1} at {_fmt(val)} deg, beyond its limits [{_fmt(lo)}, {_fmt(hi)}] "
                f"less the {_fmt(robot.joint_margin_deg)} deg margin (in the configuration that comes closest)"
            )
        best = float(np.where(in_limits[j], cond[j], 0.0).max())
        b = int(np.argmax(np.where(in_limits[j], cond[j], -1.0)))
        q5 = math.degrees(q_all[j, b, 4])
        return "near_singularity", (
            f"target {name} is near a singularity: inverse condition number {best:.3f} < {robot.min_inv_condition:g} "
            f"(joint 5 at {_fmt(q5)} deg)"
        )
    # every point alone is fine: find the first pair of neighbours no common configuration serves
    common = np.ones(N_BRANCHES, dtype=bool)
    for a, j in enumerate(idx):
        common &= ok[j]
        if not common.any():
            prev = targets[idx[a - 1]].name if a > 0 else targets[j].name
            before = np.flatnonzero(ok[idx[a - 1]]) if a > 0 else np.array([], dtype=int)
            after = np.flatnonzero(ok[j])
            return "configuration_flip", (
                f"no single configuration serves the path from {prev} to {targets[j].name}: the robot would "
                f"change configuration between them (cfx {before.tolist()} vs {after.tolist()})"
            )
    # a configuration serves every point, but a joint of it swings too far between two neighbours
    steps = np.abs(np.diff(q_all[idx], axis=0))  # (m-1, 8, 6)
    worst = np.where(common[None, :, None], steps, np.inf).max(axis=(0, 2))
    b = int(np.argmin(worst))
    k, joint = (int(v) for v in np.unravel_index(int(np.argmax(steps[:, b, :])), steps[:, b, :].shape))
    return "configuration_flip", (
        f"joint {joint + 1} would swing {_fmt(math.degrees(steps[k, b, joint]))} deg between {targets[idx[k]].name} and "
        f"{targets[idx[k + 1]].name} (more than {_fmt(robot.max_joint_step_deg)} deg between neighbours): "
        f"a wrist flip in mid-path"
    )


def _smooth(q_path: np.ndarray, robot: RobotModel) -> np.ndarray:
    """Per configuration (``q_path`` ``(m, 8, 6)``): no joint moves more than the robot's step between neighbours."""
    if len(q_path) < 2:
        return np.ones(q_path.shape[1], dtype=bool)
    return np.asarray(
        (np.abs(np.diff(q_path, axis=0)) <= math.radians(robot.max_joint_step_deg)).all(axis=(0, 2))
    )


def thesis_cell_path() -> Path:
    """The bundled thesis cell file (camera, fixture and the IRB6600 with its base and tool)."""
    return Path(str(resources.files("doorloc.robot") / "cells" / "thesis.yaml"))


def setup_for_cell(cell: Cell) -> ReachSetup | None:
    """The reach setup of a cell whose ``robot:`` section names a model; None when it names none.

    Raises
    ------
    doorloc.robot.section.RobotSectionError, doorloc.robot.model.RobotFileError
        A bad ``robot:`` section or robot file (messages name the key).
    """
    if not cell.robot_section:
        return None
    section = robot_section_from_doc(cell.robot_section, cell.source or "cell.yaml")
    if section.model is None:
        return None
    cell_dir = Path(cell.source).parent if cell.source else None
    return ReachSetup.of(load_robot(section.robot_path(cell_dir) or DEFAULT_ROBOT), section)


def reach_for_door(setup: ReachSetup, recipe: DoorRecipe, pose: DoorPose, face_y_mm: float) -> ReachReport:
    """Reach check of all hinge targets of ``recipe`` for a door measured at ``pose`` (cell frame, mm, deg).

    The targets are :func:`doorloc.recipes.targets.targets_for_pose` with the cell's tool orientation.
    """
    targets = targets_for_pose(recipe, pose, face_y_mm, base_orientation=setup.section.base_orientation())
    return check_reach(setup, targets)


def compensated_targets(
    setup: ReachSetup,
    recipe: DoorRecipe,
    pose: DoorPose,
    face_y_mm: float,
    *,
    clearance_mm: float = DEFAULT_CLEARANCE_MM,
) -> tuple[list[Target], ReachReport]:
    """The door's targets with the model's deflection compensation added, and the reach report they came from.

    Each pocket point moves by ``-dd`` (the predicted TCP deflection under its segment's Table 4.8 wrench,
    turned into the cell frame), except the points of hinges whose recipe carries its own
    force-displacement corrections: those are already in the targets and are not added twice
    (:func:`doorloc.robot.deflection.compensation_cell`). Approach and retract points do not move.
    An infeasible door gets its targets back unmoved (the report says why).
    """
    targets = targets_for_pose(
        recipe, pose, face_y_mm, clearance_mm=clearance_mm, base_orientation=setup.section.base_orientation()
    )
    report = check_reach(setup, targets)
    if not report.feasible:
        return targets, report
    own = {i + 1 for i, h in enumerate(recipe.hinges) if h.corrections}
    dd = np.array([t.deflection_mm for t in report.targets], dtype=float)
    comp = compensation_cell(dd, setup.base_rot_cell, np.array([t.hinge in own for t in targets]))
    moved = [
        t.model_copy(update={"x_mm": t.x_mm + c[0], "y_mm": t.y_mm + c[1], "z_mm": t.z_mm + c[2]})
        for t, c in zip(targets, comp.tolist(), strict=True)
    ]
    return moved, report


def report_table(report: ReachReport) -> str:
    """A fixed-width table of the report for people (one line per target, then the verdict)."""
    lines = [
        f"robot {report.robot}  tool pos_mm {report.tool['pos_mm']} quat {report.tool['quat']}",
        f"{'target':<10} {'ok':<3} {'joints_deg (1..6)':<52} {'confdata':<16} {'1/cond':>6} {'|dd| mm':>8}",
    ]
    for t in report.targets:
        joints = " ".join(f"{v:7.2f}" for v in t.joints_deg) if t.joints_deg else "-"
        conf = str(list(t.confdata)) if t.confdata else "-"
        cond = f"{t.inv_condition:6.3f}" if t.inv_condition is not None else "     -"
        dd = f"{math.hypot(*t.deflection_mm):8.3f}" if t.deflection_mm else "       -"
        lines.append(f"{t.name:<10} {'yes' if t.feasible else 'NO':<3} {joints:<52} {conf:<16} {cond} {dd}")
    lines.append("feasible" if report.feasible else f"NOT feasible: {report.reason}")
    return "\n".join(lines) + "\n"
