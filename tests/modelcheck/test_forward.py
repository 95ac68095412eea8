"""The analytic forward model: exact answers for effects whose pose error is known in closed form."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from doorloc.cell import DoorSize, load_cell
from doorloc.modelcheck.catalogue import CATALOGUE, EFFECT_NAMES, apply_effects, effect
from doorloc.modelcheck.dataset import MeasuredImage
from doorloc.modelcheck.forward import AnalyticModel, Observation
from doorloc.pose import DoorPose

CELL = load_cell(Path(__file__).resolve().parents[2] / "fixtures" / "cell_thesis.yaml")


def _obs(pose: DoorPose, door: DoorSize) -> Observation:
    item = MeasuredImage("a.png", Path("a.png"), door, pose)
    ranges = {"bottom": (2.0, door.thickness_mm - 2.0), "reference": (1.0, 80.0), "far": (1.0, 80.0)}
    z = np.zeros(4)
    return Observation(item, None, True, "", z, z, np.zeros(2), ranges, np.zeros((0, 2)), np.zeros(0))


poses = st.builds(DoorPose, st.floats(-10, 10), st.floats(-10, 10), st.floats(-2, 2))
doors = st.builds(lambda w, t: DoorSize(w, t, 2100.0), st.floats(600, 1200), st.floats(30, 100))


def test_catalogue_has_the_spec_names():
    assert EFFECT_NAMES == (
        "camera_roll",
        "camera_tilt",
        "camera_distance",
        "lateral_offset",
        "focal_length",
        "pixel_aspect",
        "radial_distortion",
        "arris",
        "fixture_depth",
        "response_gamma",
    )
    with pytest.raises(ValueError, match="catalogue"):
        effect("lens_flare")


@settings(max_examples=25, deadline=None)
@given(poses, doors)
def test_nominal_values_predict_no_error(pose, door):
    m = AnalyticModel([_obs(pose, door)], CELL, measured_arris=True)
    for e in CATALOGUE:
        if e.forward == "analytic":
            assert np.allclose(m.predict([e], [e.nominal(CELL)]), 0.0, atol=1e-9), e.name


@settings(max_examples=25, deadline=None)
@given(poses, doors, st.floats(-0.5, 0.5))
def test_roll_about_an_axis_normal_to_the_face_turns_the_yaw_by_the_roll(pose, door, roll):
    # the reference mount looks along +Y, normal to the hinge face: a roll turns the image of that plane
    err = AnalyticModel([_obs(pose, door)], CELL, measured_arris=True).predict(
        [effect("camera_roll")], [[roll]]
    )[0]
    assert abs(abs(err[2]) - abs(roll)) < 1e-6 + 1e-4 * abs(roll)
    assert abs(err[3]) < 1e-6  # a rotation in the plane keeps the thickness


@settings(max_examples=25, deadline=None)
@given(poses, doors, st.floats(-5, 5), st.floats(-5, 5))
def test_a_lateral_camera_shift_shifts_the_measured_corner_the_other_way(pose, door, dx, dz):
    err = AnalyticModel([_obs(pose, door)], CELL, measured_arris=True).predict(
        [effect("lateral_offset")], [[dx, dz]]
    )[0]
    assert np.allclose(err, [-dx, -dz, 0.0, 0.0], atol=1e-6)


def test_apply_effects_puts_values_where_the_catalogue_says():
    c = apply_effects(
        CELL,
        {
            "focal_length": [1.0],
            "fixture_depth": [0.02],
            "response_gamma": [2.2],
            "arris": [1.5],
            "radial_distortion": [0.05],
        },
    )
    assert c.camera.fx == pytest.approx(CELL.camera.fx * 1.01) and c.camera.fy == pytest.approx(
        CELL.camera.fy * 1.01
    )
    assert c.fixture.face_shift_per_width == pytest.approx(CELL.fixture.face_shift_per_width + 0.02)
    assert c.response_gamma == 2.2 and c.default_door.arris_mm == 1.5 and c.camera.dist_coeffs[0] == 0.05


def test_locate_works_in_a_cell_with_barrel_distortion():
    # A barrel k1 folds far points back into the image: the search region once took them for the top
    # of the reference arris and locate found no edge (the extended cell of a radial_distortion check).
    from doorloc.sim.door import render_door
    from doorloc.vision.locate import locate

    barrel = effect("radial_distortion").apply(CELL, [-0.15])
    door, pose = DoorSize(900, 50, 2100), DoorPose(3.0, -4.0, 0.7)
    r = locate(render_door(barrel, door, pose).image, barrel, door)
    assert r.ok, r.error
    assert abs(r.x_mm - 3.0) < 0.01 and abs(r.z_mm + 4.0) < 0.01 and abs(r.yaw_deg - 0.7) < 0.005
