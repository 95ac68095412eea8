"""A recipe's spindle speed, feed and hinge depths are bounded by the cell's spindle and cutter (the cell file's
``milling:`` section, doorloc's defaults where it says nothing), and every refusal names the bound and where it
came from."""

from __future__ import annotations

from dataclasses import replace

import pytest
import yaml
from fastapi.testclient import TestClient
from typer.testing import CliRunner

from doorloc.app.cli import app as cli_app
from doorloc.app.http import create_app
from doorloc.cell import CellFileError, cell_to_dict, load_cell, parse_cell
from doorloc.limits import DEFAULT_MILLING_LIMITS, FEED_RANGE_MM_S, SPINDLE_RPM_RANGE, TOOL_REACH_MM
from doorloc.recipes.importer import RecipeImportError, load_recipe_file
from doorloc.recipes.models import MILLING, DoorRecipe, milling_problems
from doorloc.recipes.store import RecipeStore

from .conftest import CELL_PATH, dev_settings, stand_in_locate

WIDE = {"spindle_rpm": [6000, 40000], "feed_mm_s": [1, 800], "tool_reach_mm": 32}


def _cell_file(tmp_path, milling: dict | None):
    doc = yaml.safe_load(CELL_PATH.read_text())
    if milling is not None:
        doc["milling"] = milling
    calibration = doc["camera"].get("calibration")
    if calibration is not None:
        doc["camera"]["calibration"] = str(CELL_PATH.parent / calibration)
    p = tmp_path / "cell.yaml"
    p.write_text(yaml.safe_dump(doc))
    return p


def _body(recipe: DoorRecipe, **change) -> dict:
    body = recipe.model_dump(mode="json")
    depth = change.pop("depth_mm", None)
    if depth is not None:
        body["hinges"] = [h | {"depth_mm": depth} for h in body["hinges"]]
    return body | change


def test_a_cell_without_a_milling_section_has_the_documented_defaults(cell):
    assert replace(cell.milling, source=None) == DEFAULT_MILLING_LIMITS
    assert (cell.milling.spindle_rpm, cell.milling.feed_mm_s, cell.milling.tool_reach_mm) == (
        SPINDLE_RPM_RANGE,
        FEED_RANGE_MM_S,
        TOOL_REACH_MM,
    )
    assert "milling" not in cell_to_dict(cell)


def test_the_milling_section_sets_each_bound_and_leaves_the_others_default(tmp_path):
    cell = load_cell(_cell_file(tmp_path, {"spindle_rpm": [6000, 24000]}))
    assert cell.milling.spindle_rpm == (6000, 24000)
    assert cell.milling.feed_mm_s == FEED_RANGE_MM_S and cell.milling.tool_reach_mm == TOOL_REACH_MM
    assert "milling.spindle_rpm in" in cell.milling.origin("spindle_rpm")
    assert str(tmp_path / "cell.yaml") in cell.milling.origin("spindle_rpm")
    assert "default" in cell.milling.origin("feed_mm_s")
    # written back as given, and read again the same
    again = parse_cell(cell_to_dict(cell), source="again.yaml")
    assert cell_to_dict(cell)["milling"] == {"spindle_rpm": [6000, 24000]}
    assert replace(again.milling, source=cell.milling.source) == cell.milling


@pytest.mark.parametrize(
    ("milling", "words"),
    [
        ({"rpm": [1000, 2000]}, ["unknown key 'milling.rpm'", "spindle_rpm, feed_mm_s, tool_reach_mm"]),
        ({"spindle_rpm": [24000, 6000]}, ["spindle_rpm", "lowest < highest"]),
        ({"feed_mm_s": [1, 50000]}, ["feed_mm_s", "5000"]),
        ({"tool_reach_mm": 0}, ["tool_reach_mm"]),
        ({"tool_reach_mm": ".nan"}, ["tool_reach_mm"]),
        ({"spindle_rpm": [1000]}, ["spindle_rpm"]),
    ],
)
def test_a_bad_milling_section_is_an_error_naming_the_key(tmp_path, milling, words):
    with pytest.raises(CellFileError) as e:
        load_cell(_cell_file(tmp_path, milling))
    assert all(w in str(e.value) for w in words), str(e.value)


@pytest.mark.parametrize(
    ("change", "bound"),
    [
        ({"spindle_rpm": 45000}, "6000-40000 rev/min"),
        ({"spindle_rpm": 5000}, "6000-40000 rev/min"),
        ({"feed_mm_s": 900}, "1-800 mm/s"),
        ({"depth_mm": 33}, "tool_reach_mm 32 mm"),
    ],
)
def test_a_recipe_beyond_the_cells_bounds_is_refused_naming_the_bound_and_the_file(
    tmp_path, recipe, change, bound
):
    cell = load_cell(_cell_file(tmp_path, WIDE))
    with pytest.raises(ValueError) as e:
        DoorRecipe.model_validate(_body(recipe, **change), context={MILLING: cell.milling})
    assert bound in str(e.value) and f"in {tmp_path / 'cell.yaml'}" in str(e.value), str(e.value)


def test_a_cell_may_widen_the_defaults_and_the_defaults_still_hold_without_it(tmp_path, recipe):
    cell = load_cell(_cell_file(tmp_path, WIDE))
    for change, words in (
        ({"spindle_rpm": 36000}, "30000 rev/min"),
        ({"feed_mm_s": 700}, "500 mm/s"),
        ({"depth_mm": 30}, "tool_reach_mm 25 mm"),
    ):
        body = _body(recipe, **change)
        assert DoorRecipe.model_validate(body, context={MILLING: cell.milling}).door_id == "D-100"
        with pytest.raises(ValueError) as e:
            DoorRecipe.model_validate(body)
        assert words in str(e.value) and "doorloc's default" in str(e.value), str(e.value)


def test_milling_problems_name_each_bound(recipe):
    tight = replace(
        DEFAULT_MILLING_LIMITS,
        spindle_rpm=(1000, 12000),
        tool_reach_mm=2.5,
        stated=frozenset({"spindle_rpm", "tool_reach_mm"}),
        source="c.yaml",
    )
    problems = milling_problems(recipe, tight)
    assert [p.field for p in problems] == ["spindle_rpm", "hinges[0].depth_mm", "hinges[1].depth_mm"]
    assert "milling.spindle_rpm in c.yaml" in problems[0].message
    assert milling_problems(recipe, DEFAULT_MILLING_LIMITS) == []


def _app(cell, store) -> TestClient:
    app = create_app(dev_settings(), cell=cell, store=store, locate_fn=stand_in_locate)
    c = TestClient(app, raise_server_exceptions=False)
    c.__enter__()
    return c


def test_the_service_stores_what_its_cell_allows_and_refuses_the_rest_naming_the_bound(tmp_path, recipe):
    cell = load_cell(_cell_file(tmp_path, WIDE))
    with RecipeStore("sqlite://") as store:
        c = _app(cell, store)
        try:
            ok = c.put("/v1/doors/D-100", json=_body(recipe, spindle_rpm=36000, depth_mm=30))
            assert ok.status_code == 200, ok.text
            assert c.get("/v1/doors/D-100").json()["spindle_rpm"] == 36000
            r = c.put("/v1/doors/D-100", json=_body(recipe, feed_mm_s=900))
            assert r.status_code == 422 and r.json()["code"] == "invalid_request"
            assert "feed_mm_s" in r.json()["detail"] and "1-800 mm/s" in r.json()["detail"], r.json()
            assert "milling.feed_mm_s" in r.json()["detail"]
            assert c.get("/v1/doors/D-100").json()["feed_mm_s"] == 25
            # the documented body is still the recipe
            schema = c.get("/openapi.json").json()["paths"]["/v1/doors/{door_id}"]["put"]["requestBody"]
            assert schema["content"]["application/json"]["schema"]["$ref"].endswith("/DoorRecipe")
        finally:
            c.__exit__(None, None, None)


def test_a_stored_recipe_beyond_the_cell_is_unusable_for_locate(tmp_path, recipe, small_png):
    wide = load_cell(_cell_file(tmp_path, WIDE))
    tight = replace(wide, milling=replace(wide.milling, spindle_rpm=(1000, 24000)))
    with RecipeStore("sqlite://") as store:
        store.put(
            DoorRecipe.model_validate(_body(recipe, spindle_rpm=36000), context={MILLING: wide.milling})
        )
        assert store.get("D-100").spindle_rpm == 36000  # read back whatever cell wrote it
        c = _app(tight, store)
        try:
            r = c.post(
                "/v1/locate", files={"image": ("d.png", small_png, "image/png")}, data={"door_id": "D-100"}
            )
            assert r.status_code == 422 and r.json()["code"] == "unusable_recipe", r.text
            assert "1000-24000 rev/min" in r.json()["detail"]
        finally:
            c.__exit__(None, None, None)


HEADER = (
    "door_id,width_mm,height_mm,thickness_mm,hinge_z_mm,hinge_length_mm,hinge_width_mm,hinge_x_mm,"
    "hinge_depth_mm,hinge_corner_radius_mm,tool_diameter_mm,spindle_rpm,feed_mm_s"
)


def test_import_checks_against_the_cell_it_is_given(tmp_path):
    wide = load_cell(_cell_file(tmp_path, WIDE))
    p = tmp_path / "r.csv"
    p.write_text(HEADER + "\nA-1,900,2100,50,250,100,30,10,30,8,16,36000,25\n")
    with pytest.raises(RecipeImportError) as e:
        load_recipe_file(p)
    assert {i.column for i in e.value.issues} == {"spindle_rpm"}
    deep = tmp_path / "deep.csv"
    deep.write_text(HEADER + "\nA-1,900,2100,50,250,100,30,10,30,8,16,18000,25\n")
    with pytest.raises(RecipeImportError) as e:
        load_recipe_file(deep)
    assert [i.column for i in e.value.issues] == ["hinge_depth_mm"] and "tool_reach_mm 25" in str(e.value)
    assert load_recipe_file(p, wide.milling)[0].spindle_rpm == 36000
    db = f"sqlite:///{tmp_path / 'r.db'}"
    refused = CliRunner().invoke(cli_app, ["recipes", "import", str(p), "--db", db])
    assert refused.exit_code == 2 and "spindle_rpm" in refused.output
    done = CliRunner().invoke(
        cli_app, ["recipes", "import", str(p), "--db", db, "--cell", str(tmp_path / "cell.yaml")]
    )
    assert done.exit_code == 0, done.output
    # the targets command holds the stored recipe against its cell (the defaults without one)
    pose = ["--pose", "0", "0", "0", "--db", db, "--door-id", "A-1"]
    assert CliRunner().invoke(cli_app, ["targets", *pose]).exit_code == 2
    assert (
        CliRunner().invoke(cli_app, ["targets", *pose, "--cell", str(tmp_path / "cell.yaml")]).exit_code == 0
    )
