"""The camera's response measured from the cell's doors (``doorloc.vision.cell_response``) and
``doorloc measure-light --response``."""

from __future__ import annotations

import dataclasses
import importlib.util
import math
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from doorloc.app.cli import app
from doorloc.cell import load_cell, measured_response_factor
from doorloc.pose import DoorPose, direction_cell
from doorloc.vision import cell_response
from doorloc.vision.cell_response import (
    RESPONSE_FACTOR_FLOOR,
    RESPONSE_MARGIN,
    ResponseMeasurement,
    ResponseNotMeasurable,
    ShoulderReading,
    doors_agree,
    exponent_range,
    measure_cell_response,
)
from doorloc.vision.light_search import LightMeasurement
from doorloc.vision.response import RESPONSE_PLAUSIBLE

_spec = importlib.util.spec_from_file_location("lit_doors", Path(__file__).with_name("lit_doors.py"))
assert _spec is not None and _spec.loader is not None
lit_doors = importlib.util.module_from_spec(_spec)
sys.modules.setdefault("lit_doors", lit_doors)
_spec.loader.exec_module(lit_doors)
lit_door, CELL, CELL_PATH = lit_doors.lit_door, lit_doors.CELL, lit_doors.CELL_PATH
LIGHT, CAMERA_GAMMA = lit_doors.LIGHT, lit_doors.CAMERA_GAMMA
STEP = 1.037


def test_the_response_of_a_cell_is_found_from_its_doors_where_the_cell_states_another():
    """Four doors with roundings of 1.2-2.4 mm under the cell's lamp, through a camera of 1.8, in a cell that
    states 1.0 (a linear camera assumed): the measured exponent's range holds the camera's and is far
    narrower than the default doubt of a stated exponent (a factor 2.2), rules the cell's 1.0 out, and the
    light read with it lies near the lamp; every exponent tried is told."""
    frames = [
        lit_door(2.4, "round", DoorPose(2.0, -3.0, 0.6), 1.1, 1),
        lit_door(1.6, "round", DoorPose(-4.0, 2.0, -1.0), 1.3, 2),
        lit_door(1.2, "round", DoorPose(5.0, 4.0, 1.2), 0.9, 3),
        lit_door(2.0, "round", DoorPose(-6.0, -5.0, -0.4), 1.0, 4),
    ]
    heard: list[str] = []
    m = measure_cell_response(frames, dataclasses.replace(CELL, response_gamma=1.0), progress=heard.append)
    assert m.gamma / m.factor <= CAMERA_GAMMA <= m.gamma * m.factor, m
    assert RESPONSE_FACTOR_FLOOR <= m.factor <= 1.35, m
    assert measured_response_factor(m.gamma, m.sigma) == pytest.approx(m.factor)
    assert m.cell_ruled_out and m.cell_gamma == 1.0 and m.cell_score > dict(m.scores)[m.gamma]
    exponents = [h for h in heard if h.startswith("exponent")]
    assert len(exponents) == len(m.scores) and exponents[-1].startswith("exponent 1.000")
    # the faces reach 0.80 of full scale, above the knee: a shoulder from there was read, and these
    # roundings, hardly above it, cannot rule it out (it stays doubted from the knee)
    assert m.shoulder is not None and m.shoulder.reached == pytest.approx(0.80, abs=0.01), m.shoulder
    assert not m.shoulder.ruled_out and m.shoulder.doubted_from == CELL.locate.response_shoulder_knee
    assert heard[-1].startswith("through a shoulder from 0.7") and "not ruled out" in heard[-1]
    off = math.degrees(
        math.acos(min(1.0, float(direction_cell(*m.light.direction_deg) @ direction_cell(*LIGHT))))
    )
    assert off <= 15.0, m.light
    assert m.doors == 4 and m.strips >= 8


def test_bright_doors_of_a_power_law_camera_rule_out_a_shoulder_up_to_their_brightest_level():
    """Three roundings whose faces reach 0.95 of full scale, through a camera that keeps its power law: read
    through a shoulder from the knee (0.7) their strips fit matt arcs far worse than read as a power law, with
    any exponent of the measured range, so the measurement says a shoulder is doubted only above the
    brightest level the doors reach."""
    poses = [DoorPose(2.0, -3.0, 0.6), DoorPose(-4.0, 2.0, -1.0), DoorPose(-6.0, -5.0, -0.4)]
    frames = [
        lit_door(a, "round", pose, blur, seed, face_albedo=0.95)
        for a, pose, blur, seed in zip((2.4, 1.6, 2.0), poses, (1.1, 1.3, 1.0), (1, 2, 4), strict=True)
    ]
    m = measure_cell_response(frames, dataclasses.replace(CELL, response_gamma=1.0))
    assert m.gamma / m.factor <= CAMERA_GAMMA <= m.gamma * m.factor, m
    s = m.shoulder
    assert s is not None and s.knee == CELL.locate.response_shoulder_knee, s
    assert s.ruled_out and s.shouldered - s.plain > 3 * RESPONSE_MARGIN, s
    assert 0.9 <= s.reached <= 1.0 and s.doubted_from == s.reached


def test_a_shoulder_is_ruled_out_by_its_score_and_doubted_from_the_brightest_level_then():
    """``ShoulderReading``: ruled out where the shouldered reading scores more than ``RESPONSE_MARGIN``
    above the plain one (as an exponent the doors rule out does); doubted from the doors' brightest level
    then, from the knee otherwise (and never below the knee)."""
    margin = RESPONSE_MARGIN
    assert ShoulderReading(0.7, 0.95, 0.1, 0.1 + 1.01 * margin, 1.8).doubted_from == 0.95
    assert ShoulderReading(0.7, 0.95, 0.1, 0.1 + 0.99 * margin, 1.8).doubted_from == 0.7
    assert ShoulderReading(0.7, 0.95, 0.3, 0.1, 1.8).doubted_from == 0.7  # the shoulder fits better
    assert ShoulderReading(0.8, 0.75, 0.0, 1.0, 1.8).doubted_from == 0.8


def test_doors_that_share_no_lamp_tell_the_response_each_under_its_own_light():
    """Five roundings of 1.2-2.4 mm, each lit by a lamp of its own (from either side, 10-45 deg up),
    through a camera of 1.8 in a cell that states 1.0: no light common to the doors explains them at any
    exponent, each door's strips are scored under its own light instead, and the range found holds the
    camera's exponent, narrower than the default doubt of a stated one, the cell's 1.0 ruled out; no light
    is stated."""
    lamps = [(-60.0, 20.0), (55.0, 30.0), (-25.0, 45.0), (70.0, 10.0), (35.0, 25.0)]
    poses = [
        DoorPose(2.0, -3.0, 0.6),
        DoorPose(-4.0, 2.0, -1.0),
        DoorPose(5.0, 4.0, 1.2),
        DoorPose(-6.0, -5.0, -0.4),
    ]
    frames = [
        lit_door(a, "round", poses[k % 4], blur, 10 + k, light=lamp)
        for k, (a, blur, lamp) in enumerate(
            zip((2.4, 1.6, 1.2, 2.0, 1.8), (1.1, 1.3, 0.9, 1.0, 1.2), lamps, strict=True)
        )
    ]
    heard: list[str] = []
    m = measure_cell_response(frames, dataclasses.replace(CELL, response_gamma=1.0), progress=heard.append)
    assert m.own_lights and m.light is None, m
    assert any("each door's strips scored under its own light" in h for h in heard)
    assert m.gamma / m.factor <= CAMERA_GAMMA <= m.gamma * m.factor, m
    assert RESPONSE_FACTOR_FLOOR <= m.factor <= 1.4, m
    assert m.cell_ruled_out and m.doors >= 4, m


def test_doors_that_rule_out_the_exponent_the_others_prefer_are_a_disagreement():
    """Each door's own scores per exponent: a door whose strips fit the common least's exponent within
    ``ARC_RULED_OUT`` of its own best agrees (one camera's doors scatter so); one that fits it worse, as
    locate's own reading of its strips would rule it out, is a second camera, and nothing is measured."""
    agreeing = {1.0: [0.30, 0.10, None], 1.8: [0.02, 0.05, None], 2.4: [0.12, 0.04, None]}
    doors_agree(agreeing, 1.8)  # (the second door's best, 2.4, fits 1.8 only 1.01 times worse)
    second_camera = {1.0: [0.30, 0.02], 1.8: [0.02, 0.30], 2.4: [0.12, 0.40]}
    with pytest.raises(ResponseNotMeasurable, match="disagree.*exponent 1.00 and 1.32 times worse with 1.80"):
        doors_agree(second_camera, 1.8)


def test_doors_under_a_diffuse_light_tell_no_response():
    """Two roundings under ambient light alone: no light is common to their strips at any exponent, and
    nothing is measured (the coarse grid alone is read)."""
    frames = [
        lit_door(2.4, "round", DoorPose(2.0, -3.0, 0.6), 1.1, 1, lamp=False),
        lit_door(1.6, "round", DoorPose(-4.0, 2.0, -1.0), 1.3, 2, lamp=False),
    ]
    with pytest.raises(ResponseNotMeasurable, match="diffuse"):
        measure_cell_response(frames, CELL)


def test_doors_without_a_rounding_or_a_camera_already_measured_are_refused_at_once():
    frames = [lit_door(2.0, "chamfer", DoorPose(0.0, 0.0, 0.0), 1.0, 3)]
    with pytest.raises(ResponseNotMeasurable, match="rounded arris"):
        measure_cell_response(frames, CELL)
    with pytest.raises(ResponseNotMeasurable, match="photometric model"):
        measure_cell_response(frames, dataclasses.replace(CELL, camera_photometry=object()))


def _grid(least_at: float, depth: float, floor: float = 0.01) -> dict[float, float]:
    """Scores over a fine grid of exponents: a valley of ``depth`` per unit log exponent, squared."""
    lo, hi = RESPONSE_PLAUSIBLE
    k = np.arange(-60, 61)
    gs = least_at * STEP**k
    gs = np.clip(gs, lo, hi)
    return {float(g): floor + depth * math.log(g / least_at) ** 2 for g in gs}


def test_the_range_holds_every_exponent_the_doors_cannot_rule_out():
    scores = _grid(1.7, 2.0)
    g, factor = exponent_range(scores, STEP)
    assert g == pytest.approx(1.7)
    near = [x for x, v in scores.items() if v <= scores[g] + RESPONSE_MARGIN]
    assert len(near) > 3 and all(g / factor <= x * STEP**0.999 and x <= g * factor for x in near)
    assert factor == pytest.approx(max(max(x / g, g / x) for x in near) * STEP)
    # a deep valley still keeps the floor; a shallow one a wide range
    assert exponent_range(_grid(1.7, 1e4), STEP)[1] == RESPONSE_FACTOR_FLOOR
    assert exponent_range(_grid(1.7, 0.2), STEP)[1] > 1.6


def test_no_range_where_no_arc_explains_the_strips_or_the_least_is_at_an_end():
    with pytest.raises(ResponseNotMeasurable, match="no matt arc"):
        exponent_range(_grid(1.7, 2.0, floor=0.3), STEP)
    with pytest.raises(ResponseNotMeasurable, match="at the end"):
        exponent_range(_grid(0.78, 2.0), STEP)
    with pytest.raises(ResponseNotMeasurable, match="at the end"):
        exponent_range(_grid(3.1, 2.0), STEP)


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.floats(0.0, 0.14), min_size=3, max_size=40),
    st.floats(1.01, 1.2),
)
def test_the_range_is_never_narrower_than_the_scores_allow(values, step):
    lo, hi = RESPONSE_PLAUSIBLE
    gs = np.geomspace(lo, hi, len(values))
    scores = dict(zip(gs.tolist(), values, strict=True))
    try:
        g, factor = exponent_range(scores, step)
    except ResponseNotMeasurable as e:
        assert "at the end" in str(e)
        return
    assert scores[g] == min(values) and factor >= RESPONSE_FACTOR_FLOOR
    for x, v in scores.items():
        if v <= scores[g] + RESPONSE_MARGIN:
            assert g / factor <= x * (1 + 1e-12) and x <= g * factor * (1 + 1e-12)


def _measured(cell_gamma: float) -> ResponseMeasurement:
    light = LightMeasurement((-44.0, 16.0), 10.0, 0.021, 6, 2)
    return ResponseMeasurement(
        1.812, 0.109, 1.12, ((1.7, 0.05), (1.812, 0.012)), cell_gamma, 0.3, light, 6, 2
    )


def _cell_and_folder(tmp_path: Path) -> tuple[Path, Path]:
    d = tmp_path / "doors"
    d.mkdir()
    cv2.imwrite(str(d / "door_1.png"), lit_door(2.0, "round", DoorPose(1.0, 1.0, 0.5), 1.0, 5)[0])
    doc = yaml.safe_load(CELL_PATH.read_text())
    doc["door"]["arris_profile"] = "round"
    doc["door"]["arris_mm"] = 2.0
    doc["camera"]["dist_coeffs"] = [0.0] * 5
    cell_path = tmp_path / "cell.yaml"
    cell_path.write_text(yaml.safe_dump(doc))
    return cell_path, d


def test_measure_light_response_prints_the_camera_and_light_lines_and_warns_of_a_wrong_cell(
    tmp_path, monkeypatch
):
    seen = {}

    def measured(frames, cell, progress=None):
        seen["doors"] = [door for _, door in frames]
        return _measured(cell.response_gamma)

    monkeypatch.setattr(cell_response, "measure_cell_response", measured)
    cell_path, folder = _cell_and_folder(tmp_path)
    res = CliRunner().invoke(app, ["measure-light", str(folder), "--cell", str(cell_path), "--response"])
    assert res.exit_code == 0, res.output
    assert seen["doors"][0].arris_mm == 2.0 and seen["doors"][0].arris_profile == "round"
    add = res.stdout.split("add to")[1]
    assert "response_gamma: 1.812" in add and "response_gamma_sigma: 0.109" in add
    assert "light_direction_deg: [-44.0, 16.0]" in add
    # the lines as printed make a cell that loads, its doubt the measured factor
    doc = yaml.safe_load(cell_path.read_text())
    lines = yaml.safe_load(add.split(":", 1)[1])
    doc["camera"].update(lines["camera"])
    doc.setdefault("locate", {}).update(lines["locate"])
    cell_path.write_text(yaml.safe_dump(doc))
    cell = load_cell(cell_path)
    assert cell.response_gamma == 1.812 and cell.locate.response_unmeasured_factor == pytest.approx(
        1.12, abs=1e-3
    )
    assert "response_gamma" in res.stderr and "outside" in res.stderr  # the fixture's cell states 1.0


def test_measure_light_response_prints_the_shoulders_knee_where_the_doors_rule_it_out(tmp_path, monkeypatch):
    """Doors that rule out a shoulder: the locate section gets ``response_shoulder_knee`` at the brightest
    level they reach, beside the light's lines, and the lines load as a cell; doors that do not: no line."""
    cell_path, folder = _cell_and_folder(tmp_path)
    for shouldered, line in ((0.5, "response_shoulder_knee: 0.94"), (0.05, None)):
        m = dataclasses.replace(_measured(1.0), shoulder=ShoulderReading(0.7, 0.94, 0.02, shouldered, 1.8))
        monkeypatch.setattr(
            cell_response, "measure_cell_response", lambda frames, cell, progress=None, m=m: m
        )
        res = CliRunner().invoke(app, ["measure-light", str(folder), "--cell", str(cell_path), "--response"])
        assert res.exit_code == 0, res.output
        add = res.stdout.split("add to")[1]
        assert "a shoulder in the response from 0.7" in res.stdout
        if line is None:
            assert "response_shoulder_knee" not in add and "not ruled out" in res.stdout
            continue
        assert line in add and add.count("locate:") == 1
        lines = yaml.safe_load(add.split(":", 1)[1])
        doc = yaml.safe_load(cell_path.read_text())
        doc["camera"].update(lines["camera"])
        doc.setdefault("locate", {}).update(lines["locate"])
        loaded_path = tmp_path / "measured.yaml"
        loaded_path.write_text(yaml.safe_dump(doc))
        cell = load_cell(loaded_path)
        assert cell.locate.response_shoulder_knee == 0.94 and cell.locate.light_direction_deg == (-44.0, 16.0)
    # without a common lamp, the knee alone makes the locate section
    m = dataclasses.replace(
        _measured(1.0), light=None, own_lights=True, shoulder=ShoulderReading(0.7, 0.94, 0.02, 0.5, 1.8)
    )
    monkeypatch.setattr(cell_response, "measure_cell_response", lambda frames, cell, progress=None: m)
    res = CliRunner().invoke(app, ["measure-light", str(folder), "--cell", str(cell_path), "--response"])
    add = res.stdout.split("add to")[1]
    assert res.exit_code == 0 and "locate:\n  response_shoulder_knee: 0.94" in add, res.output


def test_measure_light_response_of_doors_without_a_common_lamp_states_no_light(tmp_path, monkeypatch):
    def measured(frames, cell, progress=None):
        return dataclasses.replace(_measured(cell.response_gamma), light=None, own_lights=True)

    monkeypatch.setattr(cell_response, "measure_cell_response", measured)
    cell_path, folder = _cell_and_folder(tmp_path)
    res = CliRunner().invoke(app, ["measure-light", str(folder), "--cell", str(cell_path), "--response"])
    assert res.exit_code == 0, res.output
    assert "none common to the doors" in res.stdout
    add = res.stdout.split("add to")[1]
    assert "response_gamma: 1.812" in add and "light_direction_deg" not in add and "locate:" not in add


def test_measure_light_response_exits_1_where_the_doors_cannot_tell(tmp_path):
    _, folder = _cell_and_folder(tmp_path)  # (the fixture's cell: its default door has no arris)
    res = CliRunner().invoke(app, ["measure-light", str(folder), "--cell", str(CELL_PATH), "--response"])
    assert res.exit_code == 1, res.output
    assert "rounded arris" in res.stderr and "Traceback" not in res.output
