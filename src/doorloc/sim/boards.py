"""Calibration boards (checkerboard, ChArUco) rendered exactly through the camera model, with true corners.

Board frame (as OpenCV's calibration code uses it): the board lies in its plane ``z = 0``; a board
point ``(x, y, 0)`` (mm) is at ``R(rvec) @ (x, y, 0) + tvec_mm`` in the camera frame.

- :class:`Checkerboard`: ``cols x rows`` *inner* corners; object point ``k = j * cols + i`` is
  ``(i * square, j * square, 0)`` (origin at the first inner corner), the order in which
  ``cv2.findChessboardCorners[SB]`` reports corners when the board's +x axis runs roughly to image-right
  and +y to image-down (OpenCV may report the reverse order for other views: match before comparing).
  The square diagonal to the first inner corner at ``(-square, -square)`` is black.
- :class:`CharucoBoard`: exactly ``cv2.aruco.CharucoBoard`` (origin at the pattern's top-left corner,
  y down); ids are OpenCV's ChArUco corner ids, so ``cv2.aruco.CharucoDetector`` finds and names them.

Example
-------
>>> from doorloc.calib.camera import CameraModel
>>> cam = CameraModel.from_values([[800, 0, 319.5], [0, 800, 239.5], [0, 0, 1]], [], (640, 480))
>>> rb = render_board(cam, Checkerboard(7, 5, 20.0), [0.1, -0.2, 0.0], [-60.0, -40.0, 500.0])
>>> rb.image.shape, rb.corners_px.shape
((480, 640), (35, 2))
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from doorloc.calib.camera import CameraModel, Extrinsics
from doorloc.sim.effects import Effects, form_image
from doorloc.sim.raster import GridTexture, Surface, render_radiance

__all__ = ["Checkerboard", "CharucoBoard", "RenderedBoard", "render_board", "BOARD_WHITE", "BOARD_BLACK"]

#: reflectances of the printed board
BOARD_WHITE = 0.9
BOARD_BLACK = 0.06


def _cell_centres(lines: np.ndarray) -> np.ndarray:
    return np.concatenate([[lines[0] - 1.0], 0.5 * (lines[1:] + lines[:-1]), [lines[-1] + 1.0]])


@dataclass(frozen=True)
class Checkerboard:
    """A chessboard calibration target with ``cols x rows`` inner corners and ``square_mm`` squares.

    ``margin_mm``: white border around the squares (default one square).
    """

    cols: int
    rows: int
    square_mm: float
    margin_mm: float | None = None

    def __post_init__(self) -> None:
        if self.cols < 2 or self.rows < 2 or not self.square_mm > 0:
            raise ValueError("a checkerboard needs at least 2x2 inner corners and a positive square size")

    @property
    def margin(self) -> float:
        return self.square_mm if self.margin_mm is None else float(self.margin_mm)

    def object_points(self) -> np.ndarray:
        """Inner corners in the board frame, shape (cols*rows, 3), mm, row-major (OpenCV order)."""
        j, i = np.mgrid[0 : self.rows, 0 : self.cols]
        return np.stack([i.ravel(), j.ravel(), np.zeros(i.size)], axis=1) * self.square_mm

    def ids(self) -> np.ndarray:
        return np.arange(self.cols * self.rows)

    def outline(self) -> np.ndarray:
        """Board outline in the board frame (x, y), shape (4, 2), mm."""
        a = -self.square_mm - self.margin
        bx = self.cols * self.square_mm + self.margin
        by = self.rows * self.square_mm + self.margin
        return np.array([[a, a], [bx, a], [bx, by], [a, by]])

    def texture(self) -> GridTexture:
        sq = self.square_mm
        s_lines = np.arange(-1, self.cols + 1) * sq
        t_lines = np.arange(-1, self.rows + 1) * sq
        sc, tc = _cell_centres(s_lines), _cell_centres(t_lines)
        a = np.floor(sc / sq)[:, None]
        b = np.floor(tc / sq)[None, :]
        inside = (np.abs(sc[:, None] - (self.cols - 1) * sq / 2) < (self.cols + 1) * sq / 2) & (
            np.abs(tc[None, :] - (self.rows - 1) * sq / 2) < (self.rows + 1) * sq / 2
        )
        black = ((a + b) % 2 == 0) & inside
        return GridTexture(s_lines, t_lines, np.where(black, BOARD_BLACK, BOARD_WHITE))


@dataclass(frozen=True)
class CharucoBoard:
    """A ChArUco board identical to ``cv2.aruco.CharucoBoard((squares_x, squares_y), square, marker, dict)``."""

    squares_x: int
    squares_y: int
    square_mm: float
    marker_mm: float
    dictionary: str = "DICT_4X4_50"
    margin_mm: float | None = None
    legacy: bool = False  # OpenCV's pre-4.6 layout (setLegacyPattern), for boards printed by old versions

    def __post_init__(self) -> None:
        if self.squares_x < 2 or self.squares_y < 2 or not 0 < self.marker_mm < self.square_mm:
            raise ValueError("a ChArUco board needs at least 2x2 squares and 0 < marker_mm < square_mm")

    @property
    def margin(self) -> float:
        return 0.5 * self.square_mm if self.margin_mm is None else float(self.margin_mm)

    def cv_dictionary(self):
        import cv2

        name = self.dictionary
        if not hasattr(cv2.aruco, name):
            raise ValueError(f"unknown ArUco dictionary {name!r} (e.g. DICT_4X4_50, DICT_5X5_100)")
        return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))

    def cv_board(self):
        """The matching ``cv2.aruco.CharucoBoard``."""
        import cv2

        board = cv2.aruco.CharucoBoard(
            (self.squares_x, self.squares_y),
            float(self.square_mm),
            float(self.marker_mm),
            self.cv_dictionary(),
        )
        board.setLegacyPattern(bool(self.legacy))
        return board

    def object_points(self) -> np.ndarray:
        """ChArUco corners in the board frame, shape (N, 3), mm; row k has id k."""
        return np.asarray(self.cv_board().getChessboardCorners(), float).reshape(-1, 3)

    def ids(self) -> np.ndarray:
        return np.arange(self.object_points().shape[0])

    def outline(self) -> np.ndarray:
        m = self.margin
        bx, by = self.squares_x * self.square_mm + m, self.squares_y * self.square_mm + m
        return np.array([[-m, -m], [bx, -m], [bx, by], [-m, by]])

    def texture(self) -> GridTexture:
        board = self.cv_board()
        dic = self.cv_dictionary()
        nbits = int(dic.markerSize)
        sq, mk = float(self.square_mm), float(self.marker_mm)
        marker_corners = np.asarray(board.getObjPoints(), float)[..., :2]  # (M, 4, 2): TL, TR, BR, BL
        marker_ids = np.asarray(board.getIds()).ravel()
        tl = marker_corners.min(axis=1)  # (M, 2) top-left of each marker
        bit = mk / (nbits + 2)
        s_lines = set(np.arange(self.squares_x + 1) * sq)
        t_lines = set(np.arange(self.squares_y + 1) * sq)
        for x0, y0 in tl:
            s_lines.update(x0 + np.arange(nbits + 3) * bit)
            t_lines.update(y0 + np.arange(nbits + 3) * bit)
        s_arr = np.array(sorted(_dedupe(s_lines)))
        t_arr = np.array(sorted(_dedupe(t_lines)))
        sc, tc = _cell_centres(s_arr), _cell_centres(t_arr)
        S, T = np.meshgrid(sc, tc, indexing="ij")
        a, b = np.floor(S / sq).astype(int), np.floor(T / sq).astype(int)
        on_board = (a >= 0) & (a < self.squares_x) & (b >= 0) & (b < self.squares_y)
        # Markers sit in the white squares: the squares holding a marker centre.
        white_sq = np.zeros((self.squares_x, self.squares_y), bool)
        centres = tl + mk / 2
        white_sq[np.floor(centres[:, 0] / sq).astype(int), np.floor(centres[:, 1] / sq).astype(int)] = True
        vals = np.full(S.shape, BOARD_WHITE)
        vals[on_board & ~white_sq[np.clip(a, 0, self.squares_x - 1), np.clip(b, 0, self.squares_y - 1)]] = (
            BOARD_BLACK
        )
        for (x0, y0), mid in zip(tl, marker_ids, strict=True):
            img = dic.generateImageMarker(int(mid), nbits + 2, borderBits=1)  # one pixel per bit cell
            inm = (S > x0) & (S < x0 + mk) & (T > y0) & (T < y0 + mk)
            col = np.floor((S[inm] - x0) / bit).astype(int)
            row = np.floor((T[inm] - y0) / bit).astype(int)
            vals[inm] = np.where(img[row, col] > 127, BOARD_WHITE, BOARD_BLACK)
        return GridTexture(s_arr, t_arr, vals)


def _dedupe(values, tol: float = 1e-9):
    out: list[float] = []
    for v in sorted(float(x) for x in values):
        if not out or v - out[-1] > tol:
            out.append(v)
    return out


@dataclass(frozen=True, eq=False)
class RenderedBoard:
    """A rendered board view and its truth.

    Attributes
    ----------
    image : ndarray
        uint8 (H, W) (or as :class:`~doorloc.sim.effects.Effects` asks).
    corners_px : ndarray, shape (N, 2)
        True pixel positions of the inner corners (distorted image), in the board's corner order.
    ids : ndarray, shape (N,)
        Corner ids (ChArUco ids; 0..N-1 for a checkerboard).
    object_points : ndarray, shape (N, 3)
        The same corners in the board frame, mm.
    in_image : ndarray, shape (N,), bool
        Corner lies inside the image.
    radiance : ndarray, shape (H, W), float64
        The box-filtered radiance before sensor effects (for exactness checks).
    """

    image: np.ndarray
    corners_px: np.ndarray
    ids: np.ndarray
    object_points: np.ndarray
    in_image: np.ndarray
    radiance: np.ndarray


def render_board(
    camera: CameraModel,
    board: Checkerboard | CharucoBoard,
    rvec,
    tvec_mm,
    *,
    seed: int = 0,
    effects: Effects | None = None,
    background: float = 0.3,
) -> RenderedBoard:
    """Render ``board`` seen by ``camera`` at pose ``(rvec, tvec_mm)`` (board frame -> camera frame).

    Each pixel is the exact box-filter average of the board's printed pattern over its footprint,
    mapped through the camera's distortion (see :mod:`doorloc.sim.raster`); no image resampling.

    Parameters
    ----------
    camera : CameraModel
    board : Checkerboard or CharucoBoard
    rvec : array_like, shape (3,)
        Rodrigues rotation board -> camera, radians.
    tvec_mm : array_like, shape (3,)
        Board origin in the camera frame, mm.
    seed : int
        Noise seed (only matters with noise effects).
    effects : Effects or None
        Sensor/optics effects (blur, noise, gamma, ...); None = plain 8-bit.
    background : float
        Radiance around the board.

    Returns
    -------
    RenderedBoard
    """
    effects = effects or Effects()
    ext = Extrinsics(rvec, tvec_mm)
    R = ext.rotation
    surface = Surface(
        origin=ext.tvec_mm.copy(),
        s_axis=R[:, 0].copy(),
        t_axis=R[:, 1].copy(),
        polygon_st=board.outline(),
        texture=board.texture(),
        shade=1.0,
        name="board",
    )
    radiance = render_radiance(camera, [surface], float(background))
    image = form_image(radiance, effects, seed, principal_point=(camera.cx, camera.cy))
    obj = board.object_points()
    corners = camera.project(ext.cell_to_camera(obj))
    w, h = camera.image_size
    in_image = (
        np.all(np.isfinite(corners), axis=1)
        & (corners[:, 0] >= -0.5)
        & (corners[:, 0] <= w - 0.5)
        & (corners[:, 1] >= -0.5)
        & (corners[:, 1] <= h - 0.5)
    )
    return RenderedBoard(image, corners, board.ids(), obj, in_image, radiance)
