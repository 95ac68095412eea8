#!/usr/bin/env python
"""Colour cameras: a door of one hue on a background of another, located with the image's channels summed
in stored levels (OpenCV's BT.601 luma, what locate did before 2026-12-06) and summed in light at the
cell's exponent (``doorloc.vision.luminance.luminance_plane``'s ``light_gamma``, what it does now).

Where the door and the background differ in hue, each channel's edge has its own contrast; every channel is
light through the camera's response, and a weighted sum of their stored levels is no stored level of any
light: it bends the edge's profile as a wrong exponent does. Each door's light is a wood colour's on a
blue-grey fixture's (levels drawn; ``doorloc.sim.door.render_hued_light``: the door alone and the
background alone rendered linear through the lens, each times its colour). Then, as a camera does: with
``--bayer``, an RGGB mosaic of that light, the noise drawn on it and OpenCV's bilinear demosaicing
(``doorloc.sim.effects.bayer_samples``, ``demosaiced``); without, the noise drawn per channel; the response
(a power law, its exponent drawn from 1.6-2.4 and stated exactly in the cell) to 8 bits; with ``--jpeg Q``,
a JPEG round trip (locate told its quality). Plain doors (no arris; ``--arris``: rounded or chamfered arrises of 0.5-3 mm,
the cell told their size, lit from one side), 0.8-1.6 px of blur, poses over the fixture's range.

Per way of summing: the answered share, x and z RMS, the share within 2 claimed sigma, and the response
check's readings beyond 2.5 of their sigmas from the camera's exponent.

    OMP_NUM_THREADS=1 PYTHONPATH=src python bench/bench_colour_doors.py [--n 24] [--seed 1] [--bayer]
        [--jpeg 90] [--arris]
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

from doorloc.cell import DoorSize, load_cell
from doorloc.pose import DoorPose
from doorloc.sim.door import render_hued_light
from doorloc.sim.effects import Effects, bayer_samples, demosaiced
from doorloc.vision.coarse import coarse_edges
from doorloc.vision.locate import locate_steps, run_steps
from doorloc.vision.luminance import luminance_plane

CELL = Path(__file__).resolve().parents[1] / "fixtures" / "cell_thesis.yaml"
#: a light wood and a blue-grey fixture, each channel's share of the light (BGR)
WOOD_BGR = np.array([0.35, 0.55, 0.80])
FIXTURE_BGR = np.array([0.30, 0.20, 0.12])
READ_NOISE_DN = 0.6


def hued_door(cell, rng: np.random.Generator, bayer: bool, jpeg: int, arris: bool):
    """One drawn door, its pose, the camera's exponent and its colour image (BGR, uint8)."""
    pose = DoorPose(rng.uniform(-8, 8), rng.uniform(-8, 8), rng.uniform(-1.5, 1.5))
    gamma, blur = rng.uniform(1.6, 2.4), rng.uniform(0.8, 1.6)
    door, lit = DoorSize(900, 40, 2100), {}
    if arris:
        profile = str(rng.choice(["round", "chamfer"]))
        door = DoorSize(900, float(rng.choice([40, 50, 70])), 2100, rng.uniform(0.5, 3.0), profile)
        lit = dict(
            arris_profile=profile,
            light_ambient=rng.uniform(0.4, 0.7),
            light_directional=rng.uniform(0.3, 0.6),
            light_azimuth_deg=float(rng.choice([-1, 1]) * rng.uniform(10, 80)),
            light_elevation_deg=rng.uniform(0, 30),
        )
    wood = dict(albedo_hinge=1.0, albedo_chamfer=1.0, albedo_side=0.8, albedo_end=0.7)
    hues = WOOD_BGR * rng.uniform(0.7, 1.0), FIXTURE_BGR * rng.uniform(0.3, 1.0)
    light = render_hued_light(cell, door, pose, *hues, Effects(blur_sigma_px=blur, **wood, **lit))
    noise = READ_NOISE_DN / 255.0
    if bayer:
        raw = bayer_samples(light)
        light = demosaiced(np.clip(raw + rng.normal(0.0, noise, raw.shape), 0.0, 1.0), "bilinear")
    else:
        light = light + rng.normal(0.0, noise, light.shape)
    img = np.rint(np.clip(light, 0.0, 1.0) ** (1.0 / gamma) * 255.0).astype(np.uint8)
    if jpeg:
        img = cv2.imdecode(
            cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, jpeg])[1], cv2.IMREAD_UNCHANGED
        )
    return door, pose, gamma, img


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=24)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--bayer", action="store_true", help="a single-chip camera: RGGB mosaic, demosaiced")
    ap.add_argument("--jpeg", type=int, default=0, help="a JPEG round trip at this quality (0: none)")
    ap.add_argument(
        "--arris", action="store_true", help="rounded or chamfered arrises of 0.5-3 mm, light from one side"
    )
    args = ap.parse_args()
    base = load_cell(CELL)
    rng = np.random.default_rng(args.seed)
    ways = {"stored levels": lambda img, g: luminance_plane(img, None), "light": luminance_plane}
    rows: dict[str, list] = {k: [] for k in ways}
    print(
        f"seed {args.seed}, {args.n} doors, bayer {args.bayer}, jpeg {args.jpeg or 'none'}, arris {args.arris}"
    )
    for i in range(args.n):
        door, pose, gamma, img = hued_door(base, rng, args.bayer, args.jpeg, args.arris)
        cell = replace(base, response_gamma=gamma)
        line = [f"  door {i:2d} g={gamma:.2f} a={door.arris_mm:.2f} {door.arris_profile}"]
        for name, summed in ways.items():
            lum = summed(img, gamma)
            r = run_steps(locate_steps(img, cell, door, luminance=lum, jpeg_quality=args.jpeg), coarse_edges)
            read = r.diagnostics.get("camera_response") or {}
            fitted, sigma = read.get("fitted"), read.get("sigma")
            off = abs(fitted - gamma) / sigma if fitted is not None and sigma else 0.0
            if r.ok:
                u = r.uncertainty
                rows[name].append((r.x_mm - pose.x_mm, r.z_mm - pose.z_mm, u.x_mm, u.z_mm, off))
                line.append(
                    f"{name}: ex {r.x_mm - pose.x_mm:+.4f} ez {r.z_mm - pose.z_mm:+.4f} sx {u.x_mm:.3f}"
                )
            else:
                rows[name].append((np.nan, np.nan, np.nan, np.nan, off))
                line.append(f"{name}: refused {r.error_code}")
        print(" | ".join(line), flush=True)
    for name, got in rows.items():
        a = np.array(got)
        ok = np.isfinite(a[:, 0])
        e = a[ok]
        within = (
            np.mean((np.abs(e[:, 0]) <= 2 * e[:, 2]) & (np.abs(e[:, 1]) <= 2 * e[:, 3])) if ok.any() else 0
        )
        print(
            f"summed in {name}: {ok.sum()}/{len(a)} answered, x RMS {np.sqrt(np.mean(e[:, 0] ** 2)):.4f} mm, "
            f"z RMS {np.sqrt(np.mean(e[:, 1] ** 2)):.4f} mm, within 2 sigma {100 * within:.0f} %, "
            f"response readings beyond 2.5 sigma {int(np.sum(a[:, 4] > 2.5))}"
        )


if __name__ == "__main__":
    main()
