"""A rounded arris is rendered exactly: pixel values against an independent ray cast of the cylinder."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from doorloc.arris import ArrisSection
from doorloc.cell import DoorSize, load_cell
from doorloc.pose import DoorPose, yaw_rotation_matrix
from doorloc.sim.door import render_door
from doorloc.sim.effects import Effects

# a distortion-free camera: pixel -> ray is K^-1 exactly
CELL = load_cell(Path(__file__).parents[2] / "fixtures" / "rendered" / "effects" / "cell.yaml")


def _ray_cast_row(
    cell, door: DoorSize, pose: DoorPose, fx: Effects, row: int, cols: np.ndarray, k: int = 128
):
    """Box-filtered radiance of pixels on one image row near the reference arris, by ray casting k x k
    sub-samples per pixel against the hinge face, the quarter cylinder and the background (no texture)."""
    K = np.asarray(cell.camera.camera_matrix, float)
    ext = cell.extrinsics
    R, centre = ext.rotation, ext.camera_centre_cell
    Ryaw = yaw_rotation_matrix(pose.yaw_deg)
    face_y = cell.face_y(door)
    eye = Ryaw.T @ (centre - np.array([pose.x_mm, face_y, pose.z_mm]))
    a = door.arris_mm
    light = fx.light_direction_cell()
    d = (np.arange(k) + 0.5) / k - 0.5
    out = []
    for u in cols:
        uu, vv = np.meshgrid(u + d, row + d)
        pix = np.stack([uu.ravel(), vv.ravel(), np.ones(uu.size)], axis=1)
        rays = (pix @ np.linalg.inv(K).T) @ R  # camera -> cell directions
        rays = rays @ Ryaw  # cell -> door directions (Ryaw.T applied to row vectors)
        # cylinder (x - a)^2 + (y - a)^2 = a^2 about the door Z axis: first hit
        ox, oy = eye[0] - a, eye[1] - a
        dx, dy = rays[:, 0], rays[:, 1]
        qa = dx * dx + dy * dy
        qb = 2 * (ox * dx + oy * dy)
        qc = ox * ox + oy * oy - a * a
        disc = qb * qb - 4 * qa * qc
        t_cyl = np.where(disc >= 0, (-qb - np.sqrt(np.maximum(disc, 0))) / (2 * qa), np.inf)
        px, py = eye[0] + t_cyl * dx, eye[1] + t_cyl * dy
        on_arris = np.isfinite(t_cyl) & (px <= a) & (py <= a)
        t_face = -eye[1] / dy
        on_face = ~on_arris & (eye[0] + t_face * dx >= a)
        px, py = np.where(on_arris, px, a), np.where(on_arris, py, 0.0)
        n_door = np.stack([(px - a) / a, (py - a) / a, np.zeros_like(px)], axis=1)
        # the directional term under the finish: max(0, n.l) to the power finish_exponent
        p = fx.finish_exponent
        cos = np.maximum(0.0, (n_door @ Ryaw.T) @ light) ** p
        cos_face = max(0.0, float((Ryaw @ [0, -1.0, 0]) @ light)) ** p
        val = np.where(
            on_arris,
            fx.albedo_chamfer * (fx.light_ambient + fx.light_directional * cos),
            np.where(
                on_face,
                fx.albedo_hinge * (fx.light_ambient + fx.light_directional * cos_face),
                fx.albedo_background,
            ),
        )
        out.append(val.mean())
    return np.array(out)


@pytest.mark.parametrize(
    "azimuth,yaw,finish", [(40.0, 0.0, 1.0), (-55.0, 1.2, 1.0), (40.0, 0.0, 0.5), (-55.0, 1.2, 2.0)]
)
def test_rounded_arris_matches_a_ray_cast_of_the_cylinder(azimuth, yaw, finish):
    # finish: the renderer's finish_exponent (1 a matt surface; 0.5 a rough finish's flatter shading, 2 a
    # satin one's peaked shading)
    door = DoorSize(900, 50, 2100, arris_mm=2.5, arris_profile="round")
    pose = DoorPose(1.5, -2.0, yaw)
    fx = Effects(
        arris_profile="round",
        light_ambient=0.45,
        light_directional=0.5,
        light_azimuth_deg=azimuth,
        light_elevation_deg=20.0,
        finish_exponent=finish,
    )
    rd = render_door(CELL, door, pose, effects=fx)
    u0, v0 = rd.corner_px
    row = int(v0) - 250  # well above the bottom end
    # where the reference arris crosses this row: the columns around the strip
    start = int(np.argmax(rd.radiance[row, int(u0) - 40 :] > fx.albedo_background + 1e-6)) + int(u0) - 40
    cols = np.arange(start - 2, start + 16)
    ref = _ray_cast_row(CELL, door, pose, fx, row, cols)
    got = rd.radiance[row, cols]
    # the strip is shaded (not flat) and both agree pixel by pixel and in the integral
    assert np.ptp(got[3:12]) > 0.02
    assert np.max(np.abs(got - ref)) < 1.5e-3
    assert abs(np.sum(got - ref)) < 1e-3


def test_silhouette_of_a_rounding_lies_outside_the_chamfer_outline():
    # seen from the camera (X = 30 mm in front), the cylinder bulges beyond its chord
    sec = ArrisSection(3.0, "round", eye_w=30.0, eye_y=-350.0)
    th_a, th_b = sec.visible_arc()
    assert th_a == 0.0 and 1.4 < th_b < np.pi / 2
    assert sec.on_plane(th_b, 3.0) < 0.0 < sec.on_plane(0.0, 3.0)
    chamfer = ArrisSection(3.0, "chamfer", eye_w=30.0, eye_y=-350.0)
    assert chamfer.on_plane(np.pi / 2, 3.0) == pytest.approx(0.0, abs=1e-12)


def test_rounded_arris_render_is_deterministic():
    door = DoorSize(900, 50, 2100, arris_mm=3.0, arris_profile="round")
    fx = Effects(arris_profile="round", light_directional=0.5, light_ambient=0.5)
    a = render_door(CELL, door, DoorPose(2.0, 1.0, 0.5), effects=fx).image
    b = render_door(CELL, door, DoorPose(2.0, 1.0, 0.5), effects=fx).image
    assert np.array_equal(a, b)


def test_a_matt_finish_is_the_default_and_a_finish_is_validated():
    door = DoorSize(900, 50, 2100, arris_mm=2.0, arris_profile="round")
    lit = dict(arris_profile="round", light_directional=0.5, light_ambient=0.4, light_azimuth_deg=50.0)
    a = render_door(CELL, door, DoorPose(0.0, 0.0, 0.0), effects=Effects(**lit)).image
    b = render_door(CELL, door, DoorPose(0.0, 0.0, 0.0), effects=Effects(**lit, finish_exponent=1.0)).image
    rough = render_door(
        CELL, door, DoorPose(0.0, 0.0, 0.0), effects=Effects(**lit, finish_exponent=0.5)
    ).image
    assert np.array_equal(a, b)
    assert not np.array_equal(a, rough)
    with pytest.raises(ValueError, match="finish_exponent"):
        Effects(finish_exponent=0.0)
