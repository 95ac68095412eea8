#!/usr/bin/env python
"""Doors through a camera that saturates below white: refused, or answered within their sigmas?

A sensor or tone curve may store every light beyond some level under 255 at that level (OpenCV's public
board photographs pile their overexposed squares at 245-250 grey, Bouguet's at 240). A hinge face so clipped
is flat there, under the 249 that locate's white check reads, and its edges are drawn towards the dark side.
This bench renders the scenes of ``bench_camera_doors.py`` (the hard sets' light, grain and chamfers; blur
0.6-1.8 px, read noise 0.5-3 grey, JPEG 88 / 95 or none) through a power-law camera (``--gamma``, stated in
the cell) that clips at ``--clip`` of full scale, with the scene's bright end exposed to ``--over``
(overexposed) and to ``--under`` (below the clip: 0.85 of full scale in light is 0.93 in grey through 2.2)
times what stores full scale, and locates each door three times: with locate's clip check
(``locate.clipped_flat_share``, the default), without it (above 1: off), and with the cell told the
camera's clip (``told``: its camera model's ``clip_level``, as ``doorloc check-model --boards`` writes it
where the board photographs show a clip). Per column: answered, refusals by code, RMS and max error of x
and z, the share within 2 claimed sigma and the largest |error| / sigma.

    OMP_NUM_THREADS=1 PYTHONPATH=src python bench/bench_clipped_camera.py [--n 24] [--seed 4100]
        [--clip 0.941] [--gamma 2.2] [--over 1.0 1.6] [--under 0.5 0.85]
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).parent))

from bench_camera_doors import REPO, run_column, scenes, show  # noqa: E402

from doorloc.cell import load_cell  # noqa: E402
from doorloc.photometric.model import PhotometricModel  # noqa: E402


def exposed(items: list, lo: float, hi: float, seed: int) -> list:
    """``items`` with each camera's exposure (of the scene's bright end, as a share of what stores full scale
    before the clip) drawn in ``[lo, hi]``."""
    rng = np.random.default_rng(seed)
    return [
        (name, pose, door, scene, dataclasses.replace(cam, exposure=float(rng.uniform(lo, hi))), s)
        for name, pose, door, scene, cam, s in items
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=24)
    ap.add_argument("--seed", type=int, default=4100)
    ap.add_argument("--clip", type=float, default=240 / 255, help="the camera's clip, share of full scale")
    ap.add_argument("--gamma", type=float, default=2.2)
    ap.add_argument("--over", type=float, nargs=2, default=(1.0, 1.6))
    ap.add_argument("--under", type=float, nargs=2, default=(0.5, 0.85))
    a = ap.parse_args()
    cell = load_cell(REPO / "fixtures" / "cell_thesis.yaml")
    unchecked = dataclasses.replace(cell, locate=dataclasses.replace(cell.locate, clipped_flat_share=1.01))
    camera = PhotometricModel(gamma=a.gamma, clip_level=a.clip)
    items = list(scenes(a.n, a.seed))
    print(f"{a.n} doors, seed {a.seed}; camera gamma {a.gamma:g} clipping at {255 * a.clip:.0f} grey")
    for label, (lo, hi) in (("over", a.over), ("under", a.under)):
        shot = exposed(items, lo, hi, a.seed + (7 if label == "over" else 8))
        print(f"exposure {lo:g}-{hi:g} of full scale ({label})")
        show("checked", run_column(cell, camera, a.gamma, shot))
        show("unchecked", run_column(unchecked, camera, a.gamma, shot))
        show("told", run_column(cell, camera, a.gamma, shot, told=True))


if __name__ == "__main__":
    main()
