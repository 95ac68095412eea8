"""Recorded answers of the one-frame locate on every committed fixture, for the speed parity test.

Speed and structure work must not change a single answer: ``test_locate_parity.py`` runs :func:`cases`
through today's :func:`doorloc.vision.locate.locate` and compares with ``data/locate_golden.json``, which
was first written after the texture step fit, the arris strip and the response check came in, with::

    PYTHONPATH=src python tests/vision/locate_golden.py --write

Every committed fixture (``fixtures/rendered/*``, each with its own door from ``truth.csv``) is a case,
and so are inputs built from them without the renderer (so that changes to the renderer leave this alone)
that must be refused for a reason, or must give the same answer in another form (colour, 16 bit, JPEG).

When a deliberate change of the estimator moves the answers, record them again with the command above
(and say so in the commit): the golden pins today's answers, it is not ground truth.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

from doorloc.calib.camera import CameraModel
from doorloc.cell import Cell, DoorSize, load_cell
from doorloc.vision.imageio import decode_image, read_image
from doorloc.vision.result import LocateResult

ROOT = Path(__file__).resolve().parents[2]
FIX = ROOT / "fixtures" / "rendered"
GOLDEN = Path(__file__).parent / "data" / "locate_golden.json"
SETS = ("grid", "effects", "widths", "distractors")


def fixture_frames(sets: tuple[str, ...] = SETS) -> Iterator[tuple[str, Cell, DoorSize, np.ndarray]]:
    """``(name, cell, door, image)`` for every committed fixture image, the door from its truth row."""
    for s in sets:
        cell = load_cell(FIX / s / "cell.yaml")
        with open(FIX / s / "truth.csv", newline="") as f:
            rows = list(csv.DictReader(f))
        for r in rows:
            door = DoorSize(
                float(r["width_mm"]),
                float(r["thickness_mm"]),
                float(r["height_mm"]),
                float(r["arris_mm"]),
                r["arris_profile"],
            )  # type: ignore[arg-type]
            yield f"{s}/{r['image']}", cell, door, read_image(FIX / s / r["image"])


def derived_frames() -> Iterator[tuple[str, Cell, DoorSize, np.ndarray]]:
    """Inputs made from the fixtures that must be refused (or answered alike), without the renderer."""
    cell = load_cell(FIX / "grid" / "cell.yaml")
    frames = {n: (d, img) for n, _, d, img in fixture_frames(("grid",))}
    d13, centre = frames["grid/img_0013.png"]  # x = z = yaw = 0, 50 mm
    h, w = centre.shape
    rng = np.random.default_rng(14)
    yield "derived/black", cell, d13, np.zeros((h, w), np.uint8)
    yield "derived/saturated", cell, d13, np.full((h, w), 255, np.uint8)
    yield "derived/noise", cell, d13, rng.integers(0, 256, (h, w), dtype=np.uint8)
    yield "derived/flat_grey", cell, d13, np.clip(rng.normal(32, 2, (h, w)), 0, 255).astype(np.uint8)
    yield "derived/float_pixels", cell, d13, centre.astype(np.float32)
    yield "derived/wrong_size", cell, d13, cv2.resize(centre, (1280, 720), interpolation=cv2.INTER_AREA)
    yield "derived/two_channels", cell, d13, np.dstack([centre, centre])
    # the door 150 px (about 30 mm) further right / down: beyond the envelope
    yield "derived/shift_u150", cell, d13, np.roll(centre, 150, axis=1)
    yield "derived/shift_v-150", cell, d13, np.roll(centre, -150, axis=0)
    yield "derived/shift_u60", cell, d13, np.roll(centre, 60, axis=1)
    yield "derived/flip_ud", cell, d13, np.ascontiguousarray(centre[::-1])
    yield "derived/flip_lr", cell, d13, np.ascontiguousarray(centre[:, ::-1])
    yield "derived/thickness_100_for_50", cell, DoorSize(900, 100, 2100), centre
    yield "derived/thickness_45_for_50", cell, DoorSize(900, 45, 2100), centre
    clamp = centre.copy()
    clamp[640:740, 790:900] = 90  # a grey block over the reference corner
    yield "derived/clamp_over_corner", cell, d13, clamp
    covered = centre.copy()
    covered[200:1000, 850:1100] = 30  # the arrises covered up the door
    yield "derived/arrises_covered", cell, d13, covered
    yield "derived/bgr", cell, d13, cv2.cvtColor(centre, cv2.COLOR_GRAY2BGR)
    yield "derived/bgra", cell, d13, cv2.cvtColor(centre, cv2.COLOR_GRAY2BGRA)
    yield "derived/uint16", cell, d13, centre.astype(np.uint16) * 257
    d, thin = frames["grid/img_0000.png"]  # 30 mm at x = -10: far face beside the far arris
    ok, jpg = cv2.imencode(".jpg", thin, [cv2.IMWRITE_JPEG_QUALITY, 90])
    assert ok
    yield "derived/jpeg90_img_0000", cell, d, decode_image(jpg.tobytes())
    ok, jpg = cv2.imencode(".jpg", centre, [cv2.IMWRITE_JPEG_QUALITY, 75])
    assert ok
    yield "derived/jpeg75_img_0013", cell, d13, decode_image(jpg.tobytes())
    # a lens with distortion (the cell object differs from the file it came from only in the camera:
    # anything cached per cell must notice)
    K = cell.camera.camera_matrix
    lens = replace(
        cell, camera=CameraModel(K, np.array([-0.02, 0.01, 0.0002, -0.0001, 0.0]), cell.camera.image_size)
    )
    yield "derived/distorted_lens_img_0013", lens, d13, centre
    yield (
        "derived/distorted_lens_img_0040",
        lens,
        frames["grid/img_0040.png"][0],
        frames["grid/img_0040.png"][1],
    )
    noisy = np.clip(centre.astype(np.float32) + rng.normal(0, 3.0, centre.shape), 0, 255).astype(np.uint8)
    yield "derived/noise3_img_0013", cell, d13, noisy


def all_cases() -> Iterator[tuple[str, Cell, DoorSize, np.ndarray]]:
    yield from fixture_frames()
    yield from derived_frames()


def summary(r: LocateResult) -> dict:
    """What the parity test compares: the answer or the refusal."""
    out: dict = {"ok": r.ok, "error_code": r.error_code}
    if r.ok:
        out.update(
            x_mm=r.x_mm,
            z_mm=r.z_mm,
            yaw_deg=r.yaw_deg,
            thickness_mm=r.thickness_mm,
            scale_mm_per_px=r.scale_mm_per_px,
            corner_px=list(r.corner_px or []),
        )
    return out


#: tolerances of the parity test (poses within 1e-4 mm of the recorded ones)
TOL = {
    "x_mm": 1e-4,
    "z_mm": 1e-4,
    "thickness_mm": 1e-4,
    "yaw_deg": 1e-5,
    "scale_mm_per_px": 1e-7,
    # the corner image point: its move times the case's scale, mm, within the poses' 1e-4 mm (1e-4 px
    # before the line fits and step searches were compiled: an arris strip fit's posterior over its grid
    # carries a 1e-10 px change of its windows to ~2e-4 px, 4e-5 mm, on effects/img_0001)
    "corner_px": 1e-4,
}
#: fields whose tolerance is in mm of the door plane: the difference in px times the recorded scale
IN_MM = ("corner_px",)


def differences(got: dict, want: dict, tol: dict[str, float] = TOL) -> list[str]:
    """Human-readable differences between two :func:`summary` records beyond ``tol`` (empty: the same)."""
    if got["ok"] != want["ok"] or got["error_code"] != want["error_code"]:
        return [f"ok/error_code {got['ok']}/{got['error_code']} != {want['ok']}/{want['error_code']}"]
    out = []
    if want["ok"]:
        for k, t in tol.items():
            a, b = np.asarray(got[k], float), np.asarray(want[k], float)
            d = float(np.max(np.abs(a - b)))
            if k in IN_MM:
                d *= float(want["scale_mm_per_px"])
            if not (d <= t) or math.isnan(d):
                unit = " mm" if k in IN_MM else ""
                out.append(f"{k}: {got[k]} != {want[k]} (|diff| {d:.3g}{unit} > {t:g}{unit})")
    return out


def main() -> None:
    from doorloc.vision.locate import locate

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help=f"write {GOLDEN.relative_to(ROOT)}")
    a = ap.parse_args()
    rec = {name: summary(locate(img, cell, door, image_name=name)) for name, cell, door, img in all_cases()}
    if a.write:
        GOLDEN.parent.mkdir(parents=True, exist_ok=True)
        GOLDEN.write_text(json.dumps(rec, indent=1) + "\n")
        print(f"wrote {len(rec)} cases to {GOLDEN}")
    else:
        want = json.loads(GOLDEN.read_text())
        bad = {k: differences(v, want[k]) for k, v in rec.items() if differences(v, want[k])}
        print(f"{len(rec) - len(bad)}/{len(rec)} cases as recorded")
        for k, v in bad.items():
            print(k, v)


if __name__ == "__main__":
    main()
