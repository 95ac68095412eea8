"""Rendered doors: geometry of the solid, the true corner, visible faces, determinism."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from doorloc.cell import DoorSize, load_cell
from doorloc.pose import DoorPose
from doorloc.sim.door import door_faces, render_door, true_corner_px
from doorloc.sim.effects import Effects

CELL = load_cell(Path(__file__).parents[2] / "fixtures" / "cell_thesis.yaml")


def test_nominal_corner_is_where_the_cell_file_says():
    rd = render_door(CELL, DoorSize(900, 50, 2100), DoorPose())
    assert np.allclose(rd.corner_px, [802.55, 708.11], atol=0.05)
    assert rd.truth["visible_faces"] == ["hinge_face"]
    u, v = rd.corner_px
    img = rd.image.astype(float)
    hinge, bg = round(255 * Effects().albedo_hinge), round(255 * Effects().albedo_background)
    # just inside the corner: hinge face; left of and below it: background
    assert img[int(v) - 5, int(u) + 5] == hinge
    assert img[int(v) - 5, int(u) - 5] == bg
    assert img[int(v) + 5, int(u) + 5] == bg


@pytest.mark.parametrize("arris,profile,n_faces", [(0.0, "chamfer", 6), (2.0, "chamfer", 13), (2.0, "round", 55)])
def test_door_solid_is_closed_and_convex(arris, profile, n_faces):
    door = DoorSize(800, 40, 2000, arris_mm=arris)
    faces = door_faces(door, profile)
    assert len(faces) == n_faces
    pts = np.concatenate([f.polygon for f in faces])
    # every vertex lies inside every face's half-space (convexity) and within the nominal box
    for f in faces:
        d = (pts - f.polygon[0]) @ f.normal
        assert d.max() < 1e-9
    assert pts.min(axis=0) == pytest.approx([0, 0, 0], abs=1e-9)
    assert pts.max(axis=0) == pytest.approx([40, 800, 2000], abs=1e-9)
    # closed surface: the area-weighted normals sum to zero
    total = sum(0.5 * np.sum(np.cross(f.polygon, np.roll(f.polygon, -1, axis=0)), axis=0) for f in faces)
    assert np.allclose(total, 0, atol=1e-6 * 2000 * 800)


def test_thin_door_shows_its_far_face_and_thick_door_does_not():
    # the camera centre is at cell X = 30: a 20 mm door (X in [0, 20]) shows its far face X = T
    thin = render_door(CELL, DoorSize(900, 20, 2100), DoorPose())
    thick = render_door(CELL, DoorSize(900, 60, 2100), DoorPose())
    assert "far_face" in thin.truth["visible_faces"]
    assert "far_face" not in thick.truth["visible_faces"]
    assert "reference_face" not in thick.truth["visible_faces"]


def test_pose_moves_the_corner_as_the_projection_says():
    pose = DoorPose(7.0, -4.0, 1.5)
    door = DoorSize(1000, 45, 2100)
    rd = render_door(CELL, door, pose)
    assert np.allclose(rd.corner_px, true_corner_px(CELL, door, pose))
    # +X is image-right and +Z image-up at ~0.2056 mm/px
    nominal = true_corner_px(CELL, door, DoorPose())
    assert rd.corner_px[0] - nominal[0] > 25 and rd.corner_px[1] - nominal[1] > 10
    assert rd.truth["face_y_mm"] == pytest.approx(-50.0)


def test_same_seed_same_bytes():
    fx = Effects(grain_contrast=0.1, read_noise_dn=1.5, full_well_e=20000, blur_sigma_px=0.7)
    cam_cell = CELL
    a = render_door(cam_cell, DoorSize(), DoorPose(1, 2, 0.5), effects=fx, seed=11)
    b = render_door(cam_cell, DoorSize(), DoorPose(1, 2, 0.5), effects=fx, seed=11)
    c = render_door(cam_cell, DoorSize(), DoorPose(1, 2, 0.5), effects=fx, seed=12)
    assert a.image.tobytes() == b.image.tobytes()
    assert a.image.tobytes() != c.image.tobytes()
