"""The arris size and profile reach locate from every source: recipe (+ cell profile), manifest, CLI, HTTP."""

from __future__ import annotations

import dataclasses

import pytest
from fastapi.testclient import TestClient

from doorloc.app.answer import DoorChoice, door_from_fields
from doorloc.app.batch import BatchSetupError, plan_batch
from doorloc.app.http import create_app
from doorloc.app.services import resolve_door
from doorloc.cell import DoorSize

from .conftest import dev_settings, stand_in_locate


@pytest.fixture
def round_cell(cell):
    return dataclasses.replace(cell, default_door=DoorSize(900, 50, 2100, 1.5, "round"))


def test_recipe_gives_the_size_and_the_cell_the_profile(round_cell, recipe):
    r = recipe.model_copy(update={"arris_mm": 2.0})
    door = DoorChoice.from_recipe(r, round_cell).door
    assert (door.arris_mm, door.arris_profile) == (2.0, "round")
    assert DoorChoice.from_recipe(r, round_cell, arris_mm=0.5).door.arris_mm == 0.5
    assert DoorChoice.from_recipe(r).door.arris_profile == "chamfer"  # no cell: the recipe's own default


def test_sizes_take_the_cell_default_arris_unless_given(round_cell):
    assert door_from_fields(round_cell, 800, 45).arris_mm == 1.5
    d = door_from_fields(round_cell, 800, 45, arris_mm=0.0, arris_profile="chamfer")
    assert (d.arris_mm, d.arris_profile) == (0.0, "chamfer")
    with pytest.raises(ValueError, match="arris_profile"):
        door_from_fields(round_cell, 800, 45, arris_profile="bevel")


def test_cli_door_arris_and_profile(round_cell):
    # what `doorloc locate --door-width 800 --door-thickness 45 [--door-arris 2.5 --arris-profile chamfer]` asks
    c = resolve_door(round_cell, None, width_mm=800, thickness_mm=45, arris_mm=2.5, arris_profile="chamfer")
    assert (c.door.arris_mm, c.door.arris_profile) == (2.5, "chamfer")
    c = resolve_door(round_cell, None, width_mm=800, thickness_mm=45)
    assert (c.door.arris_mm, c.door.arris_profile) == (1.5, "round")


def test_manifest_column_arris_mm(tmp_path, round_cell):
    root = tmp_path / "imgs"
    root.mkdir()
    m = tmp_path / "m.csv"
    m.write_text("image,width_mm,thickness_mm,arris_mm\na.png,900,50,2.25\nb.png,900,50,\n")
    items = plan_batch(root, round_cell, m)
    assert [(it.choice.door.arris_mm, it.choice.door.arris_profile) for it in items] == [
        (2.25, "round"),
        (1.5, "round"),
    ]
    m.write_text("image,width_mm,thickness_mm,arris_mm\na.png,900,50,-1\n")
    with pytest.raises(BatchSetupError, match="line 2"):
        plan_batch(root, round_cell, m)


def test_http_form_field_arris_mm(round_cell, store, small_png):
    seen = []

    def capture(image, cell, door, **kw):
        seen.append(door)
        return stand_in_locate(image, cell, door, **kw)

    app = create_app(dev_settings(), cell=round_cell, store=store, locate_fn=capture)
    with TestClient(app) as c:
        r = c.post(
            "/v1/locate",
            files={"image": ("d.png", small_png, "image/png")},
            data={"width_mm": "800", "thickness_mm": "45", "arris_mm": "2.5"},
        )
        assert r.status_code == 200, r.text
        r = c.post(
            "/v1/locate",
            files={"image": ("d.png", small_png, "image/png")},
            data={"door_id": "D-100", "arris_mm": "0.75"},
        )
        assert r.status_code == 200, r.text
        r = c.post("/v1/locate", files={"image": ("d.png", small_png, "image/png")}, data={"arris_mm": "-1"})
        assert r.status_code == 422
    assert [(d.arris_mm, d.arris_profile) for d in seen] == [(2.5, "round"), (0.75, "round")]
