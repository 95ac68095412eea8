"""An annotated image an operator can read at a glance: what locate looked at, found and answered.

Drawn on a BGR copy of the image: the search bands (thin grey), edge points (green = used,
red = rejected), the fitted lines (cyan, extended), the corner (yellow cross), the cell axes at the
nominal corner (X red, Z blue, 10 mm long) and a text box with the answer or the refusal.
"""

from __future__ import annotations

import math

import numpy as np

from doorloc.calib.detect import brightest_level, stored_bits_holding
from doorloc.cell import Cell, DoorSize
from doorloc.vision.locate import LocateTrace
from doorloc.vision.luminance import luminance_plane
from doorloc.vision.result import LocateResult

__all__ = ["draw_overlay"]

_GREEN, _RED, _CYAN, _YELLOW, _GREY, _WHITE = (
    (60, 220, 60),
    (40, 40, 230),
    (230, 220, 0),
    (0, 230, 255),
    (150, 150, 150),
    (255, 255, 255),
)
_AX_X, _AX_Z = (60, 60, 255), (255, 120, 40)


def _bgr(image: np.ndarray, stored_bits: int | None) -> np.ndarray:
    import cv2

    try:
        plane = luminance_plane(image, stored_bits=16 if stored_bits is None else stored_bits)
        g = plane.plane
        if g.dtype != np.uint8:
            scale = plane.scale_to_8bit
            brightest = brightest_level(g)
            if stored_bits is None and stored_bits_holding(brightest) is not None:
                # a depth the cell does not state, which locate refused: the picture at its own brightest level
                scale = 255.0 / max(brightest, 1)
            g = np.clip(g.astype(np.float32) * scale, 0, 255).astype(np.uint8)
    except ValueError:
        g = np.zeros((480, 640), np.uint8)
    # Darken slightly so the annotations stand out on a bright hinge face.
    return cv2.cvtColor((g * 0.8).astype(np.uint8), cv2.COLOR_GRAY2BGR)


def _pt(p) -> tuple[int, int]:
    return int(round(float(p[0]) * 16)), int(round(float(p[1]) * 16))  # 4 fractional bits


def draw_overlay(
    image: np.ndarray,
    result: LocateResult,
    cell: Cell,
    door: DoorSize | None = None,
    trace: LocateTrace | None = None,
) -> np.ndarray:
    """Draw the locate answer on the image.

    Parameters
    ----------
    image : ndarray
        The image given to :func:`doorloc.vision.locate.locate`.
    result : LocateResult
        Its answer.
    cell : Cell
        The cell used (for the axes at the nominal corner).
    door : DoorSize, optional
        The door used (the cell's default door when None).
    trace : LocateTrace, optional
        Intermediate results of that locate call; without it, a fresh locate is run to get them.

    Returns
    -------
    ndarray (H, W, 3) uint8
        BGR overlay.
    """
    from doorloc.vision.locate import locate

    door = door or cell.default_door
    if trace is None:
        trace = LocateTrace()
        locate(image, cell, door, image_name=result.image, trace=trace)
    out = _bgr(image, cell.stored_bits)
    _draw_bands(out, trace)
    _draw_points(out, trace)
    _draw_pose(out, trace)
    _draw_cell_axes(out, cell, door)
    _draw_text_box(out, result, door)
    return out


def _draw_bands(out: np.ndarray, trace: LocateTrace) -> None:
    """The search bands (thin grey), drawn on ``out`` (BGR, image px at 4 fractional bits)."""
    import cv2

    shift = 4
    region = trace.region
    for name, band in trace.bands.items():
        if region is None or band.scan.size == 0:
            continue
        axis = region.layouts[name].axis
        for edge in (band.lo, band.hi):
            uv = np.stack([band.scan, edge], 1) if axis == "col" else np.stack([edge, band.scan], 1)
            cv2.polylines(out, [np.round(uv * 16).astype(np.int32)], False, _GREY, 1, cv2.LINE_AA, shift)


def _draw_points(out: np.ndarray, trace: LocateTrace) -> None:
    """The edge points (green: used by the line fit, red: rejected), at most about 150 of each a line."""
    import cv2

    shift = 4
    for name, s in trace.samples.items():
        uv = s.uv()
        inl = trace.inliers.get(name, np.ones(len(uv), bool))
        for pts, col in ((uv[inl], _GREEN), (uv[~inl], _RED)):
            pts = pts[np.isfinite(pts).all(axis=1)]
            for p in pts[:: max(len(pts) // 150, 1)]:
                cv2.circle(out, _pt(p), 2 * 16, col, -1, cv2.LINE_AA, shift)


def _draw_pose(out: np.ndarray, trace: LocateTrace) -> None:
    """The fitted lines (cyan, extended along the door's Z from -5 mm to 30 mm above the region's top, and
    along X 8 mm beyond the thickness) and the corner (yellow cross), from the pose on the hinge-face
    plane."""
    import cv2

    shift = 4
    pose, region = trace.pose, trace.region
    if pose is None or region is None:
        return
    ex, ez = pose.x_axis, pose.z_axis
    far = pose.corner + pose.thickness_mm * ex
    t = np.linspace(-5.0, region.z_top_mm + 30.0, 60)
    for base in (pose.corner, far):
        uv = region.image_points(base[None] + t[:, None] * ez[None])
        uv = uv[np.isfinite(uv).all(axis=1)]
        cv2.polylines(out, [np.round(uv * 16).astype(np.int32)], False, _CYAN, 1, cv2.LINE_AA, shift)
    tx = np.linspace(-8.0, pose.thickness_mm + 8.0, 30)
    uv = region.image_points(pose.corner[None] + tx[:, None] * ex[None])
    cv2.polylines(out, [np.round(uv * 16).astype(np.int32)], False, _CYAN, 1, cv2.LINE_AA, shift)
    c = pose.corner_px
    for d in ((1, 0), (0, 1)):
        a = (c[0] - 14 * d[0], c[1] - 14 * d[1])
        b = (c[0] + 14 * d[0], c[1] + 14 * d[1])
        cv2.line(out, _pt(a), _pt(b), _YELLOW, 2, cv2.LINE_AA, shift)
    cv2.circle(out, _pt(c), 6 * 16, _YELLOW, 1, cv2.LINE_AA, shift)


def _draw_cell_axes(out: np.ndarray, cell: Cell, door: DoorSize) -> None:
    """The cell axes at the nominal corner (the cell origin on the hinge-face plane), 10 mm long."""
    import cv2

    shift = 4
    pc = cell.posed_camera
    fy = cell.face_y(door)
    o, xa, za = pc.project_cell(np.array([[0.0, fy, 0.0], [10.0, fy, 0.0], [0.0, fy, 10.0]]))
    if np.isfinite([o, xa, za]).all():
        cv2.arrowedLine(out, _pt(o), _pt(xa), _AX_X, 2, cv2.LINE_AA, shift, 0.2)
        cv2.arrowedLine(out, _pt(o), _pt(za), _AX_Z, 2, cv2.LINE_AA, shift, 0.2)
        cv2.putText(
            out, "X", (int(xa[0]) + 4, int(xa[1]) + 5), cv2.FONT_HERSHEY_SIMPLEX, 0.5, _AX_X, 1, cv2.LINE_AA
        )
        cv2.putText(
            out, "Z", (int(za[0]) - 5, int(za[1]) - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.5, _AX_Z, 1, cv2.LINE_AA
        )


def _draw_text_box(out: np.ndarray, result: LocateResult, door: DoorSize) -> None:
    """The answer or the refusal and each line's quality, in a darkened box at the bottom left (the door
    fills the top of the image); text sized to the image width (1920 px: scale 1)."""
    import cv2

    h, w = out.shape[:2]
    if result.ok:
        lines = [
            f"OK  x {result.x_mm:+.3f} mm   z {result.z_mm:+.3f} mm   yaw {result.yaw_deg:+.4f} deg",
            f"thickness {result.thickness_mm:.3f} mm (door {door.thickness_mm:g})   "
            f"scale {result.scale_mm_per_px:.4f} mm/px   {result.elapsed_ms:.1f} ms",
        ]
        colour = _GREEN
    else:
        lines = [f"REFUSED ({result.error_code})"] + _wrap(result.error or "", 90)
        colour = _RED
    for lq in result.lines:
        lines.append(
            f"{lq.name:9s} {lq.n_inliers:4d}/{lq.n_points:<4d} pts  rms {lq.rms_residual_px or 0:.3f} px  "
            f"contrast {lq.contrast or 0:.0f}"
        )
    scale = max(w / 1920.0, 0.5)
    lh = int(26 * scale)
    box_h = lh * len(lines) + 12
    box_w = int(min(w - 20, 900 * scale))
    y0 = max(h - box_h - 10, 0)  # bottom-left: the door fills the top of the image
    sub = out[y0 : y0 + box_h, 10 : 10 + box_w]
    sub[:] = (sub * 0.35).astype(np.uint8)
    for i, text in enumerate(lines):
        cv2.putText(
            out,
            text,
            (18, y0 + lh * (i + 1)),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.6 * scale,
            colour if i == 0 else _WHITE,
            max(int(math.ceil(scale)), 1),
            cv2.LINE_AA,
        )


def _wrap(text: str, width: int) -> list[str]:
    words, lines, cur = text.split(), [], ""
    for wd in words:
        if len(cur) + len(wd) + 1 > width:
            lines.append(cur)
            cur = wd
        else:
            cur = f"{cur} {wd}".strip()
    if cur:
        lines.append(cur)
    return lines
