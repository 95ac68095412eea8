"""The door's bottom end tells a far face's two readings apart (``vision/bottom_end.py``), on renders."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from doorloc.cell import DoorSize, load_cell
from doorloc.pose import DoorPose, door_to_cell
from doorloc.sim.door import render_door
from doorloc.sim.effects import Effects
from doorloc.vision.bottom_end import (
    MIN_PIXELS,
    BottomEndLevel,
    DoorInView,
    bottom_end_level,
    settled_by_bottom_end,
)

CELL = load_cell(Path(__file__).parents[2] / "fixtures" / "cell_thesis.yaml")
#: the thesis cell's camera sits at X = 30 mm: a door's far face (X = x + T) is in view below that
CAMERA_X_MM = 30.0


def _u(pose: DoorPose, door_pt: list[float], face_y: float) -> float:
    return float(CELL.posed_camera.project_cell(door_to_cell(np.array([door_pt]), pose, face_y))[0, 0])


def _solve(f, t0: float = 20.0, t1: float = 40.0) -> float:
    """The root of ``f`` (a door thickness, mm; ``f`` monotone in it) by secant steps."""
    for _ in range(8):
        f0, f1 = f(t0), f(t1)
        if f1 == f0:
            break
        t0, t1 = t1, t1 - f1 * (t1 - t0) / (f1 - f0)
    return t1


@settings(max_examples=24, deadline=None)
@given(
    thickness=st.floats(24.0, 29.0),
    room=st.floats(0.0, 1.0),
    z=st.floats(-10.0, 10.0),
    yaw=st.floats(-2.0, 2.0),
    far_face_bright=st.booleans(),
)
def test_the_bottom_end_shows_which_reading_is_the_doors(thickness, room, z, yaw, far_face_bright):
    """A far face as bright as the hinge face (ambient light, one albedo) ends in a step, its back edge, that
    also reads as a thicker door's far arris; one as dark as the background in a step, the arris, that also
    reads as a thinner door's back edge. At the bottom end the door's own reading is seen. (The far face in
    view 5-12 mm inside the camera's X when bright, and 1-3 mm when dark: the thinner reading's band must
    reach the arris, and the farther the far face, the wider its band and the thinner that reading.)"""
    x_room = 5.0 + 7.0 * room if far_face_bright else 1.0 + 2.0 * room
    x = max(CAMERA_X_MM - thickness - x_room, -10.0)
    door = DoorSize(900, thickness, 2100)
    pose = DoorPose(x, z, yaw)
    fx = Effects(
        albedo_hinge=0.6,
        albedo_side=0.6 if far_face_bright else 0.15,
        albedo_background=0.15,
        light_ambient=1.0,
        light_directional=0.0,
        read_noise_dn=1.0,
    )
    image = render_door(CELL, door, pose, effects=fx, seed=1).image
    face_y = CELL.face_y(door)
    back_edge = _u(pose, [thickness, 900.0, 0.0], face_y)
    arris = _u(pose, [thickness, 0.0, 0.0], face_y)
    if far_face_bright:  # the back edge read as a thicker door's arris
        pair = (thickness, _solve(lambda t: _u(pose, [t, 0.0, 0.0], face_y) - back_edge))
    else:  # the arris read as a thinner door's back edge
        pair = (_solve(lambda t: _u(pose, [t, 900.0, 0.0], face_y) - arris), thickness)
    in_view = DoorInView(CELL.posed_camera, face_y, pose, 900)
    seen = bottom_end_level(image, 1.0, in_view, pair)
    assert seen is not None and seen.pixels >= MIN_PIXELS, seen
    assert seen.reading(6.0) == ("thinner" if far_face_bright else "thicker"), seen
    other = pair[1] if far_face_bright else pair[0]
    settled, _ = settled_by_bottom_end(image, 1.0, in_view, thickness, other, 6.0)
    assert settled
    # read the other way round, the fitted reading is not the one the bottom end shows
    settled, _ = settled_by_bottom_end(image, 1.0, in_view, other, thickness, 6.0)
    assert not settled


@pytest.mark.parametrize(
    ("seen", "reading"),
    [
        (BottomEndLevel(0.1, 400, 40.0), "thicker"),
        (BottomEndLevel(0.9, 400, 40.0), "thinner"),
        (BottomEndLevel(0.5, 400, 40.0), None),  # between the sides: a shadow, a fixture, a bevel
        (BottomEndLevel(0.9, MIN_PIXELS - 1, 40.0), None),  # too few pixels
        (BottomEndLevel(0.9, 400, 3.0), None),  # the door's bottom end hardly stands out below it
        (BottomEndLevel(float("nan"), 400, 0.0), None),
    ],
)
def test_the_bottom_end_settles_only_where_it_is_clear(seen, reading):
    assert seen.reading(6.0) == reading


def test_no_reading_where_the_hinge_faces_region_runs_past_the_reference_arris():
    door = DoorSize(900, 20.0, 2100)
    pose = DoorPose(-5.0, 0.0, 0.0)
    image = render_door(CELL, door, pose, seed=1).image
    in_view = DoorInView(CELL.posed_camera, CELL.face_y(door), pose, 900)
    assert bottom_end_level(image, 1.0, in_view, (8.0, 20.0)) is None
