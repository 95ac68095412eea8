#!/usr/bin/env python
"""Is the 1-sigma honest on JPEG frames of sharp doors? Each door located as a JPEG and as the same image
unquantised (the same noise), grouped by the rendered blur and by how near square the door lies.

Doors: plain photometry (albedos drawn, vignetting 0-0.4, a shading gradient), blur 0.15-1.2 px, noise 0-3
grey levels (shot noise in half of them), JPEG quality 80 / 88 / 95, 60 % of them within 0.15 deg of square
(their edges keep nearly one phase in JPEG's 8-px blocks), the rest anywhere in +-2 deg. The camera is exact
(``calibration_sigma_px`` 0). Per group: each axis's share within 2 sigma (ideal 95 %), how many beyond 4,
the worst, for JPEG and for the unquantised twin; then the JPEG answers' sigmas.

Each JPEG frame is located with its quality known, as the service, the CLI and batch read it from the file
(``--quality-unknown``: as an array whose file was not seen, where only the blocks the image shows tell it);
``--no-noise`` renders every door without noise (its flat blocks then show the block detector nothing).

    OMP_NUM_THREADS=1 PYTHONPATH=src python bench/bench_jpeg_doors.py [--n 800] [--seed 1000] [--workers 2]
        [--quality-unknown] [--no-noise]
"""

from __future__ import annotations

import argparse
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from functools import partial
from pathlib import Path

import numpy as np

from doorloc.cell import DoorSize, load_cell
from doorloc.pose import DoorPose
from doorloc.sim.door import render_door
from doorloc.sim.effects import Effects

CELL = Path(__file__).resolve().parents[1] / "fixtures" / "cell_thesis.yaml"
BLURS = ((0.15, 0.35), (0.35, 0.5), (0.5, 0.7), (0.7, 0.9), (0.9, 1.2))
NEAR_SQUARE_DEG = 0.15


def door(seed: int) -> tuple[DoorPose, DoorSize, Effects]:
    rng = np.random.default_rng(seed)
    bg = rng.uniform(0.08, 0.3)
    yaw = rng.uniform(-NEAR_SQUARE_DEG, NEAR_SQUARE_DEG) if rng.random() < 0.6 else rng.uniform(-2, 2)
    pose = DoorPose(rng.uniform(-10, 10), rng.uniform(-10, 10), yaw)
    size = DoorSize(900, rng.uniform(30, 100), 2100)
    eff = Effects(
        albedo_hinge=bg + rng.uniform(0.1, 0.45),
        albedo_background=bg,
        albedo_side=bg + rng.uniform(-0.05, 0.35),
        vignetting=rng.uniform(0.0, 0.4),
        gradient_u=rng.uniform(-0.25, 0.25),
        blur_sigma_px=rng.uniform(0.15, 1.2),
        full_well_e=float(rng.choice([0.0, 20000.0])),
        read_noise_dn=rng.uniform(0.0, 3.0),
        jpeg_quality=int(rng.choice([80, 88, 95])),
    )
    return pose, size, eff


def located(seed: int, quality_known: bool = True, noise: bool = True) -> dict:
    """One door as JPEG and unquantised: its blur, yaw and, for each, (errors, sigmas) or None if refused.
    ``quality_known``: the JPEG located with its quality (as read from a file); ``noise``: rendered with it."""
    from doorloc.vision.locate import locate

    cell = load_cell(CELL)
    cfg = replace(cell.locate, calibration_sigma_px=0.0, optics_edge_sigma_px=0.0)
    pose, size, eff = door(seed)
    if not noise:
        eff = replace(eff, read_noise_dn=0.0, full_well_e=0.0)
    out: dict = {"blur": eff.blur_sigma_px, "yaw": pose.yaw_deg, "quality": eff.jpeg_quality}
    for key, e in (("jpeg", eff), ("png", replace(eff, jpeg_quality=0))):
        image = render_door(cell, size, pose, effects=e, seed=seed).image
        quality = e.jpeg_quality if quality_known else 0
        r = locate(image, cell, size, config=cfg, jpeg_quality=quality)
        u = r.uncertainty
        out[key] = (
            None
            if not r.ok or u is None
            else (
                (r.x_mm - pose.x_mm, r.z_mm - pose.z_mm, r.yaw_deg - pose.yaw_deg),
                (u.x_mm, u.z_mm, u.yaw_deg),
            )
        )
    return out


def _coverage(rows: list[dict], key: str) -> str:
    z = np.array([np.abs(r[key][0]) / np.array(r[key][1]) for r in rows])
    within = " / ".join(f"{v:.1f}" for v in 100 * np.mean(z <= 2, axis=0))
    return f"{key}: within 2 sigma x/z/yaw {within} %, beyond 4 {np.sum(z > 4, axis=0).tolist()}, worst {z.max(0).round(1).tolist()}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=800)
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--quality-unknown", action="store_true", help="locate JPEGs without their quality")
    ap.add_argument("--no-noise", action="store_true", help="render every door without noise")
    a = ap.parse_args()
    one = partial(located, quality_known=not a.quality_unknown, noise=not a.no_noise)
    with ProcessPoolExecutor(a.workers) as pool:
        res = list(pool.map(one, range(a.seed, a.seed + a.n), chunksize=4))
    both = [r for r in res if r["jpeg"] is not None and r["png"] is not None]
    print(
        f"{a.n} doors from seed {a.seed}: {len(both)} answered as JPEG and PNG, "
        f"{sum(r['jpeg'] is None for r in res)} JPEG and {sum(r['png'] is None for r in res)} PNG refused"
    )
    for lo, hi in BLURS:
        for near in (True, False):
            g = [r for r in both if lo <= r["blur"] < hi and (abs(r["yaw"]) < NEAR_SQUARE_DEG) == near]
            if g:
                where = "near square" if near else "slanted"
                print(
                    f"blur {lo}-{hi} px, {where:11s} n={len(g):3d}  {_coverage(g, 'jpeg')} | {_coverage(g, 'png')}"
                )
    for q in sorted({r["quality"] for r in both}):
        g = [r for r in both if r["quality"] == q]
        print(f"JPEG quality {q}, n={len(g):3d}  {_coverage(g, 'jpeg')}")
    s = np.array([r["jpeg"][1] for r in both])
    print(
        f"JPEG sigma median x {np.median(s[:, 0]):.4f} z {np.median(s[:, 1]):.4f} mm yaw {np.median(s[:, 2]):.4f} deg"
    )


if __name__ == "__main__":
    main()
