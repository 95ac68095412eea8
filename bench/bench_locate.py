#!/usr/bin/env python
"""Accuracy, refusals and speed of `doorloc.vision.locate` over rendered sets (the accuracy and speed figures).

Sets (all rendered with `doorloc.sim.door.render_door` through the thesis cell, fixtures/cell_thesis.yaml):

- grid     default photometry, the +-10 mm / +-2 deg grid (27 poses), thickness cycling 30..100 mm
- random   default photometry, random poses in the envelope, thickness U(30, 100) mm, width 900 mm
- widths   default photometry, widths U(700, 1100) mm on the centred fixture (hinge-face depth changes)
- hard     hinge face only slightly brighter than the background, illumination gradient, vignetting, wood
           grain, blur up to 2 px, read noise up to 4 grey levels, JPEG 85 on half of them
- thin     hard photometry on thin doors (28-40 mm) at x in +-10 mm: the far face often in view beside the
           far arris (brighter or darker than the hinge face)
- bad      inputs that must be refused (and an overexposed image: refused or within 0.05 mm)

Speed: median locate time (decode excluded, one thread) over the default-photometry images, and in the
same run a plain Canny + cv2.fitLine pipeline on the same images (the baseline of the issue), with its
accuracy for comparison.

Run:  OMP_NUM_THREADS=1 python bench/bench_locate.py [--quick] [--json out.json]
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402
from collections import Counter  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from doorloc.cell import DoorSize, load_cell  # noqa: E402
from doorloc.pose import DoorPose  # noqa: E402
from doorloc.sim.door import render_door  # noqa: E402
from doorloc.sim.effects import Effects  # noqa: E402
from doorloc.vision.locate import locate  # noqa: E402
from doorloc.vision.metric import PlaneMap  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


# -- data sets -------------------------------------------------------------------------------------
def grid_set():
    ts = [30.0, 47.5, 65.0, 82.5, 100.0]
    i = 0
    for x in (-10.0, 0.0, 10.0):
        for z in (-10.0, 0.0, 10.0):
            for yaw in (-2.0, 0.0, 2.0):
                yield f"grid_{i:03d}", DoorPose(x, z, yaw), DoorSize(900, ts[i % len(ts)], 2100), None, i
                i += 1


def random_set(n, seed, widths=False):
    rng = np.random.default_rng(seed)
    for i in range(n):
        pose = DoorPose(*rng.uniform([-10, -10, -2], [10, 10, 2]))
        w = rng.uniform(700, 1100) if widths else 900.0
        yield (
            f"{'widths' if widths else 'random'}_{i:03d}",
            pose,
            DoorSize(w, rng.uniform(30, 100), 2100),
            None,
            i,
        )


def hard_set(n, seed):
    rng = np.random.default_rng(seed)
    for i in range(n):
        pose = DoorPose(*rng.uniform([-10, -10, -2], [10, 10, 2]))
        bg = rng.uniform(0.15, 0.25)
        eff = Effects(
            albedo_hinge=bg + rng.uniform(0.12, 0.2),
            albedo_background=bg,
            albedo_side=bg + 0.25,
            gradient_u=rng.uniform(-0.2, 0.2),
            gradient_v=rng.uniform(-0.2, 0.2),
            vignetting=rng.uniform(0, 0.4),
            grain_contrast=rng.uniform(0.0, 0.03),
            blur_sigma_px=rng.uniform(0.0, 2.0),
            read_noise_dn=rng.uniform(1.0, 4.0),
            jpeg_quality=85 if i % 2 else 0,
        )
        yield f"hard_{i:03d}", pose, DoorSize(900, rng.uniform(30, 100), 2100), eff, i


def thin_set(n, seed):
    """Hard photometry on thin doors shifted towards -X: the camera (cell X = 30 mm) sees the far face as a
    band beside the far arris, often brighter than the hinge face (side albedo above the hinge's)."""
    rng = np.random.default_rng(seed)
    for i, (_, _, _, eff, s) in enumerate(hard_set(n, seed + 1000)):
        t = rng.uniform(28.0, 40.0)
        pose = DoorPose(rng.uniform(-10.0, 10.0), rng.uniform(-10, 10), rng.uniform(-2, 2))
        if i % 3 == 0:  # the far face darker than the hinge face
            eff = replace(eff, albedo_side=eff.albedo_background + 0.06)
        yield f"thin_{i:03d}", pose, DoorSize(900, t, 2100), eff, s


def bad_set(cell):
    """(name, image, door, expected refusal) — or expected None for 'refused or accurate'."""
    w, h = cell.camera.image_size
    rng = np.random.default_rng(7)
    d50 = DoorSize(900, 50, 2100)
    out = [
        ("no_door", np.clip(rng.normal(32, 2, (h, w)), 0, 255).astype(np.uint8), d50, DoorPose()),
        ("black", rng.integers(0, 3, (h, w), dtype=np.uint8), d50, DoorPose()),
        ("noise", rng.integers(0, 256, (h, w), dtype=np.uint8), d50, DoorPose()),
        (
            "wrong_size",
            cv2.resize(render_door(cell, d50, DoorPose()).image, (1280, 720), interpolation=cv2.INTER_AREA),
            d50,
            DoorPose(),
        ),
        (
            "outside_envelope_x+25mm",
            render_door(cell, d50, DoorPose(35.0, 0.0, 0.0)).image,
            d50,
            DoorPose(35, 0, 0),
        ),
        (
            "outside_envelope_z-25mm",
            render_door(cell, d50, DoorPose(0.0, -35.0, 0.0)).image,
            d50,
            DoorPose(0, -35, 0),
        ),
        ("yaw_6deg", render_door(cell, d50, DoorPose(0.0, 0.0, 6.0)).image, d50, DoorPose(0, 0, 6)),
        (
            "clamp_over_corner",
            _clamp(cell, d50, render_door(cell, d50, DoorPose(1.0, 1.0, 0.3)).image),
            d50,
            DoorPose(1, 1, 0.3),
        ),
        (
            "panel_12mm_recipe_50mm",
            render_door(cell, DoorSize(900, 12, 2100), DoorPose()).image,
            d50,
            DoorPose(),
        ),
        ("calibration_board", _board(cell), d50, DoorPose()),
        ("saturated", np.full((h, w), 255, np.uint8), d50, DoorPose()),
        (
            "overexposed",
            render_door(
                cell, d50, DoorPose(1.0, -2.0, 0.5), effects=Effects(albedo_hinge=1.4, albedo_background=0.3)
            ).image,
            d50,
            DoorPose(1, -2, 0.5),
        ),
    ]
    return out


def _clamp(cell, door, img):
    """A grey clamp block (18 x 18 mm) painted over the reference corner."""
    pm = PlaneMap(cell.posed_camera, cell.face_y(door))
    (u0, v0), (u1, v1) = pm.to_image(np.array([[-8.0, 10.0], [10.0, -8.0]]))
    img = img.copy()
    img[int(v0) : int(v1), int(u0) : int(u1)] = 90
    return img


def _board(cell):
    from doorloc.sim.boards import Checkerboard, render_board

    return render_board(
        cell.camera, Checkerboard(11, 7, 20.0), [0.05, -0.1, 0.02], [-120.0, -60.0, 420.0]
    ).image


# -- baseline: Canny + cv2.fitLine -----------------------------------------------------------------
def baseline(img, cell, door):
    """A plain pipeline: Canny over the frame, edge pixels in fixed bands around the nominal edges,
    cv2.fitLine (Huber) per edge in pixels, corner = intersection, back-projected to the hinge-face plane;
    yaw from the bottom line (as in the thesis), thickness between the arris lines."""
    pm = PlaneMap(cell.posed_camera, cell.face_y(door))
    edges = cv2.Canny(img, 40, 120)
    c0 = pm.to_image(np.array([[0.0, 0.0]]))[0]
    scale = 0.2056
    band = (cell.envelope.x_mm + 3.0) / scale
    t_px = door.thickness_mm / scale
    vs, us = np.nonzero(edges)

    def fit(mask):
        if mask.sum() < 10:
            return None
        pts = np.stack([us[mask], vs[mask]], 1).astype(np.float32)
        vx, vy, x0, y0 = cv2.fitLine(pts, cv2.DIST_HUBER, 0, 0.01, 0.01).ravel()
        return np.array([x0, y0]), np.array([vx, vy])

    ref = fit((np.abs(us - c0[0]) < band) & (vs < c0[1] - band - 10) & (vs > 5))
    far = fit((np.abs(us - c0[0] - t_px) < band) & (vs < c0[1] - band - 10) & (vs > 5))
    if ref is None or far is None:
        return None
    # bottom-end pixels between the two fitted arrises (10 px inset), near the nominal bottom row
    u_ref = ref[0][0] + (vs - ref[0][1]) * ref[1][0] / ref[1][1]
    u_far = far[0][0] + (vs - far[0][1]) * far[1][0] / far[1][1]
    bot = fit((np.abs(vs - c0[1]) < band) & (us > u_ref + 10) & (us < u_far - 10))
    if bot is None:
        return None

    def inter(a, b):
        (p, d), (q, e) = a, b
        t = np.linalg.solve(np.stack([d, -e], 1), q - p)
        return p + t[0] * d

    corner = pm.to_plane(inter(ref, bot)[None])[0]
    b0, b1 = pm.to_plane(np.stack([bot[0], bot[0] + 100 * bot[1]]))
    yaw = math.degrees(math.atan2(b1[1] - b0[1], b1[0] - b0[0]))
    if yaw > 90:
        yaw -= 180
    elif yaw < -90:
        yaw += 180
    fc = pm.to_plane(inter(far, bot)[None])[0]
    return corner[0], corner[1], yaw, float(np.hypot(*(fc - corner)))


# -- run ---------------------------------------------------------------------------------------------
def stats(errs):
    e = np.array(errs, float).reshape(-1, 4)
    if e.size == 0:
        return {}
    names = ("x_mm", "z_mm", "yaw_deg", "thickness_mm")
    return (
        {f"rms_{k}": float(np.sqrt(np.mean(e[:, i] ** 2))) for i, k in enumerate(names)}
        | {f"max_{k}": float(np.max(np.abs(e[:, i]))) for i, k in enumerate(names)}
        | {f"median_abs_{k}": float(np.median(np.abs(e[:, i]))) for i, k in enumerate(names)}
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer images per set")
    ap.add_argument("--json", type=Path, help="also write the figures here")
    ap.add_argument(
        "--speed-only", action="store_true", help="only the timing comparison (skip the accuracy sets)"
    )
    args = ap.parse_args()
    cv2.setNumThreads(1)
    cell = load_cell(REPO / "fixtures" / "cell_thesis.yaml")
    n_rand, n_w, n_hard = (10, 6, 10) if args.quick else (40, 24, 40)
    sets = {
        "grid": list(grid_set()),
        "random": list(random_set(n_rand, 11)),
        "widths": list(random_set(n_w, 12, widths=True)),
        "hard": list(hard_set(n_hard, 13)),
        "thin": list(thin_set(n_hard, 14)),
    }
    report: dict = {"sets": {}, "bad": {}, "speed": {}}
    ours_ms, base_ms, base_err, worst = [], [], [], {"pos_mm": 0.0, "yaw_deg": 0.0}
    for set_name, items in sets.items():
        if args.speed_only:
            break
        errs, refusals = [], Counter()
        for name, pose, door, eff, seed in items:
            img = render_door(cell, door, pose, effects=eff, seed=seed).image
            r = locate(img, cell, door, image_name=name)
            if not r.ok:
                refusals[r.error_code] += 1
                print(f"  {name}: refused {r.error_code}: {r.error}")
                continue
            e = (
                r.x_mm - pose.x_mm,
                r.z_mm - pose.z_mm,
                r.yaw_deg - pose.yaw_deg,
                r.thickness_mm - door.thickness_mm,
            )
            errs.append(e)
            worst["pos_mm"] = max(worst["pos_mm"], abs(e[0]), abs(e[1]))
            worst["yaw_deg"] = max(worst["yaw_deg"], abs(e[2]))
            if eff is None:  # speed on default photometry, both pipelines on the same image
                ours_ms.append(r.elapsed_ms)
                t0 = time.perf_counter()
                b = baseline(img, cell, door)
                base_ms.append((time.perf_counter() - t0) * 1e3)
                if b is not None:
                    base_err.append(
                        (b[0] - pose.x_mm, b[1] - pose.z_mm, b[2] - pose.yaw_deg, b[3] - door.thickness_mm)
                    )
        s = {"n": len(items), "ok": len(errs), "refused": dict(refusals)} | stats(errs)
        report["sets"][set_name] = s
        print(
            f"{set_name:7s} n={s['n']:3d} ok={s['ok']:3d} refused={dict(refusals)}  RMS x {s.get('rms_x_mm', float('nan')):.4f} "
            f"z {s.get('rms_z_mm', float('nan')):.4f} mm, yaw {s.get('rms_yaw_deg', float('nan')):.5f} deg, "
            f"T {s.get('rms_thickness_mm', float('nan')):.4f} mm | max x {s.get('max_x_mm', float('nan')):.4f} "
            f"z {s.get('max_z_mm', float('nan')):.4f} yaw {s.get('max_yaw_deg', float('nan')):.5f} T {s.get('max_thickness_mm', float('nan')):.4f}"
        )
    print("bad inputs:")
    for name, img, door, pose in [] if args.speed_only else bad_set(cell):
        r = locate(img, cell, door, image_name=name)
        entry = {"ok": r.ok, "error_code": r.error_code, "error": r.error}
        if r.ok:
            entry["error_mm"] = max(abs(r.x_mm - pose.x_mm), abs(r.z_mm - pose.z_mm))
            worst["pos_mm"] = max(worst["pos_mm"], entry["error_mm"])
            worst["yaw_deg"] = max(worst["yaw_deg"], abs(r.yaw_deg - pose.yaw_deg))
        report["bad"][name] = entry
        verdict = f"OK (err {entry['error_mm']:.4f} mm)" if r.ok else f"refused {r.error_code}"
        print(f"  {name:26s} {verdict}: {r.error or ''}")
    # Timing on a shared machine: interleave both pipelines on the same images, repeat each image,
    # and keep per image the best of the repeats (what the code costs, not what other processes cost),
    # next to the plain median over all calls.
    timing_items = sets["random"][:12]
    imgs = [render_door(cell, d, p).image for _, p, d, _, _ in timing_items]
    doors = [d for _, _, d, _, _ in timing_items]
    best_ours, best_base, all_ours, all_base = [], [], [], []
    for img, d in zip(imgs, doors, strict=True):
        o, b_ = [], []
        for _ in range(5):
            o.append(locate(img, cell, d).elapsed_ms)
            t0 = time.perf_counter()
            baseline(img, cell, d)
            b_.append((time.perf_counter() - t0) * 1e3)
        best_ours.append(min(o))
        best_base.append(min(b_))
        all_ours += o
        all_base += b_
    sp = {
        "locate_median_ms": float(np.median(ours_ms + all_ours)),
        "baseline_canny_fitline_median_ms": float(np.median(base_ms + all_base)),
        "locate_median_of_best_of_5_ms": float(np.median(best_ours)),
        "baseline_median_of_best_of_5_ms": float(np.median(best_base)),
        "threads": 1,
        "n_timed": len(ours_ms) + len(all_ours),
    }
    sp["ratio_best_of_5"] = sp["locate_median_of_best_of_5_ms"] / sp["baseline_median_of_best_of_5_ms"]
    sp["ratio_locate_over_baseline"] = sp["locate_median_ms"] / sp["baseline_canny_fitline_median_ms"]
    report["speed"] = sp
    report["baseline_accuracy"] = {"n": len(base_err)} | stats(base_err)
    report["worst_ok_error"] = worst
    b = report["baseline_accuracy"]
    print(
        f"speed (one thread, decode excluded, {sp['n_timed']} locate calls): locate median {sp['locate_median_ms']:.2f} ms, "
        f"Canny+fitLine median {sp['baseline_canny_fitline_median_ms']:.2f} ms, ratio {sp['ratio_locate_over_baseline']:.2f}; "
        f"median of per-image best of 5: locate {sp['locate_median_of_best_of_5_ms']:.2f} ms, "
        f"Canny+fitLine {sp['baseline_median_of_best_of_5_ms']:.2f} ms, ratio {sp['ratio_best_of_5']:.2f}"
    )
    print(
        f"baseline accuracy (default photometry, n={b['n']}): RMS x {b.get('rms_x_mm', float('nan')):.4f} z {b.get('rms_z_mm', float('nan')):.4f} mm, "
        f"yaw {b.get('rms_yaw_deg', float('nan')):.4f} deg, T {b.get('rms_thickness_mm', float('nan')):.4f} mm; median |error| "
        f"x {b.get('median_abs_x_mm', float('nan')):.4f} z {b.get('median_abs_z_mm', float('nan')):.4f} mm, "
        f"yaw {b.get('median_abs_yaw_deg', float('nan')):.4f} deg"
    )
    print(f"worst ok=true error over all sets: {worst['pos_mm']:.4f} mm, {worst['yaw_deg']:.5f} deg")
    if args.json:
        args.json.write_text(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
