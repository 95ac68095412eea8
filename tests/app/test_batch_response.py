"""`doorloc batch` measures its camera's response from its own rounded doors where the cell only states it
(:func:`doorloc.app.batch.batch_response`); the measurement itself is tested in
tests/vision/test_cell_response.py."""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import sys
from pathlib import Path

import cv2
import pytest
import yaml
from typer.testing import CliRunner

from doorloc.app.batch import (
    BATCH_RESPONSE_DOORS,
    BATCH_RESPONSE_FACTOR_MAX,
    BATCH_RESPONSE_MIN_DOORS,
    batch_response,
    plan_folder,
)
from doorloc.app.cli import app
from doorloc.cell import load_cell
from doorloc.pose import DoorPose
from doorloc.vision import cell_response
from doorloc.vision.cell_response import ResponseMeasurement, ResponseNotMeasurable, ShoulderReading

_spec = importlib.util.spec_from_file_location(
    "lit_doors", Path(__file__).parents[1] / "vision" / "lit_doors.py"
)
assert _spec is not None and _spec.loader is not None
lit_doors = importlib.util.module_from_spec(_spec)
sys.modules.setdefault("lit_doors", lit_doors)
_spec.loader.exec_module(lit_doors)


def _measured(cell_gamma: float) -> ResponseMeasurement:
    """What the doors of a camera of 1.8 measure (each door under its own lamp: no light stated)."""
    return ResponseMeasurement(
        1.812, 0.109, 1.12, ((1.812, 0.012),), cell_gamma, 0.3, None, 16, 8, own_lights=True
    )


@pytest.fixture
def rounded_job(tmp_path):
    """A folder of ``BATCH_RESPONSE_DOORS + 2`` images of doors with 2 mm roundings, and a cell whose door is
    one, stating a linear camera (1.0) without a measurement."""
    folder = tmp_path / "doors"
    folder.mkdir()
    image = lit_doors.lit_door(2.0, "round", DoorPose(1.0, 1.0, 0.5), 1.0, 5)[0]
    for k in range(BATCH_RESPONSE_DOORS + 2):
        cv2.imwrite(str(folder / f"door_{k:02d}.png"), image)
    doc = yaml.safe_load(lit_doors.CELL_PATH.read_text())
    doc["door"].update(arris_profile="round", arris_mm=2.0)
    doc["camera"]["response_gamma"] = 1.0
    doc["camera"].pop("response_gamma_sigma", None)
    cell_path = tmp_path / "cell.yaml"
    cell_path.write_text(yaml.safe_dump(doc))
    return folder, cell_path


def test_a_batch_takes_its_cameras_response_from_its_rounded_doors(rounded_job, monkeypatch):
    folder, cell_path = rounded_job
    cell = load_cell(cell_path)
    seen: list[int] = []

    def measured(frames, cell, progress=None):
        seen.append(len(frames))
        return _measured(cell.response_gamma)

    monkeypatch.setattr(cell_response, "measure_cell_response", measured)
    items, _ = plan_folder(folder, cell)
    said = batch_response(items, cell)
    assert seen == [BATCH_RESPONSE_DOORS]  # spread over the ten, no more than eight
    assert said.cell.response_gamma == 1.812 and said.cell.response_gamma_sigma == 0.109
    assert said.cell.locate.response_unmeasured_factor == 1.12
    assert said.sentence is not None and "measured from 8 of the batch's doors" in said.sentence
    assert "response_gamma: 1.812" in said.sentence and "warning" in said.sentence  # the cell's 1.0 ruled out
    # a cell whose response was measured keeps it; a job with too few rounded doors, a cell that trusts its
    # stated exponent (a factor at the measurement's floor) and one without a rounding measure nothing
    measured_cell = dataclasses.replace(cell, response_gamma_sigma=0.05)
    assert batch_response(items, measured_cell) == type(said)(measured_cell)
    assert batch_response(items[: BATCH_RESPONSE_MIN_DOORS - 1], cell).measurement is None
    trusting = dataclasses.replace(
        cell, locate=dataclasses.replace(cell.locate, response_unmeasured_factor=1.1)
    )
    assert batch_response(items, trusting).measurement is None
    chamfered = [
        dataclasses.replace(
            it,
            choice=dataclasses.replace(
                it.choice, door=dataclasses.replace(it.choice.door, arris_profile="chamfer")
            ),
        )
        for it in items
    ]
    assert batch_response(chamfered, cell).measurement is None
    assert len(seen) == 1


def test_a_batch_whose_doors_rule_out_a_shoulder_doubts_it_only_above_their_brightest_level(
    rounded_job, monkeypatch
):
    """Where the measured doors' roundings fit a shoulder from the knee clearly worse than the power law
    (``RESPONSE_MARGIN`` in their score), every door of the job is located with the shoulder doubted only
    above the brightest level those doors reach, and the sentence says so; where they do not, the cell's
    knee stays."""
    folder, cell_path = rounded_job
    cell = load_cell(cell_path)
    items = plan_folder(folder, cell)[0]
    knee = cell.locate.response_shoulder_knee
    for shouldered, knee_after in ((0.40, 0.93), (0.05, knee)):
        reading = ShoulderReading(knee, 0.93, 0.02, shouldered, 1.8)
        m = dataclasses.replace(_measured(1.0), shoulder=reading)
        monkeypatch.setattr(
            cell_response, "measure_cell_response", lambda frames, cell, progress=None, m=m: m
        )
        said = batch_response(items, cell)
        assert said.cell.locate.response_shoulder_knee == knee_after
        assert said.sentence is not None
        assert ("rule out a shoulder" in said.sentence) == (knee_after != knee), said.sentence
        assert said.cell.response_gamma == 1.812


def test_a_batch_whose_doors_cannot_tell_keeps_the_stated_response_and_says_why(rounded_job, monkeypatch):
    folder, cell_path = rounded_job
    cell = load_cell(cell_path)
    items = plan_folder(folder, cell)[0]

    def refused(frames, cell, progress=None):
        raise ResponseNotMeasurable("the light is diffuse")

    monkeypatch.setattr(cell_response, "measure_cell_response", refused)
    said = batch_response(items, cell)
    assert said.cell is cell and said.measurement is None
    assert said.sentence is not None and "the light is diffuse" in said.sentence
    assert "stated exponent 1 used" in said.sentence
    # a range wider than the batch takes: the stated exponent kept, the range told
    wide = dataclasses.replace(_measured(1.0), factor=BATCH_RESPONSE_FACTOR_MAX * 1.1)
    monkeypatch.setattr(cell_response, "measure_cell_response", lambda frames, cell, progress=None: wide)
    said = batch_response(items, cell)
    assert said.cell is cell and said.measurement == wide
    assert said.sentence is not None and "only within exponents 1.10-2.99" in said.sentence


def test_batch_locates_every_door_with_the_measured_response_unless_told_the_stated_one(
    rounded_job, tmp_path, monkeypatch
):
    folder, cell_path = rounded_job
    for extra in sorted(folder.iterdir())[BATCH_RESPONSE_MIN_DOORS:]:
        extra.unlink()  # (five doors: the fewest a batch measures from)
    calls: list[int] = []

    def measured(frames, cell, progress=None):
        calls.append(len(frames))
        if progress is not None:
            progress("exponent 1.812: 15 rounded strips fit matt arcs under each door's own light at 0.012")
        return _measured(cell.response_gamma)

    monkeypatch.setattr(cell_response, "measure_cell_response", measured)
    runs = {}
    for label, extra in (("measured", []), ("stated", ["--stated-response"])):
        out = tmp_path / f"{label}.jsonl"
        res = CliRunner().invoke(
            app, ["batch", str(folder), "--cell", str(cell_path), "--out", str(out), "--workers", "1", *extra]
        )
        assert res.exit_code in (0, 1), res.output
        runs[label] = ([json.loads(line) for line in out.read_text().splitlines()], res.stderr)
    assert calls == [BATCH_RESPONSE_MIN_DOORS]  # --stated-response measured nothing
    records, said = runs["measured"]
    assert len(records) == BATCH_RESPONSE_MIN_DOORS and "exponent 1.812" in said and "measured from 8" in said
    assert {(r["model"]["response_gamma"], r["model"]["response_gamma_sigma"]) for r in records} == {
        (1.812, 0.109)
    }
    records, said = runs["stated"]
    assert "measured from" not in said
    assert {(r["model"]["response_gamma"], r["model"]["response_gamma_sigma"]) for r in records} == {
        (1.0, None)
    }
