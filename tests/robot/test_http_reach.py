"""POST /v1/locate gains a reach block when the cell names a robot; an infeasible target is a refusal."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from fastapi.testclient import TestClient

from doorloc.app.http import create_app
from doorloc.app.settings import ServiceSettings
from doorloc.cell import parse_cell
from doorloc.recipes.importer import load_recipe_file
from doorloc.recipes.store import RecipeStore
from doorloc.vision.result import LocateResult

REPO = Path(__file__).resolve().parents[2]
DOC = yaml.safe_load((REPO / "fixtures" / "cell_thesis.yaml").read_text())


def _locate_at(x_mm: float):
    def locate(image, cell, door, *, image_name="", config=None, trace=None, jpeg_quality=0):
        return LocateResult(
            image=image_name,
            ok=True,
            x_mm=x_mm,
            z_mm=-2.5,
            yaw_deg=0.3,
            thickness_mm=door.thickness_mm,
            scale_mm_per_px=0.206,
            corner_px=[802.0, 708.0],
            elapsed_ms=1.0,
        )

    return locate


@pytest.fixture
def post(tmp_path):
    store = RecipeStore("sqlite://")
    store.put_many(load_recipe_file(REPO / "fixtures" / "recipes" / "thesis_extremes.csv"))
    clients = []

    def run(x_mm: float, robot: bool = True) -> dict:
        doc = dict(DOC)
        if not robot:
            doc.pop("robot")
        cell = parse_cell(doc, REPO / "fixtures", "cell.yaml")
        c = TestClient(
            create_app(
                ServiceSettings(open_access=True, allowed_hosts=["testserver"]),
                cell=cell,
                store=store,
                locate_fn=_locate_at(x_mm),
            ),
            raise_server_exceptions=False,
        )
        c.__enter__()
        clients.append(c)
        ok, png = cv2.imencode(".png", np.full((48, 64), 128, np.uint8))
        r = c.post(
            "/v1/locate",
            files={"image": ("door.png", png.tobytes(), "image/png")},
            data={"door_id": "THESIS-1350"},
        )
        assert r.status_code == 200, r.text
        return r.json()

    yield run
    for c in clients:
        c.__exit__(None, None, None)
    store.close()


def test_reach_block_with_the_spec_fields(post):
    a = post(1.25)
    assert a["ok"] is True and a["reach"]["feasible"] is True and a["reach"]["robot"] == "IRB6600-175/2.55"
    assert len(a["reach"]["targets"]) == len(a["targets"]) == 19
    t = a["reach"]["targets"][0]
    assert {
        "name",
        "joints_deg",
        "confdata",
        "tcp_base_mm",
        "quat_base",
        "feasible",
        "reason",
        "inv_condition",
        "deflection_mm",
    } <= set(t)


def test_infeasible_target_turns_the_answer_into_a_refusal(post):
    a = post(500.0)
    assert a["ok"] is False and a["error_code"] == "unreachable"
    assert "H2_APP" in a["error"] and a["x_mm"] is None and a["targets"] == []
    assert a["measured_pose"]["x_mm"] == 500.0
    assert a["reach"]["feasible"] is False and not all(t["feasible"] for t in a["reach"]["targets"])


def test_no_robot_no_reach_block(post):
    a = post(1.25, robot=False)
    assert a["ok"] is True and a["reach"] is None and len(a["targets"]) == 19
