"""Draw the 6-point and 9-point hinge pocket paths with their point order: docs/hinge_paths.png.

    python bench/draw_hinge_paths.py [--out docs/hinge_paths.png]

Both panels show a hinge pocket as the camera sees it (door frame X right, Z up), the tool-centre
path from doorloc.recipes.paths with its points numbered, the tool circle at P2, and the
approach/retract point in front of the face. Drawn with OpenCV (no matplotlib here).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import cv2
import numpy as np

from doorloc.recipes.models import Hinge
from doorloc.recipes.paths import pocket_points_xz

SCALE = 7.0  # px per mm
MARGIN = 70
FONT = cv2.FONT_HERSHEY_SIMPLEX
INK, POCKET, PATH, TOOL, NOTE = (30, 30, 30), (120, 120, 120), (200, 90, 20), (40, 140, 40), (90, 90, 90)


def _rounded_rect(h: Hinge, n: int = 24) -> np.ndarray:
    x0, x1, z0, z1, r = h.x_mm, h.x_mm + h.width_mm, h.z_mm, h.z_mm + h.length_mm, h.corner_radius_mm
    pts = []
    for cx, cz, a0 in (
        (x1 - r, z0 + r, -90),
        (x1 - r, z1 - r, 0),
        (x0 + r, z1 - r, 90),
        (x0 + r, z0 + r, 180),
    ):
        for k in range(n + 1):
            a = math.radians(a0 + 90 * k / n)
            pts.append((cx + r * math.cos(a), cz + r * math.sin(a)))
    return np.array(pts)


def panel(title: str, subtitle: str, h: Hinge, tool_d: float) -> np.ndarray:
    w = int(h.width_mm * SCALE) + 2 * MARGIN + 120
    ht = int(h.length_mm * SCALE) + 2 * MARGIN + 40
    img = np.full((ht, w, 3), 255, np.uint8)

    def px(x: float, z: float) -> tuple[int, int]:  # X right, Z up
        return int(round(MARGIN + (x - h.x_mm) * SCALE)), int(round(ht - MARGIN - (z - h.z_mm) * SCALE))

    outline = np.array([px(x, z) for x, z in _rounded_rect(h)], np.int32)
    cv2.polylines(img, [outline], True, POCKET, 2, cv2.LINE_AA)
    xz, kinds = pocket_points_xz(h, tool_d)
    cv2.circle(img, px(*xz[1]), int(tool_d / 2 * SCALE), TOOL, 1, cv2.LINE_AA)
    for a, b in zip(xz[:-1], xz[1:], strict=True):
        if np.allclose(a, b):
            continue
        cv2.arrowedLine(
            img,
            px(*a),
            px(*b),
            PATH,
            2,
            cv2.LINE_AA,
            tipLength=min(0.5, 12 / max(1, np.hypot(*(b - a)) * SCALE)),
        )
    centre = xz[:-1].mean(axis=0)
    placed: list[tuple[int, int]] = []
    for k, ((x, z), kind) in enumerate(zip(xz, kinds, strict=True), start=1):
        p = px(x, z)
        cv2.circle(img, p, 5 if kind == "corner" else 4, INK, -1 if kind == "corner" else 1, cv2.LINE_AA)
        d = np.array([x - centre[0], -(z - centre[1])])
        d = d / (np.linalg.norm(d) + 1e-9)
        lp = (int(p[0] + 22 * d[0]) - 12, int(p[1] + 22 * d[1]) + 6)
        while any(abs(lp[0] - q[0]) < 26 and abs(lp[1] - q[1]) < 16 for q in placed):
            lp = (lp[0], lp[1] + 16 * (1 if d[1] >= 0 else -1))
        placed.append(lp)
        cv2.putText(img, f"P{k}", lp, FONT, 0.5, INK, 1, cv2.LINE_AA)
    # approach/retract: in front of P1 (and of the last point), drawn as a ring around P1
    cv2.circle(img, px(*xz[0]), 11, NOTE, 1, cv2.LINE_AA)
    ax, az = px(h.x_mm + h.width_mm, h.z_mm)
    cv2.putText(img, "APP/RET: in front of", (ax + 12, az - 26), FONT, 0.4, NOTE, 1, cv2.LINE_AA)
    cv2.putText(img, "P1/Pn (Y = -clearance)", (ax + 12, az - 10), FONT, 0.4, NOTE, 1, cv2.LINE_AA)
    cv2.putText(img, title, (10, 24), FONT, 0.6, INK, 1, cv2.LINE_AA)
    cv2.putText(img, subtitle, (10, 46), FONT, 0.42, NOTE, 1, cv2.LINE_AA)
    # axes
    o = (12, ht - 14)
    cv2.arrowedLine(img, o, (o[0] + 40, o[1]), INK, 1, cv2.LINE_AA, tipLength=0.25)
    cv2.arrowedLine(img, o, (o[0], o[1] - 40), INK, 1, cv2.LINE_AA, tipLength=0.25)
    cv2.putText(img, "X", (o[0] + 44, o[1] + 4), FONT, 0.4, INK, 1, cv2.LINE_AA)
    cv2.putText(img, "Z", (o[0] - 4, o[1] - 44), FONT, 0.4, INK, 1, cv2.LINE_AA)
    return img


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path(__file__).parents[1] / "docs" / "hinge_paths.png")
    args = ap.parse_args()
    six = Hinge(z_mm=0, length_mm=80, width_mm=28, x_mm=0, depth_mm=3, corner_radius_mm=7, path_points=6)
    nine = Hinge(z_mm=0, length_mm=80, width_mm=28, x_mm=0, depth_mm=3, corner_radius_mm=12, path_points=9)
    a = panel("6-point path (fig. 3.24b)", "pocket 28x80 r7, tool 14: P1=P6", six, 14.0)
    b = panel("9-point path (fig. 3.24a)", "pocket 28x80 r12, tool 14: P1=P9", nine, 14.0)
    h = max(a.shape[0], b.shape[0])

    def pad(im):
        return cv2.copyMakeBorder(im, 0, h - im.shape[0], 0, 0, cv2.BORDER_CONSTANT, value=(255, 255, 255))

    img = np.hstack([pad(a), np.full((h, 6, 3), 220, np.uint8), pad(b)])
    foot = np.full((40, img.shape[1], 3), 255, np.uint8)
    cv2.putText(
        foot,
        "seen from the camera; counter-clockwise; filled: corners (fine); open: z0 (P1 ends the plunge: fine); green: tool",
        (10, 24),
        FONT,
        0.42,
        NOTE,
        1,
        cv2.LINE_AA,
    )
    img = np.vstack([img, foot])
    args.out.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(args.out), img):
        raise SystemExit(f"cannot write {args.out}")
    print(f"wrote {args.out} ({img.shape[1]}x{img.shape[0]})")


if __name__ == "__main__":
    main()
