"""The functional work window (paper 004, Urbanic et al. 2016) for the tool orientation, as a PNG.

The paper reduces reach to 2-D: with joint 1 fixed (points projected radially about its axis onto the
``(r, z)`` plane) and joints 4 and 6 fixed, joints 2, 3 and 5 swept within their limits place the
flange in a region of the arm's plane for a given approach angle. Here the approach angle is the
targets' own: the pitch of the flange's +Z axis above the horizontal (0 for the thesis cell, whose
flange points along base +X). The window is drawn for the **flange** (the thesis's end effector) and
the targets at their flange positions (TCP less the tool), ``r = hypot(x, y)``, base frame.

For targets off the base x-axis the fixed tool orientation adds an in-plane yaw that the 2-D view
does not show, so feasibility is decided by the 3-D inverse kinematics (:mod:`doorloc.robot.reach`);
this picture is for people placing a cell. Drawn with OpenCV (already a dependency): filled window,
its outline, Table 4.5's region radially projected, targets green (feasible) or red (not).
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from doorloc.robot.reach import ReachReport, ReachSetup

__all__ = ["window_points", "draw_window", "THESIS_REGION_MM"]

#: thesis Table 4.5, robot base frame, mm: x, y, z ranges of the flange for the hinges
THESIS_REGION_MM = ((1300.0, 1400.0), (-290.0, 290.0), (0.0, 2700.0))


def window_points(setup: ReachSetup, pitch_rad: float, steps: int = 361) -> np.ndarray:
    """Flange positions ``(r, z)`` (mm) reachable with the approach pitch, sweeping joints 2, 3, 5.

    Joints 1, 4, 6 are 0; joints 2 and 3 run over their limits less the margin on a ``steps x steps``
    grid; joint 5 is solved for the pitch and kept where it is inside its limits less the margin.

    Returns
    -------
    ndarray, shape (m, 2)
    """
    robot, kin = setup.robot, setup.kin
    lim = robot.limits_rad()
    m = math.radians(robot.joint_margin_deg)
    q2, q3 = np.meshgrid(
        np.linspace(lim[1, 0] + m, lim[1, 1] - m, steps), np.linspace(lim[2, 0] + m, lim[2, 1] - m, steps)
    )
    q = np.zeros((q2.size, 6))
    q[:, 1], q[:, 2] = q2.ravel(), q3.ravel()

    def pitch(qq: np.ndarray) -> np.ndarray:
        z = kin.forward(qq)[:, :3, 2]
        return np.arctan2(z[:, 2], np.hypot(z[:, 0], z[:, 1]) * np.sign(z[:, 0] + 1e-300))

    a0 = pitch(q)
    probe = q.copy()
    probe[:, 4] = 1e-3
    sign = np.sign(np.median((pitch(probe) - a0) / 1e-3))  # pitch changes with joint 5 as a0 + sign * q5
    q[:, 4] = (np.mod(pitch_rad - a0 + np.pi, 2 * np.pi) - np.pi) / sign
    keep = (q[:, 4] >= lim[4, 0] + m) & (q[:, 4] <= lim[4, 1] - m)
    p = kin.forward(q[keep])[:, :3, 3]
    return np.column_stack([p[:, 0], p[:, 2]])


def draw_window(setup: ReachSetup, report: ReachReport, size_px: int = 900) -> np.ndarray:
    """The work window with the report's targets projected onto it, as a BGR image (uint8)."""
    tool_inv = np.linalg.inv(setup.section.tool.matrix())  # type: ignore[union-attr]
    T = np.tile(np.eye(4), (len(report.targets), 1, 1))
    if report.targets:
        T[:, :3, :3] = Rotation.from_quat(
            [t.quat_base for t in report.targets], scalar_first=True
        ).as_matrix()
        T[:, :3, 3] = [t.tcp_base_mm for t in report.targets]
    flange = T @ tool_inv
    fz = flange[:, :3, 2]
    pitch = float(np.median(np.arctan2(fz[:, 2], np.hypot(fz[:, 0], fz[:, 1])))) if len(fz) else 0.0
    win = window_points(setup, pitch)
    r_t = np.hypot(flange[:, 0, 3], flange[:, 1, 3])
    z_t = flange[:, 2, 3]

    pad = 60
    r_max = max(float(win[:, 0].max()) if len(win) else 3000.0, float(r_t.max()) if len(r_t) else 0.0) + 200
    z_lo = min(float(win[:, 1].min()) if len(win) else -1000.0, float(z_t.min()) if len(z_t) else 0.0) - 200
    z_hi = max(float(win[:, 1].max()) if len(win) else 3000.0, float(z_t.max()) if len(z_t) else 0.0) + 200
    r_lo = 0.0
    scale = (size_px - 2 * pad) / max(r_max - r_lo, z_hi - z_lo)
    w = int(2 * pad + (r_max - r_lo) * scale)
    h = int(2 * pad + (z_hi - z_lo) * scale)

    def px(r: np.ndarray, z: np.ndarray) -> np.ndarray:
        return (
            np.column_stack([pad + (r - r_lo) * scale, h - pad - (z - z_lo) * scale]).round().astype(np.int32)
        )

    img = np.full((h, w, 3), 255, np.uint8)
    mask = np.zeros((h, w), np.uint8)
    if len(win):
        pts = px(win[:, 0], win[:, 1])
        inside = (pts[:, 0] >= 0) & (pts[:, 0] < w) & (pts[:, 1] >= 0) & (pts[:, 1] < h)
        mask[pts[inside, 1], pts[inside, 0]] = 255
        # the swept samples are a dense cloud; closing fills the gaps between neighbouring samples
        mask = np.asarray(
            cv2.morphologyEx(
                cv2.dilate(mask, np.ones((3, 3), np.uint8)), cv2.MORPH_CLOSE, np.ones((9, 9), np.uint8)
            ),
            dtype=np.uint8,
        )
        img[mask > 0] = (220, 245, 220)
        contours, _ = cv2.findContours(mask, cv2.RETR_LIST, cv2.CHAIN_APPROX_SIMPLE)
        cv2.drawContours(img, contours, -1, (60, 140, 60), 2, cv2.LINE_AA)
    # axes and a 500 mm grid
    for v in np.arange(0.0, r_max + 1, 500.0):
        x = int(px(np.array([v]), np.array([z_lo]))[0, 0])
        cv2.line(img, (x, pad), (x, h - pad), (225, 225, 225), 1)
        cv2.putText(
            img,
            f"{v:.0f}",
            (x - 18, h - pad + 20),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.45,
            (80, 80, 80),
            1,
            cv2.LINE_AA,
        )
    for v in np.arange(math.ceil(z_lo / 500) * 500.0, z_hi + 1, 500.0):
        y = int(px(np.array([0.0]), np.array([v]))[0, 1])
        cv2.line(img, (pad, y), (w - pad, y), (225, 225, 225), 1)
        cv2.putText(img, f"{v:.0f}", (5, y + 5), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (80, 80, 80), 1, cv2.LINE_AA)
    (x0, x1), (y0, y1), (zr0, zr1) = THESIS_REGION_MM
    region = px(np.array([x0, math.hypot(x1, max(abs(y0), abs(y1)))]), np.array([zr0, zr1]))
    cv2.rectangle(img, tuple(region[0]), tuple(region[1]), (200, 120, 0), 1, cv2.LINE_AA)
    cv2.putText(
        img,
        "thesis Table 4.5",
        (int(region[0, 0]) + 4, int(region[1, 1]) - 6),
        cv2.FONT_HERSHEY_SIMPLEX,
        0.45,
        (200, 120, 0),
        1,
        cv2.LINE_AA,
    )
    for (x, y), t in zip(px(r_t, z_t), report.targets, strict=True):
        cv2.circle(img, (int(x), int(y)), 4, (40, 170, 40) if t.feasible else (30, 30, 220), -1, cv2.LINE_AA)
    verdict = "feasible" if report.feasible else f"NOT feasible: {report.error_code}"
    cv2.putText(
        img,
        f"{report.robot}: flange work window, approach pitch {math.degrees(pitch):.1f} deg, j1=j4=j6=0",
        (pad, 22),
        cv2.FONT_HERSHEY_SIMPLEX,
        0.5,
        (0, 0, 0),
        1,
        cv2.LINE_AA,
    )
    cv2.putText(
        img,
        f"r = hypot(x, y) [mm] right, z [mm] up, base frame; {len(report.targets)} targets: {verdict}",
        (pad, 42),
        cv2.FONT_HERSHEY_SIMPLEX,
        0.45,
        (0, 0, 0),
        1,
        cv2.LINE_AA,
    )
    return img


def window_png(setup: ReachSetup, report: ReachReport) -> bytes:
    """:func:`draw_window` encoded as PNG bytes."""
    ok, buf = cv2.imencode(".png", draw_window(setup, report))
    if not ok:  # pragma: no cover - OpenCV encodes any uint8 BGR image
        raise RuntimeError("could not encode the work window as PNG")
    return buf.tobytes()
