"""An arris seen from the camera: the strip between the hinge face's outline and the arris's outer border.

:func:`arris_geometry` gives, for a door at a pose, each arris's cross-section as the camera sees it: where
the strip's borders lie on the outline plane, and the surface angle across the strip's image width (what a
rounding's shading follows). :mod:`doorloc.vision.arris_model` fits the strip's shading on it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from doorloc.arris import ArrisSection
from doorloc.pose import yaw_rotation_matrix

__all__ = ["ArrisGeometry", "arris_geometry"]


@dataclass(frozen=True)
class ArrisGeometry:
    """One arris seen from the camera, in its cross-section (:mod:`doorloc.arris`).

    Attributes
    ----------
    section : ArrisSection
        Size, profile and the camera centre in cross-section coordinates.
    w_outer_mm, w_inner_mm : float
        The strip's outer and inner borders on the outline plane ``y = a``, measured inwards from the
        sharp corner's line, mm (a chamfer: ``0`` and about ``a``; a rounding's silhouette lies a little inside ``0``).
    tau, theta : ndarray
        Fraction of the strip's image width from its outer border (0) to its inner border (1), and the
        surface angle there (``theta = 0`` on the hinge face), increasing ``tau``.
    normals_cell : (ndarray (3,), ndarray (3,)) or None
        Outward unit normals, cell frame, of the hinge face and of the arris's other face (the reference
        face, the bottom end or the far face): the arc's normal at ``theta`` is ``cos theta n1 + sin theta n2``.
    """

    section: ArrisSection
    w_outer_mm: float
    w_inner_mm: float
    tau: np.ndarray
    theta: np.ndarray
    normals_cell: tuple[np.ndarray, np.ndarray] | None = None

    def theta_at(self, tau: np.ndarray) -> np.ndarray:
        return np.interp(tau, self.tau, self.theta)


#: outward normals in the door's frame (the cell's at yaw 0, the reference corner at the origin): the hinge
#: face looks at the camera (-Y), the reference face -X, the far face +X, the bottom end -Z
_HINGE_NORMAL = np.array([0.0, -1.0, 0.0])
_SIDE_NORMALS = {
    "reference": np.array([-1.0, 0.0, 0.0]),
    "far": np.array([1.0, 0.0, 0.0]),
    "bottom": np.array([0.0, 0.0, -1.0]),
}


def arris_geometry(
    size_mm: float,
    profile: str,
    eye_cell: np.ndarray,
    corner_xz: np.ndarray,
    yaw_deg: float,
    face_y: float,
    thickness_mm: float,
) -> dict[str, ArrisGeometry]:
    """Cross-sections of the bottom, reference and far arrises for a door at this pose.

    Parameters
    ----------
    size_mm, profile : float, str
        The arris (chamfer leg or rounding radius, mm; ``"chamfer"`` or ``"round"``).
    eye_cell : ndarray (3,)
        Camera centre, cell frame, mm.
    corner_xz : ndarray (2,)
        The reference corner (cell X, Z), mm; ``yaw_deg`` the door's yaw.
    face_y : float
        Depth of the hinge face, mm.
    thickness_mm : float
        Door thickness (where the far arris is), mm.

    Returns
    -------
    dict
        ``{"bottom": ..., "reference": ..., "far": ...}``; an arris with nothing in view is left out.
    """
    R = yaw_rotation_matrix(yaw_deg)
    eye = R.T @ (np.asarray(eye_cell, float) - np.array([corner_xz[0], face_y, corner_xz[1]]))
    coords = {
        "reference": (eye[0], eye[1]),
        "bottom": (eye[2], eye[1]),
        "far": (thickness_mm - eye[0], eye[1]),
    }
    out = {}
    for name, (ew, ey) in coords.items():
        sec = ArrisSection(size_mm, profile, float(ew), float(ey))
        th_a, th_b = sec.visible_arc()
        if not np.isfinite(th_a) or th_a > 1e-9:
            continue  # the hinge side of the arris is turned away: not a strip beside the hinge face
        a = size_mm
        th = np.linspace(0.0, th_b, 257)
        on_face = sec.on_plane(th, 0.0)
        tau = (on_face - on_face[-1]) / (on_face[0] - on_face[-1])  # 1 at the inner border, 0 at the outer
        tau, th = tau[::-1], th[::-1]  # increasing tau: from the outer border inwards
        if np.any(np.diff(tau) <= 0):
            continue
        normals = (R @ _HINGE_NORMAL, R @ _SIDE_NORMALS[name])
        out[name] = ArrisGeometry(
            sec, float(sec.on_plane(th_b, a)), float(sec.on_plane(0.0, a)), tau, th, normals
        )
    return out
