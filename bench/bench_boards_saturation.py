#!/usr/bin/env python
"""Saturated squares on the public board photographs: the edge offset against the bright square's level, and
what an edge fit that treats clipped samples as censored gives.

On OpenCV's set the plain edge offset (the area estimator against the board's corner lines) grows with the
bright square's grey level: about 0 px below 200 grey and -0.3 to -0.5 px (towards the dark side) from 245 up,
while the normalised profile's bright half reaches its plateau early. That is a sensor or tone curve that
clips an overexposed square: the area estimator takes the clipped level for the true one. The censored fit
here reads such an edge from the samples below ``--cut`` of the plateau only, as a Gaussian-blurred step
whose true bright level is free (at least the clipped one), with the camera's blur measured on the edges
that are not clipped (an error-function fit with its position free, so the corner lines are never an input).

Prints per set: the offset by bright level and by edge direction (the signatures), the camera's blur, per
photograph the median offset plain and censored, and the RMS over photographs of both. No parameter is fitted
to the offsets; this is an analysis of the data, not yet a cause in :mod:`doorloc.photometric.catalogue`.

Run:  OMP_NUM_THREADS=1 PYTHONPATH=src python bench/bench_boards_saturation.py [--level 240] [--cut 0.85]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares
from scipy.special import ndtr

from doorloc.calib.detect import Chessboard
from doorloc.photometric.check import measure_boards
from doorloc.photometric.fit import Photograph, noise_floor_px

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
SETS = (("opencv-left", Chessboard(9, 6, 25.0)), ("bouguet-calib-example", Chessboard(13, 12, 30.0)))


def normalised(photo: Photograph) -> tuple[np.ndarray, np.ndarray]:
    """Each scan line's samples: distance from the board's edge (px along the normal, + towards bright) and
    grey scaled to 0 on the dark plateau and 1 on the bright one (N, L) each."""
    e = photo.edges
    d = e.windows.distance_px()
    z = (e.windows.grey - e.dark[:, None]) / (e.bright - e.dark)[:, None]
    return d, z


def step_blur_px(d: np.ndarray, z: np.ndarray) -> float:
    """Blur sigma (px) of one unclipped scan line: an error function with its position free."""
    r = least_squares(lambda p: ndtr((d - p[0]) / p[1]) - z, [0.0, 1.0], bounds=([-3, 0.3], [3, 5]))
    return float(r.x[1])


def censored_offset_px(d: np.ndarray, z: np.ndarray, blur_px: float, cut: float) -> float:
    """Edge offset (px) of one clipped scan line from its samples below ``cut``: ``r * Phi((d - x0) / blur)``
    with ``r >= 1`` the true bright level over the clipped one."""
    m = z < cut
    if m.sum() < 3:
        return float("nan")
    r = least_squares(
        lambda p: p[1] * ndtr((d[m] - p[0]) / blur_px) - z[m], [0.0, 1.2], bounds=([-3, 1.0], [3, 5])
    )
    return float(r.x[0])


def signatures(photos: list[Photograph]) -> None:
    off = np.concatenate([p.edges.offset_px for p in photos])
    bright = np.concatenate([p.edges.bright for p in photos])
    normal = np.concatenate([p.edges.normal[p.edges.windows.edge] for p in photos])
    ok = np.isfinite(off)
    print("  plain offset by the bright square's level (grey): ", end="")
    for lo, hi in ((0, 200), (200, 230), (230, 245), (245, 252), (252, 256)):
        m = ok & (bright >= lo) & (bright < hi)
        if m.sum() >= 20:
            print(f"{lo}-{hi}: {np.median(off[m]):+.3f} px (n {m.sum()})  ", end="")
    print()
    quadrant = np.round(np.arctan2(normal[:, 1], normal[:, 0]) / (np.pi / 2)).astype(int) % 4
    print(
        "  plain offset by the bright side's direction (+u, +v, -u, -v): "
        + "  ".join(f"{np.median(off[ok & (quadrant == q)]):+.3f}" for q in range(4))
        + " px"
    )


def run(folder: str, board: Chessboard, level: float, cut: float) -> None:
    measured = measure_boards(DATA / folder, board)
    photos = measured.photographs
    print(f"{folder}: {len(photos)} photographs ({measured.camera_source})")
    signatures(photos)
    blurs = []
    for p in photos:
        d, z = normalised(p)
        unclipped = np.flatnonzero(np.isfinite(p.edges.offset_px) & (p.edges.bright < level))
        blurs += [step_blur_px(d[i], z[i]) for i in unclipped[::10]]
    blur = float(np.median(blurs))
    print(f"  camera blur from {len(blurs)} unclipped scan lines: sigma {blur:.3f} px")
    plain, censored, noise = [], [], []
    for p in photos:
        d, z = normalised(p)
        off = p.edges.offset_px.copy()
        ok = np.isfinite(off)
        clipped = np.flatnonzero(ok & (p.edges.bright >= level))
        for i in clipped:
            off[i] = censored_offset_px(d[i], z[i], blur, cut)
        plain.append(float(np.median(p.edges.offset_px[ok])))
        censored.append(float(np.nanmedian(off[ok])))
        noise.append(noise_floor_px(p))
        print(
            f"    {p.name}: {clipped.size}/{ok.sum()} scan lines clipped, median offset "
            f"{plain[-1]:+.3f} -> {censored[-1]:+.3f} px"
        )
    rms = lambda x: float(np.sqrt(np.nanmean(np.square(x))))  # noqa: E731
    print(
        f"  RMS over photographs of the median offset: plain {rms(plain):.4f} px, censored {rms(censored):.4f} px "
        f"(standard error from noise {rms(noise):.4f} px)"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "--level", type=float, default=240.0, help="bright plateau (grey) from which a line is clipped"
    )
    ap.add_argument(
        "--cut", type=float, default=0.85, help="samples below this fraction of the plateau are fitted"
    )
    a = ap.parse_args()
    print(
        f"clipped: bright plateau >= {a.level:g} grey; censored fit on samples below {a.cut:g} of the plateau"
    )
    for folder, board in SETS:
        run(folder, board, a.level, a.cut)


if __name__ == "__main__":
    main()
