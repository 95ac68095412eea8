#!/usr/bin/env python
"""The camera response measured on chessboard photographs (`doorloc calibrate`'s `response_gamma`).

- rendered: chessboards seen by the thesis camera at random poses, camera exponents 1.0, 1.6, 2.2 and 2.4,
  blur 0.6-1.8 px and read noise 0-3 grey levels drawn per photograph (seeds printed): the measured exponent,
  its sigma, and the error in sigmas;
- real: the two published photograph sets in ../shared/data (their cameras' exponents are not published:
  the figure is the measurement and its scatter).

Run:  OMP_NUM_THREADS=1 python bench/bench_response_boards.py [--views 8]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from doorloc.calib.detect import Chessboard
from doorloc.calib.folder import detect_views, full_board_views, read_folder
from doorloc.cell import load_cell
from doorloc.sim.boards import Checkerboard, render_board
from doorloc.sim.effects import Effects
from doorloc.vision.board_response import board_response

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data"


def rendered(gamma: float, n_views: int, seed: int) -> None:
    cam = load_cell(REPO / "fixtures" / "cell_thesis.yaml").camera
    board = Checkerboard(9, 6, 25.0)
    rng = np.random.default_rng(seed)
    views = []
    while len(views) < n_views:
        rvec = rng.uniform(-0.5, 0.5, 3)
        tvec = [rng.uniform(-150, 30), rng.uniform(-120, 20), rng.uniform(400, 750)]
        fx = Effects(gamma=gamma, blur_sigma_px=rng.uniform(0.6, 1.8), read_noise_dn=rng.uniform(0.0, 3.0))
        rb = render_board(cam, board, rvec, tvec, effects=fx, seed=seed * 100 + len(views))
        if rb.in_image.all():
            views.append((rb.image, rb.corners_px))
    r = board_response(views, 9, 6)
    if r is None:
        print(f"  rendered gamma {gamma:.1f} (seed {seed}): not measured")
        return
    print(
        f"  rendered gamma {gamma:.1f} (seed {seed}): {r.gamma:.3f} +- {r.sigma:.3f}, error "
        f"{(r.gamma - gamma) / r.sigma:+.1f} sigma; per photograph "
        + " ".join(f"{g:.2f}" for g in r.per_image)
    )


def real(folder: str, glob: str, board: Chessboard) -> None:
    images = read_folder(DATA / folder, glob)
    views = full_board_views(images, detect_views(images, board).scan, board)
    r = board_response(views, board.cols, board.rows)
    if r is None:
        print(f"  {folder}: not measured")
        return
    print(
        f"  {folder}: {r.gamma:.3f} +- {r.sigma:.3f} over {len(r.per_image)} photographs (factor "
        f"{r.unmeasured_factor:.2f}); per photograph " + " ".join(f"{g:.2f}" for g in r.per_image)
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--views", type=int, default=8)
    args = ap.parse_args()
    print("camera response from chessboard photographs")
    for i, g in enumerate((1.0, 1.6, 2.2, 2.4)):
        rendered(g, args.views, 7000 + i)
    real("opencv-left", "left*.jpg", Chessboard(9, 6, 25.0))
    real("bouguet-calib-example", "Image*.png", Chessboard(13, 12, 30.0))


if __name__ == "__main__":
    main()
