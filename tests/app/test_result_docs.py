"""docs/result.md documents every key a real answer carries, and every refusal code doorloc can give.

Real answers: the bundled rendered fixtures located with their own cells (answers, far faces, arrises,
distractors), refusals made on purpose (black, noise, wrong size, wrong thickness, outside the envelope),
an HTTP answer with targets, RAPID text, overlay and a reach block, an HTTP reach refusal, and batch
records (answered, refused, failed). Each key path (``a.b``, ``list[].key``) must match a path documented
in docs/result.md, where ``<name>`` stands for one key of a keyed object (a line, a term, a stage). The
models' own fields are walked too, so a field that is null in every answer here is still held to the doc.
"""

from __future__ import annotations

import csv
import json
import os
import re
import subprocess
import sys
import typing
from collections.abc import Iterator
from functools import cache
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from fastapi.testclient import TestClient

from .conftest import dev_settings, door_d100, post_locate, recipe_store

# The answers, records and located fixtures below are made once per test process (module fixtures, a cached
# function): the module's tests run in one process, so each is made once (about 17 s apiece on two CPUs).
pytestmark = pytest.mark.xdist_group("result_docs")

REPO = Path(__file__).resolve().parents[2]
DOC = REPO / "docs" / "result.md"
RENDERED = REPO / "fixtures" / "rendered"
GRID_IMAGE = RENDERED / "grid" / "img_0031.png"  # a 900 x 50 mm door, the grid cell's default door


# ------------------------------------------------------------------------------------------ the document


@cache
def documented() -> tuple[list[re.Pattern[str]], set[str], set[str]]:
    """(key-path patterns, error codes, field paths) from docs/result.md's tables.

    A table row documents the path in its first cell's backticks; rows under the "Refusal codes" heading
    document error codes instead.
    """
    patterns, codes, paths = [], set(), set()
    in_codes = False
    for line in DOC.read_text(encoding="utf-8").splitlines():
        if line.startswith("#"):
            in_codes = "refusal codes" in line.lower()
            continue
        m = re.match(r"^\|\s*`([^`]+)`", line)
        if not m:
            continue
        name = m.group(1)
        if in_codes:
            codes.add(name)
            continue
        paths.add(name)
        rx = re.escape(name)
        rx = re.sub(r"<[a-z_]+>", r"[^.\\[\\]]+", rx)
        patterns.append(re.compile(rx))
    return patterns, codes, paths


def undocumented(found: set[str]) -> list[str]:
    patterns, _, _ = documented()
    return sorted(p for p in found if not any(rx.fullmatch(p) for rx in patterns))


def key_paths(obj: object, prefix: str = "") -> Iterator[str]:
    """Every key path of a JSON value: ``a.b`` for objects, ``a[]`` for the objects in a list."""
    if isinstance(obj, dict):
        for k, v in obj.items():
            path = f"{prefix}.{k}" if prefix else str(k)
            yield path
            yield from key_paths(v, path)
    elif isinstance(obj, list):
        for item in obj:
            if isinstance(item, dict):
                yield from key_paths(item, prefix + "[]")


def error_codes(obj: dict) -> set[str]:
    codes = {obj["error_code"]} if obj.get("error_code") else set()
    reach = obj.get("reach") or {}
    return codes | ({reach["error_code"]} if reach.get("error_code") else set())


# ------------------------------------------------------------------------------------------ real answers


def _truth_rows(folder: Path) -> list[dict[str, str]]:
    with open(folder / "truth.csv", newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


@cache
def located_fixtures() -> list[dict]:
    """Every bundled rendered fixture located with its own cell, and refusals made on purpose."""
    from doorloc.cell import DoorSize, load_cell
    from doorloc.vision.imageio import read_image
    from doorloc.vision.locate import locate

    out = []
    for folder in sorted(p for p in RENDERED.iterdir() if p.is_dir()):
        cell = load_cell(folder / "cell.yaml")
        for row in _truth_rows(folder):
            door = DoorSize(
                width_mm=float(row["width_mm"]),
                thickness_mm=float(row["thickness_mm"]),
                height_mm=float(row.get("height_mm") or 2100.0),
                arris_mm=float(row.get("arris_mm") or 0.0),
                arris_profile=row.get("arris_profile") or "chamfer",
            )
            image = read_image(folder / row["image"])
            out.append(locate(image, cell, door, image_name=row["image"]).model_dump(mode="json"))
    # refusals made on purpose, on the grid's cell (the thesis camera)
    from doorloc.pose import DoorPose
    from doorloc.sim.boards import Checkerboard, render_board
    from doorloc.sim.door import render_door
    from doorloc.sim.effects import Effects
    from doorloc.vision.config import LocateConfig

    cell = load_cell(RENDERED / "grid" / "cell.yaml")
    door = cell.default_door
    width, height = cell.camera.image_size
    rng = np.random.default_rng(34)
    board = render_board(cell.camera, Checkerboard(11, 7, 20.0), [0.05, -0.1, 0.02], [-120.0, -60.0, 420.0])
    made = [
        (np.zeros((height, width), np.uint8), door, None),  # black_image
        (np.full((height, width), 255, np.uint8), door, None),  # saturated_image
        (rng.integers(0, 256, (height, width), dtype=np.uint8), door, None),  # no_door
        (np.zeros((height, width), np.float64), door, None),  # bad_image
        (render_door(cell, door, DoorPose()).image[::2, ::2], door, None),  # wrong_image_size
        (render_door(cell, door, DoorPose(0, 0, 6.0)).image, door, None),  # outside_envelope
        (render_door(cell, DoorSize(900, 12, 2100), DoorPose()).image, door, None),  # thickness, coarse
        (board.image, door, None),  # not_a_door
        (
            render_door(cell, door, DoorPose(1.0, -2.0, 0.5), effects=Effects(albedo_hinge=1.4)).image,
            door,
            None,
        ),  # overexposed
        (  # thickness_mismatch after the fine stage: every check's refusal listed
            render_door(cell, DoorSize(900, 50.6, 2100), DoorPose()).image,
            door,
            LocateConfig(thickness_tolerance_mm=0.3),
        ),
    ]
    for image, the_door, config in made:
        out.append(
            locate(image, cell, the_door, image_name="made.png", config=config).model_dump(mode="json")
        )
    return out


def _thesis_cell_with_robot_base(tmp_path: Path, shift_mm: float) -> Path:
    """The thesis cell with its robot base moved ``shift_mm`` further from the door (along cell -X)."""
    doc = yaml.safe_load((REPO / "fixtures" / "cell_thesis.yaml").read_text())
    doc["robot"]["base"]["pos_mm"][0] -= shift_mm
    path = tmp_path / f"cell_shift_{shift_mm:g}.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


@pytest.fixture(scope="module")
def module_store():
    """The recipe store of :func:`http_answers`, made once for the module's tests as the answers are."""
    yield from recipe_store(door_d100())


@pytest.fixture(scope="module")
def http_answers(tmp_path_factory, module_store) -> list[dict]:
    """Real HTTP answers: targets, RAPID, overlay and reach; a reach refusal; a door given by its size."""
    from doorloc.app.http import create_app
    from doorloc.cell import load_cell

    moved_base = _thesis_cell_with_robot_base(tmp_path_factory.mktemp("cells"), 3000.0)
    answers = []
    with open(GRID_IMAGE, "rb") as f:
        png = f.read()
    for cell_path in (REPO / "fixtures" / "cell_thesis.yaml", moved_base):
        app = create_app(dev_settings(), cell=load_cell(cell_path), store=module_store)
        with TestClient(app) as client:
            answers.append(
                post_locate(client, png, "img_0031.png", "?overlay=true&rapid=true", door_id="D-100")
            )
            answers.append(post_locate(client, png, "img.png", width_mm="900", thickness_mm="50"))
    assert answers[0]["ok"] and answers[0]["reach"]["feasible"] and answers[0]["targets"]
    assert not answers[2]["ok"] and answers[2]["measured_pose"], "the moved robot should refuse the door"
    return answers


@pytest.fixture(scope="module")
def batch_records(tmp_path_factory) -> list[dict]:
    """Records of a real `doorloc batch` run: answered, refused and failed images."""
    tmp = tmp_path_factory.mktemp("batch")
    images = tmp / "images"
    images.mkdir()
    (images / "door.png").write_bytes(GRID_IMAGE.read_bytes())
    black = np.zeros((1080, 1920), np.uint8)
    (images / "black.png").write_bytes(cv2.imencode(".png", black)[1].tobytes())
    (images / "torn.png").write_bytes(GRID_IMAGE.read_bytes()[:2000])
    out = tmp / "results.jsonl"
    env = {**os.environ, "PYTHONPATH": str(REPO / "src") + os.pathsep + os.environ.get("PYTHONPATH", "")}
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "doorloc",
            "batch",
            str(images),
            "--cell",
            str(RENDERED / "grid" / "cell.yaml"),
            "--out",
            str(out),
            "--workers",
            "1",
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert proc.returncode in (0, 1), proc.stderr
    records = [json.loads(line) for line in out.read_text().splitlines()]
    assert {r["status"] for r in records} == {"answered", "refused", "failed"}, records
    return records


# ------------------------------------------------------------------------------------------ the tests


def test_every_key_of_located_fixtures_and_refusals_is_documented():
    results = located_fixtures()
    assert sum(r["ok"] for r in results) > 50 and sum(not r["ok"] for r in results) >= 10
    found = {p for r in results for p in key_paths(r)}
    assert "diagnostics.camera_response" in found and "lines[].name" in found  # the walk reaches deep keys
    assert undocumented(found) == [], "keys of locate results missing from docs/result.md"


def test_every_key_of_http_answers_and_batch_records_is_documented(http_answers, batch_records):
    found = {p for r in [*http_answers, *batch_records] for p in key_paths(r)}
    assert {"reach.targets[].joints_deg", "targets[].quat", "status", "measured_pose.x_mm"} <= found
    assert undocumented(found) == [], "keys of HTTP answers or batch records missing from docs/result.md"


def _schema_paths(schema: dict, node: dict, prefix: str, seen: frozenset[str]) -> Iterator[str]:
    """Field paths an OpenAPI schema declares (objects' properties; lists of objects as ``[]``)."""
    if "$ref" in node:
        name = node["$ref"].rsplit("/", 1)[-1]
        if name in seen:
            return
        yield from _schema_paths(schema, schema["$defs"][name], prefix, seen | {name})
        return
    for alt in node.get("anyOf", []):
        yield from _schema_paths(schema, alt, prefix, seen)
    if node.get("type") == "array" and isinstance(node.get("items"), dict):
        yield from _schema_paths(schema, node["items"], prefix + "[]", seen)
    for key, sub in node.get("properties", {}).items():
        path = f"{prefix}.{key}" if prefix else key
        yield path
        yield from _schema_paths(schema, sub, path, seen)


def test_every_field_of_the_response_model_is_documented_and_described():
    from doorloc.app.http.schemas import LocateResponse

    schema = LocateResponse.model_json_schema()
    declared = set(_schema_paths(schema, schema, "", frozenset()))
    assert {"uncertainty.x_mm", "provenance.cell_sha256", "reach.targets[].confdata"} <= declared
    assert undocumented(declared) == [], "fields of LocateResponse missing from docs/result.md"
    # OpenAPI descriptions on the result's own fields (the models docs/result.md is written from)
    from doorloc.app.http import schemas
    from doorloc.vision import result

    models = [getattr(m, n) for m in (result, schemas) for n in m.__all__]
    models += [result.PhysicalModel, schemas.RecipeChangeOut]
    bare = [f"{m.__name__}.{k}" for m in models for k, f in m.model_fields.items() if not f.description]
    assert bare == [], "fields without an OpenAPI description"


def _code_literals() -> set[str]:
    """Refusal codes written in the source: ``Refusal("code", ...)``, ``refusal(name, "code", ...)``,
    a failed batch record's ``_failed(item, "code", ...)`` and ``return None, "code", ...``, reach reasons."""
    import ast

    from doorloc.robot.reach import Reason

    codes = set(typing.get_args(Reason))
    for path in (REPO / "src" / "doorloc").rglob("*.py"):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.Call):
                name = getattr(node.func, "attr", None) or getattr(node.func, "id", None)
                position = {"Refusal": 0, "refusal": 1, "_failed": 1}.get(name or "")
                if position is not None and len(node.args) > position:
                    arg = node.args[position]
                    if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
                        codes.add(arg.value)
            elif isinstance(node, ast.Return) and isinstance(node.value, ast.Tuple):
                elts = node.value.elts
                if (
                    len(elts) == 3
                    and isinstance(elts[0], ast.Constant)
                    and elts[0].value is None
                    and isinstance(elts[1], ast.Constant)
                    and isinstance(elts[1].value, str)
                    and re.fullmatch(r"[a-z]+(_[a-z]+)+", elts[1].value)
                ):
                    codes.add(elts[1].value)
    return codes


def test_every_refusal_code_is_documented(http_answers, batch_records):
    _, doc_codes, _ = documented()
    in_source = _code_literals()
    assert {"no_door", "uncertain", "unreachable", "not_an_image", "internal_error"} <= in_source
    seen = {c for r in [*located_fixtures(), *http_answers, *batch_records] for c in error_codes(r)}
    assert {"black_image", "bad_image", "not_a_door", "overexposed", "thickness_mismatch"} <= seen
    missing = sorted((in_source | seen) - doc_codes)
    assert missing == [], "error codes missing from docs/result.md's refusal codes"
