"""Find calibration-board corners in an image: chessboards and ChArUco boards.

Corner order is the same whichever detector found the board (shared/SPEC.md pixel convention:
origin at the centre of the top-left pixel):

- chessboard: ``cols x rows`` inner corners, row-major; rows run left to right in the image
  (of the two index orders a board allows, the one whose first row points most nearly along +u;
  for a square pattern, of the four rotations). Corner ``i`` is the object point
  ``((i % cols) * square, (i // cols) * square, 0)``.
- ChArUco: OpenCV's corner ids, which the markers fix on the board itself.

Sub-pixel refinement uses a window sized from the local square size: a fixed 11x11 half-window
(OpenCV's sample) reaches the neighbouring corners on ~25 px squares and moves corners by pixels.
Each corner's half-window is ``WINDOW_FRACTION`` (0.35) of the shortest distance to a grid neighbour,
minus a one-pixel margin, between ``MIN_HALF_WINDOW`` and ``MAX_HALF_WINDOW``.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import cv2
import numpy as np

__all__ = [
    "Chessboard",
    "CharucoSpec",
    "BoardDetection",
    "detect_chessboard",
    "detect_charuco",
    "detect_board",
    "refine_corners",
    "local_square_px",
    "canonical_grid_order",
    "to_gray",
    "stored_grey",
    "stored_grey_8bit",
    "STORED_BITS_READ",
    "stored_bits_of",
    "stored_bits_holding",
    "brightest_level",
    "SkippedImage",
    "BoardScan",
    "scan_images",
]

WINDOW_FRACTION = 0.35
MIN_HALF_WINDOW = 2
MAX_HALF_WINDOW = 15
_SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 100, 1e-4)


@dataclass(frozen=True)
class Chessboard:
    """A chessboard by its inner corners: ``cols`` per row, ``rows`` rows, squares ``square_mm`` wide.

    Examples
    --------
    >>> Chessboard(9, 6, 25.0).object_points()[:2].tolist()
    [[0.0, 0.0, 0.0], [25.0, 0.0, 0.0]]
    """

    cols: int
    rows: int
    square_mm: float

    def __post_init__(self) -> None:
        if self.cols < 2 or self.rows < 2:
            raise ValueError(f"a chessboard needs at least 2x2 inner corners, got {self.cols}x{self.rows}")
        if not self.square_mm > 0:
            raise ValueError(f"square size must be positive, got {self.square_mm}")

    @property
    def n_corners(self) -> int:
        return self.cols * self.rows

    def object_points(self) -> np.ndarray:
        """Board-frame corner positions, mm, shape (cols*rows, 3), in the detection order."""
        c, r = np.meshgrid(np.arange(self.cols), np.arange(self.rows))
        return np.stack([c.ravel() * self.square_mm, r.ravel() * self.square_mm, np.zeros(c.size)], axis=-1)


@dataclass(frozen=True)
class CharucoSpec:
    """A ChArUco board: ``squares_x`` x ``squares_y`` squares (not inner corners), marker size, ArUco dictionary.

    ``legacy`` selects OpenCV's pre-4.6 layout (boards printed from old generators with an even row count).
    """

    squares_x: int
    squares_y: int
    square_mm: float
    marker_mm: float
    dictionary: str = "DICT_4X4_50"
    legacy: bool = False

    def __post_init__(self) -> None:
        if self.squares_x < 3 or self.squares_y < 3:
            raise ValueError(
                f"a ChArUco board needs at least 3x3 squares, got {self.squares_x}x{self.squares_y}"
            )
        if not 0 < self.marker_mm < self.square_mm:
            raise ValueError(
                f"marker size must be positive and smaller than the square ({self.marker_mm} mm)"
            )
        if not hasattr(cv2.aruco, self.dictionary):
            raise ValueError(f"unknown ArUco dictionary {self.dictionary!r} (e.g. DICT_4X4_50, DICT_5X5_100)")

    @property
    def n_corners(self) -> int:
        return (self.squares_x - 1) * (self.squares_y - 1)

    def cv_board(self) -> cv2.aruco.CharucoBoard:
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        b = cv2.aruco.CharucoBoard(
            (self.squares_x, self.squares_y), float(self.square_mm), float(self.marker_mm), d
        )
        b.setLegacyPattern(bool(self.legacy))
        return b

    def object_points(self) -> np.ndarray:
        """Board-frame positions of all inner corners by id, mm, shape (n_corners, 3)."""
        return np.asarray(self.cv_board().getChessboardCorners(), float).reshape(-1, 3)


@dataclass(frozen=True)
class BoardDetection:
    """Corners of one board found in one image.

    Attributes
    ----------
    corners_px : ndarray, shape (N, 2)
        Refined corner pixels (u, v).
    ids : ndarray of int, shape (N,)
        Index of each corner into the board's ``object_points()``.
    image_size : tuple of int
        ``(width, height)`` of the image.
    method : str
        Which detector found the board (``"sb"``, ``"classic"``, ``"charuco"``).
    half_window_px : ndarray of int, shape (N,)
        Sub-pixel refinement half-window used at each corner (0: not refined).
    square_px : ndarray, shape (N,)
        Shortest distance to a grid neighbour at each corner, px.
    """

    corners_px: np.ndarray
    ids: np.ndarray
    image_size: tuple[int, int]
    method: str
    half_window_px: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    square_px: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def object_points(self, board: Chessboard | CharucoSpec) -> np.ndarray:
        """Board-frame points of the detected corners, mm, shape (N, 3)."""
        return board.object_points()[self.ids]


def _single_channel(image: np.ndarray) -> np.ndarray:
    im = np.asarray(image)
    if im.ndim == 3:
        code = cv2.COLOR_BGRA2GRAY if im.shape[2] == 4 else cv2.COLOR_BGR2GRAY
        im = cv2.cvtColor(im, code) if im.shape[2] in (3, 4) else im[..., 0]
    return np.ascontiguousarray(im)


def stored_grey(image: np.ndarray) -> np.ndarray:
    """Single-channel view of ``image`` (grey, BGR or BGRA) for reading a camera's response: an 8- or
    16-bit image at its stored depth, no level rescaled; any other depth (a float TIFF) as :func:`to_gray`
    gives it."""
    im = _single_channel(image)
    return im if im.dtype in (np.uint8, np.uint16) else to_gray(im)


def stored_grey_8bit(image: np.ndarray, stored_bits: int | None = None) -> np.ndarray:
    """:func:`stored_grey` on the 8-bit scale, a 16-bit level ``v`` stored as ``round(v * 255 / top)``, ``top``
    the camera's full scale (``2^stored_bits - 1``; 65535 where ``stored_bits`` is None): the full scale
    locate reads a 16-bit image on (:func:`doorloc.vision.luminance.luminance_plane`), one for every
    photograph, for measuring a camera's response. (:func:`to_gray`, for finding corners, stretches each
    image to its own brightest level: a gain that changes from photograph to photograph bends a response read
    through it.)"""
    im = stored_grey(image)
    if im.dtype == np.uint8:
        return im
    top = 65535.0 if stored_bits is None else float((1 << int(stored_bits)) - 1)
    return np.clip(np.rint(im.astype(float) * (255.0 / top)), 0, 255).astype(np.uint8)


#: the depths a camera's 16-bit photographs are read as storing where their levels all stay within them
#: (:func:`stored_bits_of`): a 10- or 12-bit camera that stores its levels from 0. (Photographs within 14
#: bits may be a 16-bit camera's at a quarter of its range: that depth is stated, not read.)
STORED_BITS_READ = (10, 12)


def stored_bits_of(images: Iterable[np.ndarray | None]) -> int | None:
    """The bits a camera stores its levels at in its 16-bit photographs ``images`` (None entries passed
    over): the fewest of :data:`STORED_BITS_READ` whose range holds every photograph's brightest level,
    where that lies above 255 (below, the photographs are too dark to tell); None for 8-bit photographs, or
    16-bit ones whose levels reach beyond 12 bits. A board photograph's white squares lie well up a camera's
    range: a 16-bit camera that put them all below a sixteenth of it would be exposed far too short."""
    levels = [brightest_level(im) for im in images if im is not None and im.dtype == np.uint16]
    return stored_bits_holding(max(levels, default=-1))


def brightest_level(image: np.ndarray) -> int:
    """The brightest level of an image's grey or colour channels (a BGRA image's alpha is no level of the
    camera's); -1 for an empty image."""
    colour = image[..., :3] if image.ndim == 3 else image
    return int(colour.max()) if colour.size else -1


def stored_bits_holding(brightest: int) -> int | None:
    """:func:`stored_bits_of` for 16-bit images whose brightest level is ``brightest``."""
    if brightest <= 255:
        return None
    return next((b for b in STORED_BITS_READ if brightest <= (1 << b) - 1), None)


def to_gray(image: np.ndarray) -> np.ndarray:
    """8-bit single-channel view of ``image`` (grey, BGR or BGRA; 16-bit scaled down to its own brightest
    level: corners are found as well in a dark 12-bit image stored in 16 bits)."""
    im = _single_channel(image)
    if im.dtype != np.uint8:
        im = im.astype(float)
        hi = float(np.nanmax(im)) if im.size else 1.0
        im = np.clip(np.rint(im * (255.0 / max(hi, 1e-12))), 0, 255).astype(np.uint8)
    return np.ascontiguousarray(im)


def canonical_grid_order(corners_px: np.ndarray, cols: int, rows: int) -> np.ndarray:
    """Reorder a row-major ``cols x rows`` corner grid so that rows run left to right in the image.

    Shape ``(cols*rows, 2) -> (cols*rows, 2)``. A non-square pattern allows two index orders
    (the board turned by 180 degrees); a square one four (turns by 90 degrees).
    """
    grid = np.asarray(corners_px, float).reshape(rows, cols, 2)
    options = [grid, grid[::-1, ::-1]]
    if cols == rows:
        options += [np.rot90(grid, 1, axes=(0, 1)), np.rot90(grid, 3, axes=(0, 1))]

    def score(g: np.ndarray) -> tuple[float, float]:
        r = np.mean(g[:, -1] - g[:, 0], axis=0)
        n = np.linalg.norm(r) or 1.0
        return (r[0] / n, -r[1] / n)

    best = max(options, key=score)
    return np.ascontiguousarray(best).reshape(-1, 2)


def local_square_px(corners_px: np.ndarray, cols: int, rows: int) -> np.ndarray:
    """Shortest distance from each corner of a ``cols x rows`` grid to its grid neighbours, px, shape (N,)."""
    g = np.asarray(corners_px, float).reshape(rows, cols, 2)
    d = np.full((rows, cols), np.inf)
    dx = np.linalg.norm(np.diff(g, axis=1), axis=-1)  # (rows, cols-1)
    dy = np.linalg.norm(np.diff(g, axis=0), axis=-1)  # (rows-1, cols)
    d[:, :-1] = np.minimum(d[:, :-1], dx)
    d[:, 1:] = np.minimum(d[:, 1:], dx)
    d[:-1, :] = np.minimum(d[:-1, :], dy)
    d[1:, :] = np.minimum(d[1:, :], dy)
    return d.ravel()


def half_window_from_square(square_px: np.ndarray) -> np.ndarray:
    """Refinement half-window for corners with the given local square size, px (int array)."""
    w = np.floor(WINDOW_FRACTION * np.asarray(square_px, float) - 1.0)
    w = np.where(np.isfinite(w), w, MIN_HALF_WINDOW)
    return np.clip(w, MIN_HALF_WINDOW, MAX_HALF_WINDOW).astype(int)


def refine_corners(gray: np.ndarray, corners_px: np.ndarray, half_window_px: np.ndarray) -> np.ndarray:
    """Sub-pixel refinement (``cv2.cornerSubPix``) with a per-corner half-window.

    Parameters
    ----------
    gray : ndarray, uint8, shape (H, W)
    corners_px : ndarray, shape (N, 2)
        Initial corner pixels.
    half_window_px : ndarray of int, shape (N,)
        Half-size of the search window at each corner (window is ``2w+1`` pixels wide).

    Returns
    -------
    ndarray, shape (N, 2)
        Refined pixels; a corner whose refinement walks further than its half-window keeps its
        initial position (the refinement was pulled by something other than this corner).
    """
    out = np.asarray(corners_px, np.float32).reshape(-1, 2).copy()
    hw = np.asarray(half_window_px, int)
    for w in np.unique(hw):
        sel = np.flatnonzero(hw == w)
        pts = out[sel].reshape(-1, 1, 2).copy()
        ref = cv2.cornerSubPix(gray, pts, (int(w), int(w)), (-1, -1), _SUBPIX_CRITERIA).reshape(-1, 2)
        moved = np.linalg.norm(ref - out[sel], axis=1)
        keep = moved <= w
        out[sel[keep]] = ref[keep]
    return out.astype(float)


def detect_chessboard(image: np.ndarray, board: Chessboard, *, refine: bool = True) -> BoardDetection | None:
    """Find ``board``'s inner corners in ``image``; None if the whole board is not found.

    Tries ``cv2.findChessboardCornersSB`` (sector-based, robust to blur and partial borders)
    first, then the classic detector; puts the corners in canonical order (module docstring)
    and refines them with windows sized from the local square size.
    """
    gray = to_gray(image)
    pattern = (int(board.cols), int(board.rows))
    method = "sb"
    ok, corners = cv2.findChessboardCornersSB(
        gray, pattern, flags=cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
    )
    if not ok or corners is None:
        method = "classic"
        ok, corners = cv2.findChessboardCorners(
            gray, pattern, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
        )
    if not ok or corners is None:
        return None
    c = canonical_grid_order(np.asarray(corners, float).reshape(-1, 2), board.cols, board.rows)
    sq = local_square_px(c, board.cols, board.rows)
    hw = half_window_from_square(sq)
    if refine:
        c = refine_corners(gray, c, hw)
    else:
        hw = np.zeros_like(hw)
    h, w = gray.shape[:2]
    return BoardDetection(c, np.arange(int(board.cols) * int(board.rows)), (w, h), method, hw, sq)


def nearby_chessboard(image: np.ndarray, board: Chessboard) -> tuple[int, int] | None:
    """The inner-corner count ``(cols, rows)`` of a chessboard ``image`` does show where ``board`` is not found.

    Tries the usual mistakes: squares counted instead of inner corners (one more each way), one count off,
    columns and rows swapped. None when none of those is found either. For a message, not for measuring:
    the classic detector with its fast check, no refinement.
    """
    gray = to_gray(image)
    c, r = int(board.cols), int(board.rows)
    tries = [
        (c - 1, r - 1),
        (r, c),
        (c - 1, r),
        (c, r - 1),
        (r - 1, c - 1),
        (c + 1, r + 1),
        (c + 1, r),
        (c, r + 1),
    ]
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_FAST_CHECK
    for cols, rows in dict.fromkeys(tries):
        if (
            min(cols, rows) >= 2
            and (cols, rows) != (c, r)
            and cv2.findChessboardCorners(gray, (cols, rows), flags=flags)[0]
        ):
            return cols, rows
    return None


def detect_charuco(
    image: np.ndarray, board: CharucoSpec, *, refine: bool = True, min_corners: int = 6
) -> BoardDetection | None:
    """Find the visible ChArUco corners of ``board`` in ``image`` (partial views allowed).

    None when fewer than ``min_corners`` corners are found. The local square size of each
    corner is taken from its nearest detected neighbour (ids adjacent on the board).
    """
    gray = to_gray(image)
    detector = cv2.aruco.CharucoDetector(board.cv_board())
    ch_corners, ch_ids, _, _ = detector.detectBoard(gray)
    if ch_ids is None or len(ch_ids) < min_corners:
        return None
    c = np.asarray(ch_corners, float).reshape(-1, 2)
    ids = np.asarray(ch_ids, int).ravel()
    order = np.argsort(ids)
    c, ids = c[order], ids[order]
    ncols = board.squares_x - 1
    col, row = ids % ncols, ids // ncols
    sq = np.full(len(ids), np.inf)
    for i in range(len(ids)):
        nb = (np.abs(col - col[i]) + np.abs(row - row[i])) == 1
        if np.any(nb):
            sq[i] = float(np.min(np.linalg.norm(c[nb] - c[i], axis=1)))
    if np.any(~np.isfinite(sq)):
        # Isolated corners: use the typical spacing of the view.
        fin = sq[np.isfinite(sq)]
        sq[~np.isfinite(sq)] = np.median(fin) if fin.size else 2 * (MIN_HALF_WINDOW + 1)
    # The markers sit (square - marker)/2 from the corners: the window must not reach their edges.
    gap = (board.square_mm - board.marker_mm) / (2 * board.square_mm)
    hw = np.minimum(
        half_window_from_square(sq), np.maximum(np.floor(gap * sq - 1.0), MIN_HALF_WINDOW)
    ).astype(int)
    if refine:
        c = refine_corners(gray, c, hw)
    else:
        hw = np.zeros_like(hw)
    h, w = gray.shape[:2]
    return BoardDetection(c, ids, (w, h), "charuco", hw, sq)


def detect_board(
    image: np.ndarray, board: Chessboard | CharucoSpec, *, refine: bool = True
) -> BoardDetection | None:
    """Dispatch to :func:`detect_chessboard` or :func:`detect_charuco` by the board's type."""
    if isinstance(board, CharucoSpec):
        return detect_charuco(image, board, refine=refine)
    return detect_chessboard(image, board, refine=refine)


@dataclass(frozen=True)
class SkippedImage:
    """An image that gave no view, and a sentence saying why."""

    name: str
    reason: str


@dataclass(frozen=True)
class BoardScan:
    """Board detections over a set of images.

    ``detections`` maps image name -> :class:`BoardDetection` for the images used; ``skipped``
    says why every other image was left out; ``image_size`` is the size all used images share.
    """

    detections: dict[str, BoardDetection]
    skipped: list[SkippedImage]
    image_size: tuple[int, int] | None


def scan_images(
    images: list[tuple[str, np.ndarray | None, str | None]],
    board: Chessboard | CharucoSpec,
    *,
    refine: bool = True,
) -> BoardScan:
    """Detect ``board`` in each image; keep those of the most common size.

    Parameters
    ----------
    images : list of (name, image or None, read error or None)
        Images as read at the edge; an image that could not be read carries its error message.
    board : the board to look for

    Returns
    -------
    BoardScan
        Images of another size than the most common one are skipped with a reason (mixed
        image sizes cannot share one set of intrinsics).
    """
    skipped: list[SkippedImage] = []
    sizes: dict[tuple[int, int], int] = {}
    readable: list[tuple[str, np.ndarray]] = []
    for name, im, err in images:
        if im is None:
            skipped.append(SkippedImage(name, err or "could not be read as an image"))
            continue
        size = (int(im.shape[1]), int(im.shape[0]))
        sizes[size] = sizes.get(size, 0) + 1
        readable.append((name, im))
    if not sizes:
        return BoardScan({}, skipped, None)
    size = max(sizes, key=lambda s: (sizes[s], s))
    detections: dict[str, BoardDetection] = {}
    for name, im in readable:
        s = (int(im.shape[1]), int(im.shape[0]))
        if s != size:
            skipped.append(
                SkippedImage(
                    name,
                    f"image is {s[0]}x{s[1]}, the others are {size[0]}x{size[1]}; "
                    "one calibration needs one image size",
                )
            )
            continue
        det = detect_board(im, board, refine=refine)
        if det is None:
            what = (
                "ChArUco board"
                if isinstance(board, CharucoSpec)
                else f"{board.cols}x{board.rows} chessboard (inner corners)"
            )
            skipped.append(
                SkippedImage(
                    name,
                    f"no {what} found: check --pattern, lighting and focus, "
                    "and that the whole board is in view",
                )
            )
            continue
        detections[name] = det
    return BoardScan(detections, skipped, size)
