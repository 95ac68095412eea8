"""Geometry of one arris seen from a viewpoint: the part of a chamfer or rounding in view, and where it lies.

Shared by the renderer (:mod:`doorloc.sim.door`, which shades a rounded arris exactly) and by locate
(:mod:`doorloc.vision.arris_model`, which finds the virtual sharp corner behind it), so both use one model.

Everything happens in the arris's **cross-section**, a plane perpendicular to the edge: an arris is a
prism (chamfer) or a cylinder (round) along the edge, and so is the pencil of camera rays through one
ruling (a line along the edge); projecting along the edge loses nothing. Coordinates, mm:

- ``w``: inwards from the side face (the face the edge bends onto: reference face, bottom end, far face);
- ``y``: inwards from the hinge face (door +Y).

The virtual sharp corner is ``(0, 0)``. An arris of size ``a`` runs from ``(a, 0)`` on the hinge face
(angle ``theta = 0``) to ``(0, a)`` on the side face (``theta = pi/2``): a chamfer along the straight line
between them, a rounding along the quarter circle of centre ``(a, a)``:
``(w, y) = (a - a sin(theta), a - a cos(theta))``; its outward normal is ``(-sin(theta), -cos(theta))``.
``theta`` is used for the chamfer too (the point at the same fraction of the chord).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["ArrisSection"]


@dataclass(frozen=True)
class ArrisSection:
    """One arris's cross-section and the viewpoint.

    Attributes
    ----------
    size_mm : float
        Chamfer leg or rounding radius, mm (> 0).
    profile : str
        ``"chamfer"`` or ``"round"``.
    eye_w, eye_y : float
        The camera centre in the cross-section coordinates, mm (``eye_y < 0``: in front of the hinge face).
    """

    size_mm: float
    profile: str
    eye_w: float
    eye_y: float

    def point(self, theta: np.ndarray | float) -> np.ndarray:
        """``(w, y)`` of the arris at ``theta``, shape (..., 2), mm."""
        a = self.size_mm
        th = np.asarray(theta, float)
        if self.profile == "round":
            return np.stack([a - a * np.sin(th), a - a * np.cos(th)], axis=-1)
        f = th / (0.5 * math.pi)
        return np.stack([a * (1.0 - f), a * f], axis=-1)

    def normal(self, theta: np.ndarray | float) -> np.ndarray:
        """Outward unit normal ``(n_w, n_y)`` at ``theta``, shape (..., 2)."""
        th = np.asarray(theta, float)
        if self.profile == "round":
            return np.stack([-np.sin(th), -np.cos(th)], axis=-1)
        return np.broadcast_to(np.array([-1.0, -1.0]) / math.sqrt(2.0), th.shape + (2,)).copy()

    def visible_arc(self) -> tuple[float, float]:
        """The part ``[theta_a, theta_b]`` of ``[0, pi/2]`` that faces the camera.

        On a rounding the arc ends where the view ray grazes the cylinder (the silhouette) when the
        adjacent face is turned away; on a chamfer the whole face is in view or none of it.
        Returns ``(nan, nan)`` when nothing is in view.
        """
        a = self.size_mm
        if self.profile == "chamfer":
            # front-facing: normal . (p - eye) < 0 at any point of the plane
            n = self.normal(0.0)
            p = self.point(0.0)
            d = float(n @ (p - np.array([self.eye_w, self.eye_y])))
            return (0.0, 0.5 * math.pi) if d < 0 else (math.nan, math.nan)
        # normal(theta) . (point(theta) - eye) < 0  <=>  u1 cos(theta) + u2 sin(theta) > a, with the eye relative
        # to the centre (a, a) written in the (-y, -w) axes of theta
        u1 = -(self.eye_y - a)
        u2 = -(self.eye_w - a)
        r = math.hypot(u1, u2)
        if r <= a:
            return (math.nan, math.nan)
        phi = math.atan2(u2, u1)
        half = math.acos(a / r)
        lo, hi = max(phi - half, 0.0), min(phi + half, 0.5 * math.pi)
        return (lo, hi) if hi > lo else (math.nan, math.nan)

    def on_plane(self, theta: np.ndarray | float, depth_y: float) -> np.ndarray:
        """``w`` where the view ray through the arris at ``theta`` meets the plane ``y = depth_y``, mm.

        The image position of an arris ruling is that of this point: on the hinge face's plane
        (``depth_y = 0``) it is what a flat door would show there.
        """
        p = self.point(theta)
        k = (depth_y - self.eye_y) / (p[..., 1] - self.eye_y)
        return self.eye_w + (p[..., 0] - self.eye_w) * k

    def lambert_basis(self, theta: np.ndarray, light_angle: float) -> np.ndarray:
        """``max(0, cos(angle between the normal and a light at ``light_angle``))`` across the arris.

        ``light_angle`` is the direction towards the light in the cross-section, measured like ``theta``
        (0: along the hinge face's outward normal, pi/2: along the side face's).
        """
        n = self.normal(theta)
        lw, ly = -math.sin(light_angle), -math.cos(light_angle)
        return np.maximum(0.0, n[..., 0] * lw + n[..., 1] * ly)
