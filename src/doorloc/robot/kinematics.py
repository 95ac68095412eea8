"""Forward and inverse kinematics, confdata and the geometric Jacobian of a spherical-wrist 6R arm.

Conventions (docs/robot.md): standard DH, each link ``Rz(theta_offset + q) Tz(d) Tx(a) Rx(alpha)``
(thesis Table 2.1); lengths in mm, joint angles in radians inside this module; every function takes
arrays with any leading batch shape (``q`` is ``(..., 6)``, poses ``(..., 4, 4)``) so one call
handles all targets of a door. The chain ends at the flange (ABB's ``tool0``); tools are applied by
the caller (:mod:`doorloc.robot.reach`).

Why hand-written: at the time of writing no well-kept Python library gives a closed-form inverse
for a DH arm with these offsets without a one-time symbolic derivation (roboticstoolbox-python is
about half a gigabyte; pytransform3d and pinocchio give forward kinematics and numeric inverses).
The decoupling used here is the thesis's section 2.1.2 (Pieper): wrist centre from the pose, joint 1
from its azimuth, joints 2-3 from the planar two-link triangle, joints 4-6 from ``R36 = R03^T R``
(eq. 2.24-2.27, with eq. 2.27's sign slip corrected: ``q6 = atan2(R32, -R31)`` for ``sin q5 > 0``).

Branches: :func:`inverse` returns 8 solutions per pose, index ``4*shoulder + 2*elbow + wrist``
(shoulder 0: joint 1 towards the wrist centre, 1: turned half a turn; elbow 0/1: the two triangle
solutions; wrist 0: ``q5 >= 0``, 1: ``q5 < 0``), which is ABB's ``cfx`` of the solution (tested);
the full ``confdata`` of any joint vector comes from :meth:`Kinematics.confdata`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from doorloc.robot.model import RobotModel

__all__ = ["Kinematics", "N_BRANCHES", "wrap_angle"]

#: solutions of the inverse kinematics per pose (shoulder x elbow x wrist)
N_BRANCHES = 8


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Angles wrapped into ``(-pi, pi]``, radians."""
    w = np.mod(a + np.pi, 2 * np.pi) - np.pi
    return np.where(w == -np.pi, np.pi, w)


def _dh_transforms(theta: np.ndarray, d: np.ndarray, a: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """``Rz(theta) Tz(d) Tx(a) Rx(alpha)`` for arrays broadcasting to ``(..., k)``; shape ``(..., k, 4, 4)``."""
    ct, st = np.cos(theta), np.sin(theta)
    ca, sa = np.cos(alpha), np.sin(alpha)
    out = np.zeros((*ct.shape, 4, 4))
    out[..., 0, 0], out[..., 0, 1], out[..., 0, 2], out[..., 0, 3] = ct, -st * ca, st * sa, a * ct
    out[..., 1, 0], out[..., 1, 1], out[..., 1, 2], out[..., 1, 3] = st, ct * ca, -ct * sa, a * st
    out[..., 2, 1], out[..., 2, 2], out[..., 2, 3] = sa, ca, d
    out[..., 3, 3] = 1.0
    return out


@dataclass(frozen=True)
class Kinematics:
    """The arm of a :class:`~doorloc.robot.model.RobotModel` as arrays (mm, rad).

    Examples
    --------
    >>> from doorloc.robot.model import load_robot
    >>> kin = Kinematics.of(load_robot())
    >>> np.round(kin.forward(np.zeros(6))[:3, 3], 3).tolist()   # flange at home, base frame, mm
    [1662.0, 0.0, 2055.0]
    """

    theta_offset: np.ndarray
    d: np.ndarray
    a: np.ndarray
    alpha: np.ndarray

    @classmethod
    def of(cls, robot: RobotModel) -> Kinematics:
        """Arrays of the robot's DH table."""
        return cls(
            theta_offset=np.radians([link.theta_offset_deg for link in robot.dh]),
            d=np.array([link.d_mm for link in robot.dh], dtype=float),
            a=np.array([link.a_mm for link in robot.dh], dtype=float),
            alpha=np.radians([link.alpha_deg for link in robot.dh]),
        )

    # ----------------------------------------------------------------------------- forward
    def frames(self, q: np.ndarray) -> np.ndarray:
        """Base frame and the frames after joints 1..6, shape ``(..., 7, 4, 4)``, base frame, mm."""
        q = np.asarray(q, dtype=float)
        links = _dh_transforms(q + self.theta_offset, self.d, self.a, self.alpha)
        out = np.empty((*q.shape[:-1], 7, 4, 4))
        out[..., 0, :, :] = np.eye(4)
        for i in range(6):
            out[..., i + 1, :, :] = out[..., i, :, :] @ links[..., i, :, :]
        return out

    def forward(self, q: np.ndarray) -> np.ndarray:
        """Flange pose in the base frame, shape ``(..., 4, 4)``, mm; ``q`` in radians, ``(..., 6)``."""
        return self.frames(q)[..., 6, :, :]

    # ----------------------------------------------------------------------------- inverse
    def inverse(self, flange: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """All 8 closed-form solutions for flange poses.

        Parameters
        ----------
        flange : ndarray, shape (..., 4, 4)
            Flange pose in the base frame, mm.

        Returns
        -------
        q : ndarray, shape (..., 8, 6)
            Joint angles, radians, each wrapped into ``(-pi, pi]`` (branch index: module docstring).
            Where a branch does not exist the values are those of the nearest reachable point.
        exists : ndarray of bool, shape (..., 8)
            False where the wrist centre is out of the arm's reach for that shoulder branch.
        """
        flange = np.asarray(flange, dtype=float)
        batch = flange.shape[:-2]
        R, p = flange[..., :3, :3], flange[..., :3, 3]
        d1, d4, d6 = self.d[0], self.d[3], self.d[5]
        a1, a2, a3 = self.a[0], self.a[1], self.a[2]
        wc = p - d6 * R[..., :, 2]
        azimuth = np.arctan2(wc[..., 1], wc[..., 0])
        rho = np.hypot(wc[..., 0], wc[..., 1])
        # shoulder branches: (..., 2)
        q1 = np.stack([azimuth, azimuth + np.pi], axis=-1) - self.theta_offset[0]
        r = np.stack([rho, -rho], axis=-1)
        # wrist centre in frame 1 (x forward along the arm, y down), the planar two-link problem
        x1 = r - a1
        y1 = -(wc[..., 2:3] - d1) * np.ones_like(r)
        l3 = np.hypot(a3, d4)
        phi = np.arctan2(d4, a3)
        cos_psi = (x1**2 + y1**2 - a2**2 - l3**2) / (2 * a2 * l3)
        exists2 = np.abs(cos_psi) <= 1.0 + 1e-12
        psi_abs = np.arccos(np.clip(cos_psi, -1.0, 1.0))
        psi = np.stack([psi_abs, -psi_abs], axis=-1)  # (..., 2 shoulder, 2 elbow)
        th3 = psi - phi
        th2 = np.arctan2(y1, x1)[..., None] - np.arctan2(l3 * np.sin(psi), a2 + l3 * np.cos(psi))
        q1e = np.broadcast_to(q1[..., None], th2.shape)
        q123 = np.stack([q1e, th2 - self.theta_offset[1], th3 - self.theta_offset[2]], axis=-1)
        # wrist: R36 = R03^T R = Rz(t4) Ry(-t5) Rz(t6) for alpha4 = +90, alpha5 = -90
        R03 = self._r03(q123)
        M = np.swapaxes(R03, -1, -2) @ R[..., None, None, :, :]
        # t5 from atan2 (acos loses half the digits near t5 = 0); t6 from what Rz(t4) Ry(-t5) leaves of R36,
        # so FK(IK) stays exact even where t4 and t6 are ill-defined (near the wrist singularity)
        s5_abs = np.hypot(M[..., 0, 2], M[..., 1, 2])
        t5_abs = np.arctan2(s5_abs, M[..., 2, 2])
        t5 = np.stack([t5_abs, -t5_abs], axis=-1)  # (..., 2, 2, 2 wrist)
        t4_pos = np.where(s5_abs > 1e-12, np.arctan2(-M[..., 1, 2], -M[..., 0, 2]), 0.0)
        t4 = np.stack([t4_pos, np.where(s5_abs > 1e-12, t4_pos + np.pi, 0.0)], axis=-1)
        c4, s4, c5, s5 = np.cos(t4), np.sin(t4), np.cos(t5), np.sin(t5)
        Mx = M[..., None, :, :]
        n00 = c5 * (c4 * Mx[..., 0, 0] + s4 * Mx[..., 1, 0]) + s5 * Mx[..., 2, 0]
        n10 = -s4 * Mx[..., 0, 0] + c4 * Mx[..., 1, 0]
        t6 = np.arctan2(n10, n00)
        q456 = np.stack(
            [t4 - self.theta_offset[3], t5 - self.theta_offset[4], t6 - self.theta_offset[5]], axis=-1
        )
        q = np.concatenate([np.broadcast_to(q123[..., None, :], (*q456.shape[:-1], 3)), q456], axis=-1)
        q = wrap_angle(q).reshape(*batch, N_BRANCHES, 6)
        exists = np.broadcast_to(exists2[..., None, None], (*exists2.shape, 2, 2)).reshape(*batch, N_BRANCHES)
        return q, exists

    def _r03(self, q123: np.ndarray) -> np.ndarray:
        links = _dh_transforms(q123 + self.theta_offset[:3], self.d[:3], self.a[:3], self.alpha[:3])[
            ..., :3, :3
        ]
        return links[..., 0, :, :] @ links[..., 1, :, :] @ links[..., 2, :, :]

    # ----------------------------------------------------------------------------- Jacobian
    def jacobian(self, q: np.ndarray, tcp_flange_mm: np.ndarray | None = None) -> np.ndarray:
        """Geometric Jacobian at the TCP (thesis eq. 2.29), base frame; shape ``(..., 6, 6)``.

        Rows 0-2: linear velocity of the TCP in mm/rad; rows 3-5: angular velocity (rad/rad).
        ``tcp_flange_mm`` (3,) is the TCP in the flange frame (default: the flange origin).
        """
        return self.jacobian_of_frames(self.frames(q), tcp_flange_mm)

    @staticmethod
    def jacobian_of_frames(F: np.ndarray, tcp_flange_mm: np.ndarray | None = None) -> np.ndarray:
        """:meth:`jacobian` from frames already computed by :meth:`frames` (``(..., 7, 4, 4)``)."""
        p = F[..., 6, :3, 3]
        if tcp_flange_mm is not None:
            p = p + F[..., 6, :3, :3] @ np.asarray(tcp_flange_mm, dtype=float)
        z = F[..., :6, :3, 2]
        r = p[..., None, :] - F[..., :6, :3, 3]
        jv = np.stack(
            [
                z[..., 1] * r[..., 2] - z[..., 2] * r[..., 1],
                z[..., 2] * r[..., 0] - z[..., 0] * r[..., 2],
                z[..., 0] * r[..., 1] - z[..., 1] * r[..., 0],
            ],
            axis=-2,
        )
        return np.concatenate([jv, np.swapaxes(z, -1, -2)], axis=-2)

    # ----------------------------------------------------------------------------- confdata
    def confdata(self, q: np.ndarray) -> np.ndarray:
        """ABB ``confdata`` ``[cf1, cf4, cf6, cfx]`` of joint vectors, shape ``(..., 4)``, int.

        ``cf1/cf4/cf6`` are the quarter revolutions of joints 1, 4, 6 (``floor(q / 90 deg)``);
        ``cfx = 4 * (wrist centre behind axis 1) + 2 * (wrist centre behind the lower arm) + (q5 < 0)``
        (ABB's table for serial 6-axis robots: 0 = in front, in front, q5 >= 0 ... 7 = behind, behind, q5 < 0).
        """
        q = np.asarray(q, dtype=float)
        return self.confdata_of_frames(self.frames(q), q)

    def confdata_of_frames(self, F: np.ndarray, q: np.ndarray) -> np.ndarray:
        """:meth:`confdata` from frames already computed by :meth:`frames`."""
        wc = F[..., 4, :3, 3]
        o1, o2, z1 = F[..., 1, :3, 3], F[..., 2, :3, 3], F[..., 1, :3, 2]
        theta1 = q[..., 0] + self.theta_offset[0]
        behind_axis1 = (np.cos(theta1) * wc[..., 0] + np.sin(theta1) * wc[..., 1]) < 0
        u, v = o2 - o1, wc - o1
        behind_arm = (
            (u[..., 1] * v[..., 2] - u[..., 2] * v[..., 1]) * z1[..., 0]
            + (u[..., 2] * v[..., 0] - u[..., 0] * v[..., 2]) * z1[..., 1]
            + (u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]) * z1[..., 2]
        ) < 0
        cfx = 4 * behind_axis1.astype(int) + 2 * behind_arm.astype(int) + (q[..., 4] < 0).astype(int)
        quarters = np.floor(np.degrees(q[..., [0, 3, 5]]) / 90.0 + 1e-9).astype(int)
        return np.concatenate([quarters, cfx[..., None]], axis=-1)
