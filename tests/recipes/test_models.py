"""Recipe validation: each broken rule is reported with the field and the reason."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from doorloc.cell import DoorSize
from doorloc.recipes.models import DoorRecipe, Hinge, PointCorrection, recipe_problems


def _problems(**over) -> dict[str, str]:
    base = dict(
        door_id="D-1",
        width_mm=900,
        height_mm=2100,
        thickness_mm=50,
        tool_diameter_mm=16,
        spindle_rpm=18000,
        feed_mm_s=25,
        hinges=[Hinge(z_mm=250, length_mm=100, width_mm=30, x_mm=10, depth_mm=3, corner_radius_mm=8)],
    )
    base.update(over)
    r = DoorRecipe.model_validate(base, context={"skip_cross_checks": True})
    return {p.field: p.message for p in recipe_problems(r)}


def test_valid_recipe_has_no_problems_and_a_door_size(recipe_factory):
    r = recipe_factory()
    assert recipe_problems(r) == []
    assert r.door_size() == DoorSize(900.0, 50.0, 2100.0, 1.0)


@pytest.mark.parametrize(
    ("over", "field", "words"),
    [
        (
            {
                "hinges": [
                    Hinge(z_mm=250, length_mm=100, width_mm=30, x_mm=25, depth_mm=3, corner_radius_mm=8)
                ]
            },
            "hinges[0].width_mm",
            "wider than the door thickness",
        ),
        (
            {
                "hinges": [
                    Hinge(z_mm=2050, length_mm=100, width_mm=30, x_mm=10, depth_mm=3, corner_radius_mm=8)
                ]
            },
            "hinges[0].length_mm",
            "above the door top",
        ),
        (
            {
                "hinges": [
                    Hinge(z_mm=250, length_mm=100, width_mm=30, x_mm=10, depth_mm=950, corner_radius_mm=8)
                ]
            },
            "hinges[0].depth_mm",
            "less than the door width",
        ),
        (
            {
                "hinges": [
                    Hinge(z_mm=250, length_mm=100, width_mm=30, x_mm=10, depth_mm=3, corner_radius_mm=16)
                ]
            },
            "hinges[0].corner_radius_mm",
            "exceeds half",
        ),
        ({"tool_diameter_mm": 20}, "tool_diameter_mm", "does not fit hinge 1's corner radius 8 mm"),
        (
            {
                "tool_diameter_mm": 12,
                "hinges": [
                    Hinge(z_mm=250, length_mm=100, width_mm=30, x_mm=10, depth_mm=3, corner_radius_mm=8)
                ],
            },
            "hinges[0].width_mm",
            "uncut island",
        ),
        (
            {
                "hinges": [
                    Hinge(z_mm=250, length_mm=100, width_mm=30, x_mm=10, depth_mm=3, corner_radius_mm=8),
                    Hinge(z_mm=340, length_mm=100, width_mm=30, x_mm=15, depth_mm=3, corner_radius_mm=8),
                ]
            },
            "hinges[1].z_mm",
            "overlaps hinge 1",
        ),
        ({"arris_mm": 25}, "arris_mm", "half the thickness"),
    ],
)
def test_each_rule_names_field_and_reason(over, field, words):
    problems = _problems(**over)
    assert field in problems, problems
    assert words in problems[field]


def test_side_by_side_hinges_at_same_height_do_not_overlap():
    hs = [
        Hinge(z_mm=250, length_mm=100, width_mm=20, x_mm=0, depth_mm=3, corner_radius_mm=8),
        Hinge(z_mm=250, length_mm=100, width_mm=20, x_mm=25, depth_mm=3, corner_radius_mm=8),
    ]
    assert _problems(hinges=hs) == {}


def test_constructing_a_bad_recipe_raises_with_field_names():
    with pytest.raises(ValidationError) as ei:
        DoorRecipe(
            door_id="D-1",
            width_mm=900,
            height_mm=2100,
            thickness_mm=50,
            tool_diameter_mm=16,
            spindle_rpm=18000,
            feed_mm_s=25,
            hinges=[Hinge(z_mm=250, length_mm=100, width_mm=30, x_mm=30, depth_mm=3, corner_radius_mm=8)],
        )
    assert "hinges[0].width_mm" in str(ei.value) and "x_mm + width_mm must be <= thickness" in str(ei.value)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"depth_mm": 0}, "depth_mm"),
        ({"depth_mm": -1}, "depth_mm"),
        ({"length_mm": 0}, "length_mm"),
        ({"path_points": 7}, "path_points"),
        ({"corrections": [PointCorrection()] * 5}, "corrections"),
    ],
)
def test_field_rules_of_a_hinge(kwargs, field):
    base = dict(z_mm=250, length_mm=100, width_mm=30, x_mm=10, depth_mm=3, corner_radius_mm=8)
    base.update(kwargs)
    with pytest.raises(ValidationError) as ei:
        Hinge(**base)
    assert ei.value.errors()[0]["loc"][0] == field


@pytest.mark.parametrize("door_id", ["", "a b", "x;y", "-lead", "é"])
def test_door_ids_are_barcode_safe(recipe_factory, door_id):
    with pytest.raises(ValidationError):
        recipe_factory(door_id=door_id)
