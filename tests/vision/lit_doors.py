"""Doors rendered under one cell lamp, for the tests of what a cell's doors measure together (its light,
``tests/vision/test_cell_light.py``; its camera's response, ``tests/vision/test_cell_response.py``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from doorloc.cell import DoorSize, load_cell
from doorloc.pose import DoorPose
from doorloc.sim.door import render_door
from doorloc.sim.effects import Effects

CELL_PATH = Path(__file__).parents[2] / "fixtures" / "cell_thesis.yaml"
CELL = load_cell(CELL_PATH)
#: the lamp, [azimuth, elevation] deg (cell frame), and the camera's response exponent of every door
LIGHT = (-45.0, 15.0)
CAMERA_GAMMA = 1.8


def lit_door(
    arris_mm: float,
    profile: str,
    pose: DoorPose,
    blur: float,
    seed: int,
    lamp: bool = True,
    light: tuple[float, float] = LIGHT,
    gamma: float = CAMERA_GAMMA,
    face_albedo: float = 0.7,
) -> tuple[np.ndarray, DoorSize]:
    """A 900 x 50 mm door with an arris of ``arris_mm`` (``profile``) at ``pose`` under the lamp ``LIGHT`` (or
    another at ``light``, [azimuth, elevation] deg; ``lamp`` False, ambient light alone), blurred by ``blur``
    px, through a camera of ``CAMERA_GAMMA`` (or ``gamma``), its hinge face's albedo ``face_albedo`` (0.7:
    the face at about 0.8 of full scale; 0.95 at about 0.95), its arrises' 0.93 times that: the image and
    the door."""
    door = DoorSize(900, 50.0, 2100, arris_mm=arris_mm, arris_profile=profile)
    fx = Effects(
        arris_profile=profile,
        albedo_hinge=face_albedo,
        albedo_chamfer=0.65 / 0.7 * face_albedo,
        albedo_background=0.12,
        light_ambient=0.45 if lamp else 1.05,
        light_directional=0.6 if lamp else 0.0,
        light_azimuth_deg=light[0],
        light_elevation_deg=light[1],
        blur_sigma_px=blur,
        read_noise_dn=0.5,
        gamma=gamma,
    )
    return render_door(CELL, door, pose, effects=fx, seed=seed).image, door
