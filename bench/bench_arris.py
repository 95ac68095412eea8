"""Arris and camera-response bias of locate on rendered doors, seeds printed.

Sets (each image: random pose inside the envelope, lighting, albedos, blur; see ``random_effects``):

- ``arris``: chamfer and round arrises of 0-3 mm, lit from either side (light azimuth +-10..80 deg);
- ``gamma``: a camera of response gamma 1.0-2.4 and a cell file that says so;
- ``wrong-gamma``: cameras of gamma 1.0-2.4 and a cell file that says another value drawn from 1.0-2.4
  (at least 0.3 away): the error and the claimed uncertainty (the camera response is absorbed or flagged);
- ``wrong-gamma-2.2``: gamma 2.2 cameras and a cell file that says 1.0;
- ``square-gamma``, ``square-wrong-gamma`` (not in the default sets): as ``gamma`` and ``wrong-gamma``
  (other seeds) with the door square to the camera (``|yaw| < 0.04 deg``: each edge at one pixel phase,
  where the response is read between the pixels or, below 1 px of blur, not at all);
- ``fixtures``: the committed rendered fixtures with a 1.5 mm chamfer and a gamma-2.2 camera
  (fixtures/rendered/effects), with the cell's ``response_gamma`` set to 2.2 and left at 1.0;
- ``timing`` (not in the default sets): thread-CPU time per frame of locate on those fixtures, and the part
  spent in the arris strip fit (the median of a second pass over the 27 frames).

Prints per image the seed, the conditions and the errors; per set the mean error (the bias), its
standard error, RMS, the fraction within 2 claimed sigma and beyond 5, and the refusals with their codes.

    OMP_NUM_THREADS=1 PYTHONPATH=src python bench/bench_arris.py [--n 24] [--sets arris,gamma,wrong-gamma,fixtures]
        [--response-factor F]   (the arris set with a cell whose response was measured, e.g. 1.11)
        [--seed S]              (another draw: the arris set's first seed, default 1000; the response sets'
                                 move by S - 1000 with it)
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import math
from pathlib import Path

import cv2
import numpy as np

from doorloc.cell import DoorSize, load_cell
from doorloc.pose import DoorPose
from doorloc.sim.door import render_door
from doorloc.sim.effects import Effects
from doorloc.vision.locate import locate

ROOT = Path(__file__).parents[1]
#: the square sets' largest yaw: the edges' phase then changes by under a quarter pixel along them
SQUARE_YAW_DEG = 0.04


def random_effects(rng: np.random.Generator, profile: str, gamma: float) -> Effects:
    """Wide random lighting, albedos and blur (not tuned to anything), mild sensor noise."""
    side = rng.choice([-1.0, 1.0])
    hinge, chamfer = rng.uniform(0.5, 0.9), rng.uniform(0.3, 0.95)
    amb, direct = rng.uniform(0.2, 1.0), rng.uniform(0.0, 0.9)
    k = min(1.0, 0.95 / (max(hinge, chamfer) * (amb + direct)))  # no face clips at white
    return Effects(
        arris_profile=profile,
        albedo_hinge=hinge,
        albedo_chamfer=chamfer,
        albedo_background=rng.uniform(0.05, 0.2),
        light_ambient=amb * k,
        light_directional=direct * k,
        light_azimuth_deg=side * rng.uniform(10.0, 80.0),
        light_elevation_deg=rng.uniform(-30.0, 60.0),
        blur_sigma_px=rng.uniform(0.6, 1.8),
        read_noise_dn=rng.uniform(0.0, 1.0),
        gamma=gamma,
    )


def _row(label, seed, res, pose, door, extra=""):
    if not res.ok:
        print(f"  seed {seed:5d} {label:34s} REFUSED {res.error_code}: {res.error[:80]}")
        return ("refused", res.error_code)
    ex, ez = res.x_mm - pose.x_mm, res.z_mm - pose.z_mm
    ux, uz = res.uncertainty.x_mm, res.uncertainty.z_mm
    # the reported uncertainty plus the per-line edge-model doubts (arris correction, response check)
    arr = {ln.name: getattr(ln, "arris_correction_sigma_mm", None) for ln in res.lines}
    rsp = {ln.name: getattr(ln, "response_sigma_mm", None) for ln in res.lines}
    sx = math.hypot(ux, arr.get("reference") or 0.0, rsp.get("reference") or 0.0)
    sz = math.hypot(uz, arr.get("bottom") or 0.0, rsp.get("bottom") or 0.0)
    print(
        f"  seed {seed:5d} {label:34s} ex {ex:+.4f} ez {ez:+.4f} dT {res.thickness_mm - door.thickness_mm:+.4f} "
        f"sigma x {sx:.4f} z {sz:.4f} (reported {ux:.4f} {uz:.4f}) {extra}"
    )
    return ex, ez, sx, sz, ux, uz


def _summary(name, rows, n_total):
    ok = [r for r in rows if r is not None and r[0] != "refused"]
    codes = sorted({r[1] for r in rows if r is not None and r[0] == "refused"})
    refused = {c: sum(1 for r in rows if r is not None and r[1] == c) for c in codes}
    print(f"{name}: {len(ok)}/{n_total} answered; refused: {refused or 'none'}")
    if not ok:
        return
    a = np.array(ok)
    for k, lab in ((0, "x"), (1, "z")):
        e = a[:, k]
        se = e.std(ddof=1) / math.sqrt(len(e)) if len(e) > 1 else float("nan")
        within = float(np.mean(np.abs(e) <= 2 * a[:, k + 2]))
        beyond = float(np.mean(np.abs(e) > 5 * a[:, k + 2]))
        print(
            f"  {lab}: bias {e.mean():+.4f} mm (+- {se:.4f} s.e.), RMS {np.sqrt(np.mean(e**2)):.4f}, "
            f"max |{np.abs(e).max():.4f}|, within 2 sigma {within:.0%}, beyond 5 sigma {beyond:.0%}, "
            f"median sigma {np.median(a[:, k + 2]):.4f}"
        )
        # the answer's own uncertainty (it holds the per-line doubts already: the figure above counts
        # them twice)
        u = a[:, k + 4]
        print(
            f"     reported uncertainty alone: within 2 sigma {float(np.mean(np.abs(e) <= 2 * u)):.0%}, "
            f"beyond 5 sigma {float(np.mean(np.abs(e) > 5 * u)):.0%}, median {np.median(u):.4f}"
        )


def run_arris(n: int, seed0: int = 1000, factor: float | None = None) -> None:
    cell = load_cell(ROOT / "fixtures" / "cell_thesis.yaml")
    if factor is not None:  # a cell whose response was measured (doorloc calibrate prints the factor)
        cell = dataclasses.replace(
            cell, locate=dataclasses.replace(cell.locate, response_unmeasured_factor=factor)
        )
    for profile in ("chamfer", "round"):
        rows = []
        for i in range(n):
            seed = seed0 + i + (0 if profile == "chamfer" else 500)
            rng = np.random.default_rng(seed)
            a = float(rng.uniform(0.0, 3.0)) if i else 0.0
            door = DoorSize(
                900, float(rng.choice([40.0, 50.0, 70.0])), 2100, arris_mm=a, arris_profile=profile
            )
            pose = DoorPose(rng.uniform(-8, 8), rng.uniform(-8, 8), rng.uniform(-1.5, 1.5))
            fx = random_effects(rng, profile, 1.0)
            img = render_door(cell, door, pose, effects=fx, seed=seed).image
            res = locate(img, cell, door)
            rows.append(_row(f"{profile} a={a:.2f} az={fx.light_azimuth_deg:+.0f}", seed, res, pose, door))
        _summary(f"arris {profile} 0-3 mm", rows, n)


def run_gamma(
    n: int, wrong: bool = False, seed0: int = 3000, fixed: bool = True, max_yaw_deg: float = 1.5
) -> None:
    base = load_cell(ROOT / "fixtures" / "cell_thesis.yaml")
    rows = []
    for i in range(n):
        seed = seed0 + i + (500 if wrong else 0) + (0 if fixed else 1000)
        rng = np.random.default_rng(seed)
        g = 2.2 if wrong and fixed else float(rng.uniform(1.0, 2.4))
        claimed = g
        if wrong:
            claimed = 1.0
            while not fixed and abs(claimed - g) < 0.3:
                claimed = round(float(rng.uniform(1.0, 2.4)), 2)
        profile = str(rng.choice(["chamfer", "round"]))
        a = float(rng.choice([0.0, rng.uniform(0.5, 3.0)]))
        door = DoorSize(900, 50, 2100, arris_mm=a, arris_profile=profile)
        pose = DoorPose(rng.uniform(-8, 8), rng.uniform(-8, 8), rng.uniform(-max_yaw_deg, max_yaw_deg))
        fx = random_effects(rng, profile, g)
        img = render_door(base, door, pose, effects=fx, seed=seed).image
        cell = dataclasses.replace(base, response_gamma=claimed)
        res = locate(img, cell, door)
        resp = res.diagnostics.get("camera_response", {}) if res.ok else {}
        fitted = f"fit {resp['fitted']:.2f}{'*' if resp.get('absorbed') else ''}" if "fitted" in resp else ""
        rows.append(
            _row(
                f"gamma {g:.2f} cell {cell.response_gamma:.2f} {profile} a={a:.2f}",
                seed,
                res,
                pose,
                door,
                fitted,
            )
        )
    name = (
        (
            "wrong response_gamma (camera 2.2, cell 1.0)"
            if fixed
            else "wrong response_gamma (camera and cell 1.0-2.4)"
        )
        if wrong
        else "gamma 1.0-2.4 with the cell's response_gamma"
    )
    _summary(
        name + (f", square to the camera (|yaw| < {max_yaw_deg:g} deg)" if max_yaw_deg < 1.5 else ""), rows, n
    )


def run_fixtures() -> None:
    d = ROOT / "fixtures" / "rendered" / "effects"
    base = load_cell(d / "cell.yaml")
    truth = list(csv.DictReader(open(d / "truth.csv")))
    for g in (2.2, 1.0):
        cell = dataclasses.replace(base, response_gamma=g)
        rows = []
        for r in truth:
            img = cv2.imread(str(d / r["image"]), cv2.IMREAD_UNCHANGED)
            door = DoorSize(
                float(r["width_mm"]),
                float(r["thickness_mm"]),
                float(r["height_mm"]),
                float(r["arris_mm"]),
                r["arris_profile"],
            )
            pose = DoorPose(float(r["x_mm"]), float(r["z_mm"]), float(r["yaw_deg"]))
            res = locate(img, cell, door)
            rows.append(_row(f"{r['image']} cell gamma {g}", int(r["seed"]), res, pose, door))
        _summary(f"fixtures/rendered/effects, cell response_gamma {g}", rows, len(truth))


def run_timing() -> None:
    import time

    import doorloc.vision.arris_lines as al

    d = ROOT / "fixtures" / "rendered" / "effects"
    base = load_cell(d / "cell.yaml")
    truth = list(csv.DictReader(open(d / "truth.csv")))
    spent = [0.0]
    fit = al.fit_strip_profile

    def timed(*a, **k):
        t = time.thread_time()
        out = fit(*a, **k)
        spent[0] += time.thread_time() - t
        return out

    al.fit_strip_profile = timed  # locate calls it through arris_lines, which imported it by name
    try:
        for g in (2.2, 1.0):
            cell = dataclasses.replace(base, response_gamma=g)
            frame, strip = [], []
            for rep in range(2):  # the first pass warms the caches
                for r in truth:
                    img = cv2.imread(str(d / r["image"]), cv2.IMREAD_UNCHANGED)
                    door = DoorSize(
                        float(r["width_mm"]),
                        float(r["thickness_mm"]),
                        float(r["height_mm"]),
                        float(r["arris_mm"]),
                        r["arris_profile"],
                    )
                    spent[0] = 0.0
                    t = time.thread_time()
                    locate(img, cell, door)
                    if rep:
                        frame.append(time.thread_time() - t)
                        strip.append(spent[0])
            print(
                f"fixtures/rendered/effects, cell response_gamma {g}: median thread CPU per frame "
                f"{1000 * np.median(frame):.1f} ms, of which the arris strip fit {1000 * np.median(strip):.1f} ms"
            )
    finally:
        al.fit_strip_profile = fit


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=24)
    ap.add_argument("--sets", default="arris,gamma,wrong-gamma,wrong-gamma-2.2,fixtures")
    ap.add_argument(
        "--response-factor",
        type=float,
        default=None,
        help="arris set: the cell's locate.response_unmeasured_factor (default: the cell's, 2.2); e.g. 1.11, "
        "what doorloc calibrate allows for a response measured to +-0.12 at 2.15 (Bouguet's photographs)",
    )
    ap.add_argument(
        "--seed",
        type=int,
        default=1000,
        help="arris set: first seed (chamfers S.., roundings S+500..); the response sets' move by S - 1000",
    )
    args = ap.parse_args()
    sets = args.sets.split(",")
    known = (
        "arris",
        "gamma",
        "wrong-gamma",
        "wrong-gamma-2.2",
        "fixtures",
        "timing",
        "square-gamma",
        "square-wrong-gamma",
    )
    if unknown := [s for s in sets if s not in known]:
        ap.error(f"unknown set(s) {', '.join(unknown)}; the sets are {', '.join(known)}")
    if "arris" in sets:
        run_arris(args.n, seed0=args.seed, factor=args.response_factor)
    g0 = 3000 + args.seed - 1000
    if "gamma" in sets:
        run_gamma(args.n, seed0=g0)
    if "wrong-gamma" in sets:
        run_gamma(args.n, wrong=True, fixed=False, seed0=g0)
    if "wrong-gamma-2.2" in sets:
        run_gamma(args.n, wrong=True, seed0=g0)
    if "square-gamma" in sets:
        run_gamma(args.n, seed0=g0 + 5000, max_yaw_deg=SQUARE_YAW_DEG)
    if "square-wrong-gamma" in sets:
        run_gamma(args.n, wrong=True, fixed=False, seed0=g0 + 5000, max_yaw_deg=SQUARE_YAW_DEG)
    if "fixtures" in sets:
        run_fixtures()
    if "timing" in sets:
        run_timing()


if __name__ == "__main__":
    main()
