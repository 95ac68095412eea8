"""The kernels' warm-ups cover the argument types locate passes on a realistic frame: a process started from a
numba cache that the warm-ups filled (the container image, the service's start) compiles nothing on its first
image, 8-bit or 16-bit, grey or colour. A missed type (a read-only cached table, a camera's read-only
coefficients) had cost the first realistic frame 6 s; an arris strip's read-only candidates one more kernel."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

# Run in a process of its own: kernels compiled by other tests in this one would hide a missing warm-up.
SCRIPT = textwrap.dedent(
    """
    import json
    from dataclasses import replace

    import cv2
    import numpy as np

    from doorloc.calib.camera import CameraModel
    from doorloc.cell import load_cell
    from doorloc.domain import DoorSize
    from doorloc.sim.dataset import random_poses
    from doorloc.sim.door import render_door
    from doorloc.sim.effects import Effects
    from doorloc.vision import jit
    from doorloc.vision.imageio import decode_image
    from doorloc.vision.locate import locate

    base = load_cell("fixtures/cell_thesis.yaml")
    cam = base.camera
    # a realistic cell: a distorting lens, a measured response; grain, noise, shading; PNG and JPEG
    cell = replace(
        base,
        camera=CameraModel(cam.camera_matrix, np.array([-0.08, 0.05, 0.0, 0.0, 0.0]), cam.image_size),
        response_gamma=2.2,
        response_gamma_sigma=0.05,
    )
    images = []
    # sharp doors, and a rounded and a chamfered arris (the strip fits' kernels)
    doors = [(0.0, "chamfer"), (0.0, "chamfer"), (2.0, "round"), (1.5, "chamfer")]
    for k, pose in enumerate(random_poses(cell.envelope, 4, 11)):
        door = DoorSize(900.0, 40.0 + 5 * k, 2100.0, *doors[k])
        fx = Effects(arris_profile=door.arris_profile, gamma=2.2, full_well_e=9000.0, read_noise_dn=1.5,
                     blur_sigma_px=0.8, gradient_u=0.1, vignetting=0.1, grain_contrast=0.05)
        img = render_door(cell, door, pose, effects=fx, seed=k).image
        images.append((img, door))
        images.append((decode_image(cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 95])[1].tobytes()), door))
        # a 16-bit camera's frame (its low byte noise) and a colour one (BGR JPEG): other planes' types
        deep = img.astype(np.uint16) * 256 + np.random.default_rng(k).integers(0, 256, img.shape, np.uint16)
        images.append((decode_image(cv2.imencode(".png", deep)[1].tobytes()), door))
        colour = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
        images.append((decode_image(cv2.imencode(".jpg", colour, [cv2.IMWRITE_JPEG_QUALITY, 90])[1].tobytes()), door))
    jit.compile_kernels()
    before = jit.compiled_signatures()
    answered = sum(locate(img, cell, door).ok for img, door in images)
    after = jit.compiled_signatures()
    print(json.dumps({"answered": answered, "added": {k: after[k] - before.get(k, 0) for k in after
                                                      if after[k] != before.get(k, 0)}}))
    """
)


@pytest.mark.slow
def test_locate_compiles_nothing_after_the_warm_ups():
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT], cwd=REPO, capture_output=True, text=True, check=True
    ).stdout
    res = json.loads(out.strip().splitlines()[-1])
    assert res["answered"] >= 12, res  # (the frames went the whole way: every stage's kernels ran)
    assert res["added"] == {}, res
