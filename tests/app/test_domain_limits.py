"""Door sizes are bounded everywhere they enter (API, recipe import, CLI), and internal errors are real bugs
logged with a traceback and an incident id the answer quotes."""

from __future__ import annotations

import logging

import pytest
from sqlalchemy import update
from typer.testing import CliRunner

from doorloc.app.cli import app as cli_app
from doorloc.limits import DOOR_RANGES_MM, door_size_problems
from doorloc.recipes.importer import RecipeImportError, load_recipe_file
from doorloc.recipes.tables import DoorRow

from .conftest import CELL_PATH, dev_settings


def _post(client, png, **form):
    return client.post("/v1/locate", files={"image": ("door.png", png, "image/png")}, data=form)


@pytest.mark.parametrize(
    ("field", "value"),
    [("width_mm", "1e308"), ("thickness_mm", "10000"), ("height_mm", "50"), ("width_mm", "100")],
)
def test_locate_refuses_door_sizes_outside_the_range_naming_the_field(client, small_png, field, value):
    """Issue defect: width_mm=1e308 or thickness 10000 reached locate and ended as internal_error."""
    r = _post(client, small_png, **{field: value})
    assert r.status_code == 422, r.text
    body = r.json()
    assert body["code"] == "invalid_door" and field in body["detail"] and "accepted" in body["detail"]


def test_sizes_inside_the_margins_are_accepted(client, small_png):
    lo = {k: str(v[0]) for k, v in DOOR_RANGES_MM.items()}
    assert _post(client, small_png, **lo).status_code == 200
    # SPEC's own extremes
    assert _post(client, small_png, width_mm="1350", thickness_mm="100", height_mm="3000").status_code == 200


def test_recipe_put_refuses_an_absurd_width_and_keeps_the_old_one(client, recipe):
    """Issue defect: width_mm=1e308 was stored."""
    body = recipe.model_dump(mode="json") | {"width_mm": 1e308}
    r = client.put("/v1/doors/D-100", json=body)
    assert r.status_code == 422
    assert "width_mm" in r.json()["detail"] and "Value error" not in r.json()["detail"]
    assert client.get("/v1/doors/D-100").json()["width_mm"] == 900


def test_recipe_import_names_the_column(tmp_path):
    header = (
        "door_id,width_mm,height_mm,thickness_mm,hinge_z_mm,hinge_length_mm,hinge_width_mm,hinge_x_mm,"
        "hinge_depth_mm,hinge_corner_radius_mm,tool_diameter_mm,spindle_rpm,feed_mm_s"
    )
    p = tmp_path / "r.csv"
    p.write_text(header + "\nA-1,900,2100,10000,250,100,30,10,3,8,16,18000,25\n")
    with pytest.raises(RecipeImportError) as e:
        load_recipe_file(p)
    assert e.value.issues[0].column == "thickness_mm" and "outside the accepted" in e.value.issues[0].message


def test_cli_locate_refuses_a_door_outside_the_range(tmp_path, small_png):
    img = tmp_path / "door.png"
    img.write_bytes(small_png)
    r = CliRunner().invoke(cli_app, ["locate", str(img), "--cell", str(CELL_PATH), "--door-width", "1e308"])
    assert r.exit_code == 2 and "width_mm" in r.output and "Traceback" not in r.output


def test_arris_must_stay_below_half_the_thickness():
    assert [f for f, _ in door_size_problems(900, 40, 2100, 20)] == ["arris_mm"]
    assert door_size_problems(900, 40, 2100, 19.9) == []


def test_a_stored_recipe_that_breaks_todays_rules_is_a_422_not_a_500(client, store, small_png):
    with store.engine.begin() as conn:  # as an older version (or another program) could have written it
        conn.execute(update(DoorRow).where(DoorRow.door_id == "D-100").values(width_mm=1e308))
    r = client.get("/v1/doors/D-100")
    assert (
        r.status_code == 422
        and r.json()["code"] == "invalid_stored_recipe"
        and "width_mm" in r.json()["detail"]
    )
    assert _post(client, small_png, door_id="D-100").status_code == 422


def test_an_exception_in_a_route_is_500_with_an_incident_id_logged_with_its_traceback(cell, store, caplog):
    from fastapi.testclient import TestClient

    from doorloc.app.http import create_app

    from .conftest import png_bytes

    def broken_locate(*a, **k):
        raise ZeroDivisionError("a bug")

    import numpy as np

    app = create_app(dev_settings(), cell=cell, store=store, locate_fn=broken_locate)
    with TestClient(app, raise_server_exceptions=False) as c, caplog.at_level(logging.INFO, logger="doorloc"):
        r = c.post(
            "/v1/locate", files={"image": ("a.png", png_bytes(np.full((8, 8), 9, np.uint8)), "image/png")}
        )
    assert r.status_code == 500
    incident = r.json()["request_id"]
    assert incident in r.json()["detail"]
    errors = [rec for rec in caplog.records if rec.levelno == logging.ERROR]
    assert errors and errors[0].exc_info is not None and errors[0].fields["incident_id"] == incident


def test_a_bug_inside_locate_is_logged_at_error_level_with_an_incident_id(cell, monkeypatch, caplog):
    """Issue defect: internal errors were logged at info level without a traceback."""
    import numpy as np

    from doorloc.vision import locate as locate_mod

    def boom(*a, **k):
        raise ValueError("cannot convert float NaN to integer")

    monkeypatch.setattr(locate_mod, "_locate", boom)
    with caplog.at_level(logging.INFO, logger="doorloc"):
        res = locate_mod.locate(np.zeros((16, 16), np.uint8), cell, cell.default_door, image_name="x.png")
    assert res.error_code == "internal_error"
    incident = res.model_dump()["incident_id"]
    assert incident in res.error
    rec = [r for r in caplog.records if r.levelno == logging.ERROR]
    assert rec and rec[0].exc_info is not None and rec[0].fields["incident_id"] == incident


def test_cli_locate_refuses_a_fifo_and_a_bomb_without_reading_or_decoding(tmp_path):
    import os
    import struct
    import zlib

    fifo = tmp_path / "pipe.png"
    os.mkfifo(fifo)
    r = CliRunner().invoke(cli_app, ["locate", str(fifo), "--cell", str(CELL_PATH)])
    assert r.exit_code == 2 and "not a regular file" in r.output
    ihdr = struct.pack(">IIBBBBB", 7000, 7000, 16, 6, 0, 0, 0)
    bomb = tmp_path / "bomb.png"
    bomb.write_bytes(
        b"\x89PNG\r\n\x1a\n"
        + struct.pack(">I", 13)
        + b"IHDR"
        + ihdr
        + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr))
    )
    r = CliRunner().invoke(cli_app, ["locate", str(bomb), "--cell", str(CELL_PATH)])
    assert r.exit_code == 2 and "392 MB decoded" in r.output
