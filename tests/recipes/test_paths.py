"""Hinge pocket paths (door frame): the tool stays inside the pocket, touches every side, runs CCW."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
from hypothesis import given, settings

from doorloc.recipes.models import Hinge, PointCorrection
from doorloc.recipes.paths import hinge_path, pocket_points_xz

_spec = importlib.util.spec_from_file_location(
    "hinge_strategies", Path(__file__).with_name("hinge_strategies.py")
)
strategies = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(strategies)


def _inside_rounded_pocket(px, pz, h: Hinge, rt: float, tol=1e-9, corner_tol=1e-9) -> bool:
    """Is a tool circle of radius rt centred at (px, pz) inside the pocket with rounded corners?"""
    x0, x1, z0, z1, r = h.x_mm, h.x_mm + h.width_mm, h.z_mm, h.z_mm + h.length_mm, h.corner_radius_mm
    if not (x0 + rt - tol <= px <= x1 - rt + tol and z0 + rt - tol <= pz <= z1 - rt + tol):
        return False
    cx = min(max(px, x0 + r), x1 - r)  # nearest point of the rectangle of arc centres
    cz = min(max(pz, z0 + r), z1 - r)
    return math.hypot(px - cx, pz - cz) <= r - rt + corner_tol


@settings(max_examples=300, deadline=None)
@given(strategies.tool_and_hinge())
def test_tool_stays_inside_pocket_and_reaches_every_side(case):
    d, h = case
    rt = d / 2
    xz, kinds = pocket_points_xz(h, d)
    assert len(xz) == h.path_points == len(kinds)
    # 6 points: the corners are cut with the tool radius, within the 0.5 mm milled-feature tolerance
    corner_tol = 0.5 + 1e-9 if h.path_points == 6 else 1e-9
    for px, pz in xz:
        assert _inside_rounded_pocket(px, pz, h, rt, corner_tol=corner_tol)
    # the contour touches all four sides of the pocket
    assert math.isclose(xz[:, 0].min(), h.x_mm + rt, abs_tol=1e-9)
    assert math.isclose(xz[:, 0].max(), h.x_mm + h.width_mm - rt, abs_tol=1e-9)
    assert math.isclose(xz[:, 1].min(), h.z_mm + rt, abs_tol=1e-9)
    assert math.isclose(xz[:, 1].max(), h.z_mm + h.length_mm - rt, abs_tol=1e-9)
    np.testing.assert_array_equal(xz[0], xz[-1])  # closed
    # counter-clockwise seen from the camera (X right, Z up): positive shoelace area
    area = 0.5 * np.sum(xz[:-1, 0] * xz[1:, 1] - xz[1:, 0] * xz[:-1, 1])
    degenerate = min(h.width_mm, h.length_mm) - d < 1e-6  # a slot exactly one tool wide: there and back
    assert area > 0 or (degenerate and abs(area) < 1e-6)


@settings(max_examples=200, deadline=None)
@given(strategies.tool_and_hinge())
def test_path_depth_approach_retract_and_corrections(case):
    d, h = case
    path = hinge_path(h, d, 3, clearance_mm=12.0)
    assert [p.name for p in path] == ["H3_APP", *(f"H3_P{k}" for k in range(1, h.path_points + 1)), "H3_RET"]
    assert {p.hinge for p in path} == {3}
    xz, _ = pocket_points_xz(h, d)
    corr = (
        np.array([[c.dx_mm, c.dy_mm, c.dz_mm] for c in h.corrections])
        if h.corrections
        else np.zeros((len(xz), 3))
    )
    pocket = np.array([p.point_door for p in path[1:-1]])
    expected = np.column_stack([xz[:, 0], np.full(len(xz), h.depth_mm), xz[:, 1]]) + corr
    np.testing.assert_allclose(pocket, expected, atol=1e-12)
    assert path[0].point_door == (xz[0, 0], -12.0, xz[0, 1]) and path[0].kind == "approach"
    assert path[-1].point_door == (pocket[-1, 0], -12.0, pocket[-1, 2]) and path[-1].kind == "retract"


def test_six_point_path_worked_example():
    h = Hinge(z_mm=200, length_mm=100, width_mm=30, x_mm=10, depth_mm=3, corner_radius_mm=8)
    pts = [p.point_door for p in hinge_path(h, 16.0)]
    assert pts == [
        (25.0, -10.0, 208.0),
        (25.0, 3.0, 208.0),
        (32.0, 3.0, 208.0),
        (32.0, 3.0, 292.0),
        (18.0, 3.0, 292.0),
        (18.0, 3.0, 208.0),
        (25.0, 3.0, 208.0),
        (25.0, -10.0, 208.0),
    ]


def test_nine_point_path_worked_example_with_corner_arcs():
    # corner radius 10, tool radius 6: tool-centre arcs of radius 4 around centres at x 20/30, z 210/290
    h = Hinge(
        z_mm=200,
        length_mm=100,
        width_mm=30,
        x_mm=10,
        depth_mm=3,
        corner_radius_mm=10,
        path_points=9,
        corrections=[PointCorrection(dz_mm=0.5)] + [PointCorrection()] * 8,
    )
    xz, kinds = pocket_points_xz(h, 12.0)
    assert xz.tolist() == [
        [20, 206],
        [30, 206],
        [34, 210],
        [34, 290],
        [30, 294],
        [20, 294],
        [16, 290],
        [16, 210],
        [20, 206],
    ]
    assert kinds == ["corner"] * 9
    assert hinge_path(h, 12.0)[1].point_door == (20.0, 3.0, 206.5)  # P1 carries its correction
