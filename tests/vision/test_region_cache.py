"""The search region is built once per (camera, extrinsics, fixture, envelope, door, margins) and rebuilt when any changes."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from doorloc.calib.camera import CameraModel, Extrinsics
from doorloc.cell import DoorSize, Envelope, load_cell
from doorloc.vision.region import SearchRegion


@pytest.fixture(scope="module")
def cell(thesis_cell_path):
    return load_cell(thesis_cell_path)


def _same_geometry(a: SearchRegion, b: SearchRegion) -> bool:
    ba, bb = a.arris_band(4, 45.0), b.arris_band(4, 45.0)
    return (
        a.face_y == b.face_y
        and a.layouts == b.layouts
        and np.array_equal(ba.scan, bb.scan)
        and np.array_equal(ba.lo, bb.lo)
        and np.array_equal(ba.hi, bb.hi)
    )


def test_the_same_cell_and_door_share_one_region_equal_to_a_fresh_build(cell):
    door = DoorSize(900, 50, 2100)
    a = SearchRegion.cached(cell, door, 30.0, 6.0)
    assert SearchRegion.cached(cell, DoorSize(900, 50, 2100), 30.0, 6.0) is a
    assert _same_geometry(a, SearchRegion.build(cell, door, 30.0, 6.0))


@pytest.mark.parametrize("change", ["extrinsics", "camera", "envelope", "door", "margin", "fixture"])
def test_any_change_that_moves_the_region_gives_a_new_one(cell, change):
    door = DoorSize(900, 50, 2100)
    base = SearchRegion.cached(cell, door, 30.0, 6.0)
    c2, d2, m2 = cell, door, 30.0
    if change == "extrinsics":
        c2 = cell.with_extrinsics(Extrinsics(cell.extrinsics.rvec, cell.extrinsics.tvec_mm + [5.0, 0.0, 0.0]))
    elif change == "camera":  # a new calibration in a cell object that keeps the file's hash
        c2 = replace(
            cell,
            camera=CameraModel(
                cell.camera.camera_matrix, np.array([-0.05, 0, 0, 0, 0.0]), cell.camera.image_size
            ),
        )
        assert c2.sha256 == cell.sha256
    elif change == "envelope":
        c2 = replace(cell, envelope=Envelope(12.0, 10.0, 2.0))
    elif change == "door":
        d2 = DoorSize(1000, 50, 2100)
    elif change == "margin":
        m2 = 31.0
    elif change == "fixture":
        c2 = replace(cell, fixture=replace(cell.fixture, face_y_mm=20.0))
    other = SearchRegion.cached(c2, d2, m2, 6.0)
    assert other is not base
    assert _same_geometry(other, SearchRegion.build(c2, d2, m2, 6.0))
    assert not _same_geometry(other, base)


def test_cached_bands_cannot_be_changed_by_a_caller(cell):
    band = SearchRegion.cached(cell, DoorSize(900, 50, 2100), 30.0, 6.0).arris_band(4, 45.0)
    with pytest.raises(ValueError):
        band.lo[0] = 0


@pytest.mark.parametrize("yaw_deg", [-1.5, 0.0, 2.0])
@pytest.mark.parametrize("arris", [0.0, 2.0])
def test_thickness_behind_far_face_undoes_the_back_edge_projection(cell, yaw_deg, arris):
    """A far face in view: its back edge (depth face_y + W), projected through the camera onto the plane the
    edges are measured on, lies beyond the far arris; from that distance the door's thickness comes back."""
    from doorloc.vision.metric import PlaneMap

    door = DoorSize(900, 40, 2100, arris_mm=arris)
    region = SearchRegion.build(cell, door, 30.0, 6.0)
    yaw = np.radians(yaw_deg)
    ex, ez = np.array([np.cos(yaw), np.sin(yaw)]), np.array([-np.sin(yaw), np.cos(yaw)])
    centre = region.plane_map.centre
    # the camera 6 mm beyond the far face's plane (door +X), the corner below it
    corner = centre[[0, 2]] - (door.thickness_mm + 6.0) * ex - 200.0 * ez
    back = corner + door.thickness_mm * ex + 150.0 * ez  # a point of the far face's back edge (X, Z)
    uv = PlaneMap(cell.posed_camera, region.face_y + door.width_mm).to_image(back[None])
    seen = region.plane_map.to_plane(uv)[0]
    measured = float((seen - corner) @ ex)
    assert measured > door.thickness_mm + 0.05  # the back edge looks farther out than the far arris
    assert region.thickness_behind_far_face(corner, yaw, measured) == pytest.approx(
        door.thickness_mm, abs=1e-6
    )
    # no far face in view (the camera inside its plane): no such reading
    inside = centre[[0, 2]] - (door.thickness_mm - 6.0) * ex - 200.0 * ez
    assert region.thickness_behind_far_face(inside, yaw, door.thickness_mm + 0.5) is None
