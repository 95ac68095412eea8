"""Board corners found by OpenCV in rendered boards vs the true corners (goal: <= 0.05 px RMS).

Renders a 9x6 checkerboard (25 mm squares) at several poses through the thesis camera matrix with a
moderate barrel distortion, sharp and with a 0.8 px optical blur, and prints the RMS distance between the
true corners and what cv2.findChessboardCornersSB and cv2.findChessboardCorners + cv2.cornerSubPix report;
and the same for a 7x5 ChArUco board with cv2.aruco.CharucoDetector.

    /work/venv/bin/python bench/bench_render_boards.py
"""

from __future__ import annotations

import cv2
import numpy as np

from doorloc.calib.camera import CameraModel
from doorloc.sim.boards import CharucoBoard, Checkerboard, render_board
from doorloc.sim.effects import Effects

CAM = CameraModel.from_values(
    [[1678.35, 0, 946.41], [0, 1727.22, 510.71], [0, 0, 1]], [-0.08, 0.05, 0.0005, -0.0003, 0.0], (1920, 1080)
)
POSES = [
    ([0.2, -0.3, 0.05], [-100.0, -60.0, 700.0]),
    ([-0.4, 0.1, -0.2], [-60.0, -80.0, 600.0]),
    ([0.1, 0.5, 0.3], [-150.0, -40.0, 800.0]),
    ([0.0, 0.0, 0.0], [-300.0, -150.0, 900.0]),
    ([0.6, 0.0, 1.2], [0.0, -100.0, 750.0]),
]
CRIT = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 200, 1e-5)


def _order(found, truth):
    return (
        found[::-1] if np.linalg.norm(found[0] - truth[-1]) < np.linalg.norm(found[0] - truth[0]) else found
    )


def main() -> None:
    board = Checkerboard(9, 6, 25.0)
    for label, fx in (("sharp", Effects()), ("blur 0.8 px", Effects(blur_sigma_px=0.8))):
        sb_err, sba_err, sp_err = [], [], []
        for rvec, tvec in POSES:
            rb = render_board(CAM, board, rvec, tvec, effects=fx)
            ok, c = cv2.findChessboardCornersSB(rb.image, (9, 6))
            if ok:
                sb_err.append(_order(c.reshape(-1, 2), rb.corners_px) - rb.corners_px)
            ok, c = cv2.findChessboardCornersSB(rb.image, (9, 6), flags=cv2.CALIB_CB_ACCURACY)
            if ok:
                sba_err.append(_order(c.reshape(-1, 2), rb.corners_px) - rb.corners_px)
            ok, c = cv2.findChessboardCorners(rb.image, (9, 6))
            if ok:
                c = cv2.cornerSubPix(rb.image, c.astype(np.float32), (11, 11), (-1, -1), CRIT).reshape(-1, 2)
                sp_err.append(_order(c, rb.corners_px) - rb.corners_px)
        for name, errs in (
            ("findChessboardCornersSB", sb_err),
            ("SB + CALIB_CB_ACCURACY", sba_err),
            ("cornerSubPix 11x11", sp_err),
        ):
            e = np.concatenate(errs)
            rms = np.sqrt(np.mean(np.sum(e**2, axis=1)))
            print(
                f"checkerboard {label:12s} {name:24s} views {len(errs)}/{len(POSES)}  corners {len(e):4d}  "
                f"RMS {rms:.4f} px  mean ({e[:, 0].mean():+.4f}, {e[:, 1].mean():+.4f})"
            )
    ch = CharucoBoard(7, 5, 30.0, 22.0)
    det = cv2.aruco.CharucoDetector(ch.cv_board())
    errs, n_ids = [], 0
    for rvec, tvec in POSES:
        rb = render_board(CAM, ch, rvec, tvec, effects=Effects(blur_sigma_px=0.8))
        corners, ids, _, _ = det.detectBoard(rb.image)
        if ids is not None:
            ids = ids.ravel()
            n_ids += len(ids)
            errs.append(corners.reshape(-1, 2) - rb.corners_px[ids])
    e = np.concatenate(errs)
    print(
        f"charuco      blur 0.8 px  CharucoDetector          corners {n_ids}/{len(POSES) * 24}  "
        f"RMS {np.sqrt(np.mean(np.sum(e**2, axis=1))):.4f} px"
    )


if __name__ == "__main__":
    main()
