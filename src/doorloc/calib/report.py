"""The calibration report: a JSON document and a PNG picture a person can judge a calibration by.

:func:`report_dict` collects the figures (model selection table, per-view errors, rejections,
uncertainties, corner coverage, validity region) and :func:`calibration_warnings` the sentences a
person can act on; :func:`render_report_png` draws coverage, residual vectors, validity circles and
per-view errors into one image; :func:`write_report` writes both atomically.
"""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path

import cv2
import numpy as np

from doorloc.calib.calibrate import CalibrationResult
from doorloc.calib.camera import distortion_validity
from doorloc.calib.coverage import (
    COVERAGE_CELLS,
    THIN_FRACTION,
    board_tilts_deg,
    cell_names,
    corner_coverage,
    thin_cells,
)
from doorloc.calib.detect import BoardScan, to_gray
from doorloc.fileio import atomic_write_image, atomic_write_text

__all__ = [
    "COVERAGE_CELLS",
    "coverage_grid",
    "calibration_warnings",
    "report_dict",
    "render_report_png",
    "write_report",
]

#: a board tilted less than this (deg) both ways about an axis leaves focal length and distance entangled
MIN_TILT_RANGE_DEG = 30.0
_REGION_NAMES = {
    (0, 0): "top-left",
    (1, 0): "top",
    (2, 0): "top-right",
    (0, 1): "left",
    (1, 1): "centre",
    (2, 1): "right",
    (0, 2): "bottom-left",
    (1, 2): "bottom",
    (2, 2): "bottom-right",
}


def coverage_grid(result: CalibrationResult, cells: tuple[int, int] = COVERAGE_CELLS) -> np.ndarray:
    """Number of kept corners in each of ``cells = (nx, ny)`` image cells; shape (ny, nx)."""
    return corner_coverage(
        np.concatenate([v.image_points for v in result.views]), result.camera.image_size, cells
    )


def _empty_regions(grid: np.ndarray) -> list[str]:
    """Names of the 3x3 image regions (top-left ... bottom-right) without any corner."""
    ny, nx = grid.shape
    out = []
    for (rx, ry), name in _REGION_NAMES.items():
        xs = slice(rx * nx // 3, (rx + 1) * nx // 3)
        ys = slice(ry * ny // 3, (ry + 1) * ny // 3)
        if grid[ys, xs].sum() == 0:
            out.append(name)
    return out


def calibration_warnings(result: CalibrationResult, scan: BoardScan | None = None) -> list[str]:
    """Sentences a person can act on, from the most to the least important."""
    cam = result.camera
    val = distortion_validity(cam)
    warn = list(val.warnings)
    grid = coverage_grid(result)
    empty = _empty_regions(grid)
    if empty:
        warn.append(
            f"no board corner was observed in the {', '.join(empty)} part(s) of the image: the model "
            "is extrapolated there; add views with the board in those regions"
        )
    thin = [name for name in cell_names(thin_cells(grid), grid.shape) if name not in empty]
    if thin:
        warn.append(
            f"few board corners were observed in the {', '.join(thin)} part(s) of the image (fewer than "
            f"{THIN_FRACTION:.0%} of a typical cell, see coverage.corners_per_cell): add views with the "
            "board there, tilted"
        )
    tilt = board_tilts_deg(result.fit.rvecs)
    for k, axis, how in ((0, "horizontal", "top or bottom edge"), (1, "vertical", "left or right edge")):
        if np.ptp(tilt[:, k]) < MIN_TILT_RANGE_DEG:
            warn.append(
                f"the boards were tilted about the camera's {axis} axis only over {np.ptp(tilt[:, k]):.0f} deg "
                f"({tilt[:, k].min():+.0f}..{tilt[:, k].max():+.0f}): add views with the {how} of the board "
                "turned 30-45 deg towards and away from the camera"
            )
    n = len(result.views)
    if n < 10:
        warn.append(
            f"only {n} views were used; 10-20 views with the board tilted and near the image edges "
            "give a better-conditioned calibration"
        )
    if result.fit.rms_px > 1.0:
        warn.append(
            f"the RMS reprojection error is {result.fit.rms_px:.2f} px (expect < 0.5 px): check focus, "
            "motion blur, board flatness and the --square size"
        )
    bad_views = [r for r in result.rejections if r.corner_id is None]
    if bad_views:
        warn.append(
            f"{len(bad_views)} view(s) were rejected as outliers ({', '.join(r.view for r in bad_views)}): "
            "look at them for blur, a wrong detection or a bent board"
        )
    n_corners = sum(1 for r in result.rejections if r.corner_id is not None)
    if n_corners:
        warn.append(f"{n_corners} corner(s) were rejected as outliers (listed in the report)")
    jk, formal = result.std_jackknife, result.std_intrinsics
    spread = [k for k in ("fx", "fy", "cx", "cy") if k in jk and k in formal and jk[k] > 3 * formal[k]]
    if spread:
        warn.append(
            "the views disagree more than the corner noise explains ("
            + ", ".join(f"{k}: jackknife {jk[k]:.2f} px vs formal {formal[k]:.2f} px" for k in spread)
            + "): trust the jackknife figures; check that the board is flat and add views"
        )
    corners = [s for s in result.projection_sigma_px["corners"] if s is not None]
    if corners and max(corners) > 1.0:
        warn.append(
            f"the projection uncertainty reaches {max(corners):.1f} px (1 sigma) at the image corners: "
            "do not trust the model there, or add views covering them"
        )
    if scan is not None and scan.skipped:
        warn.append(f"{len(scan.skipped)} image(s) were not used (reasons in the report)")
    return warn


def report_dict(
    result: CalibrationResult, scan: BoardScan | None = None, board: object | None = None
) -> dict:
    """The calibration report as a JSON-ready mapping (pixels, mm; 1-sigma uncertainties)."""
    cam = result.camera
    val = distortion_validity(cam)
    grid = coverage_grid(result)
    tilt = board_tilts_deg(result.fit.rvecs)
    fit = result.fit
    doc = {
        "image_size": list(cam.image_size),
        "board": _board_dict(board),
        "model": fit.candidate.name,
        "camera_matrix": cam.camera_matrix.tolist(),
        "dist_coeffs": cam.dist_coeffs.tolist(),
        "rms_px": fit.rms_px,
        "std_1sigma": result.std_intrinsics,
        "std_jackknife": result.std_jackknife,
        "model_selection": {
            "rule": "fewest parameters among the models within one standard error of the best held-out RMS",
            "folds": result.n_folds,
            "excluded": result.excluded_models,
            "candidates": [
                {
                    "name": s.name,
                    "n_params": s.n_params,
                    "train_rms_px": s.train_rms_px,
                    "held_out_rms_px": s.held_out_rms_px,
                    "chosen": s.chosen,
                }
                for s in result.scores
            ],
        },
        "views": [
            {
                "name": v.name,
                "n_corners": v.n,
                "rms_px": e,
                "max_residual_px": float(np.max(np.linalg.norm(r, axis=1))),
            }
            for v, e, r in zip(result.views, fit.per_view_rms_px, fit.residuals_px, strict=True)
        ],
        "rejected": [
            {"view": r.view, "corner_id": r.corner_id, "residual_px": r.residual_px, "reason": r.reason}
            for r in result.rejections
        ],
        "skipped_images": []
        if scan is None
        else [{"image": s.name, "reason": s.reason} for s in scan.skipped],
        "coverage": {
            "cells": list(COVERAGE_CELLS),
            "corners_per_cell": grid.tolist(),
            "fraction_of_cells_observed": float(np.mean(grid > 0)),
            "thin_cells": [list(c) for c in thin_cells(grid)],
            "board_tilt_deg": {
                "about_x": [float(tilt[:, 0].min()), float(tilt[:, 0].max())],
                "about_y": [float(tilt[:, 1].min()), float(tilt[:, 1].max())],
            },
        },
        "observed_radius_px": cam.observed_radius_px,
        "projection_uncertainty_px": result.projection_sigma_px,
        "validity": val.to_dict(),
        "warnings": calibration_warnings(result, scan),
    }
    return doc


def _colour_map(values: np.ndarray, vmax: float) -> np.ndarray:
    v = np.nan_to_num(np.clip(values / max(vmax, 1e-9), 0, 1), nan=1.0)
    return cv2.applyColorMap((v * 255).astype(np.uint8), cv2.COLORMAP_VIRIDIS)


def render_report_png(result: CalibrationResult, background: np.ndarray | None = None) -> np.ndarray:
    """The report picture (BGR uint8): left, the image with corners, residual vectors and validity
    circles over the projection-uncertainty map; right, per-view RMS bars.

    Residual vectors are drawn 50x longer than they are. Circles: green, the observed radius;
    red, where the distortion model folds over (if inside the picture).
    """
    cam = result.camera
    w, h = cam.image_size
    sig = np.array([np.nan if s is None else s for s in result.projection_sigma_px["grid"]], float)
    gy, gx = result.projection_sigma_px["grid_shape"]
    vmax = float(np.nanmax(sig)) if np.any(np.isfinite(sig)) else 1.0
    heat = cv2.resize(
        _colour_map(sig.reshape(gy, gx).astype(np.float32), vmax), (w, h), interpolation=cv2.INTER_LINEAR
    )
    if background is not None:
        # (a 16-bit photograph as the corners were found on it, stretched to its brightest level: cast to 8
        # bits its levels had wrapped round 256 into noise)
        bg = background if background.dtype == np.uint8 else to_gray(background)
        bg = bg if bg.ndim == 3 else cv2.cvtColor(bg, cv2.COLOR_GRAY2BGR)
        canvas = cv2.addWeighted(bg, 0.5, heat, 0.5, 0)
    else:
        canvas = (heat * 0.6).astype(np.uint8)
    c = (int(round(cam.cx)), int(round(cam.cy)))
    for v, r in zip(result.views, result.fit.residuals_px, strict=True):
        for p, d in zip(v.image_points, r, strict=True):
            a = (int(round(p[0])), int(round(p[1])))
            b = (int(round(p[0] + 50 * d[0])), int(round(p[1] + 50 * d[1])))
            cv2.circle(canvas, a, 1, (255, 255, 255), -1)
            cv2.line(canvas, a, b, (0, 200, 255), 1, cv2.LINE_AA)
    if cam.observed_radius_px:
        cv2.circle(canvas, c, int(round(cam.observed_radius_px)), (0, 255, 0), 1, cv2.LINE_AA)
    val = distortion_validity(cam)
    if val.fold_radius_px is not None and val.fold_radius_px < 2 * max(w, h):
        cv2.circle(canvas, c, int(round(val.fold_radius_px)), (0, 0, 255), 2, cv2.LINE_AA)
    cv2.drawMarker(canvas, c, (255, 255, 255), cv2.MARKER_CROSS, 12, 1)
    font = cv2.FONT_HERSHEY_SIMPLEX
    fs = max(0.4, h / 1200)
    lines = [
        f"{result.fit.candidate.name}: fx {cam.fx:.2f} fy {cam.fy:.2f} cx {cam.cx:.2f} cy {cam.cy:.2f}  RMS {result.fit.rms_px:.3f} px",
        f"green: observed radius {cam.observed_radius_px:.0f} px; colour: projection sigma 0..{vmax:.2f} px; "
        "vectors: residuals x50",
    ]
    for i, t in enumerate(lines):
        cv2.putText(canvas, t, (8, int(20 * fs / 0.4) * (i + 1)), font, fs, (255, 255, 255), 1, cv2.LINE_AA)
    # Per-view RMS bars on a side panel as tall as the image.
    pw = max(200, w // 3)
    panel = np.full((h, pw, 3), 32, np.uint8)
    errs = result.fit.per_view_rms_px
    emax = max(max(errs), 1e-6)
    bh = max(1, (h - 30) // max(len(errs), 1))
    for i, (v, e) in enumerate(zip(result.views, errs, strict=True)):
        y = 20 + i * bh
        cv2.rectangle(panel, (4, y), (4 + int((pw - 110) * e / emax), y + bh - 2), (0, 200, 255), -1)
        cv2.putText(
            panel, f"{e:.2f} {v.name[:12]}", (pw - 104, y + bh - 3), font, min(fs, 0.35), (255, 255, 255), 1
        )
    cv2.putText(panel, "per-view RMS (px)", (4, 14), font, min(fs, 0.4), (255, 255, 255), 1)
    return np.hstack([canvas, panel])


def write_report(
    directory: str | os.PathLike,
    result: CalibrationResult,
    scan: BoardScan | None = None,
    board: object | None = None,
    background: np.ndarray | None = None,
) -> tuple[Path, Path]:
    """Write ``calibration_report.json`` and ``calibration_report.png`` into ``directory`` (atomically)."""
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    doc = report_dict(result, scan, board)
    jpath, ppath = d / "calibration_report.json", d / "calibration_report.png"
    atomic_write_text(jpath, json.dumps(doc, indent=2, allow_nan=False, default=_json_default) + "\n")
    atomic_write_image(ppath, render_report_png(result, background))
    return jpath, ppath


def _board_dict(board: object | None) -> dict | None:
    if board is None:
        return None
    if dataclasses.is_dataclass(board) and not isinstance(board, type):
        return {"type": type(board).__name__, **dataclasses.asdict(board)}
    return {"type": type(board).__name__, "description": str(board)}


def _json_default(o: object):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")
