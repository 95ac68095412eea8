"""A board photograph's rendered twin: what a profile misfit is compared with.

A model that drew a camera's edges exactly would still leave a misfit: the sensor's noise and, in a JPEG
photograph, the compression, which quantizes the high spatial frequencies that an edge's transition is made
of. The plateaus' spread measures the first (:meth:`~doorloc.photometric.board_edges.BoardEdges.plateau_spread_rms`)
but not the second: on flat squares JPEG's quantization takes noise away, on the transitions it adds error
(rendered boards of OpenCV's poses through JPEG of quality 50, OpenCV's photographs' own: a profile misfit of
1.3-1.5 times the plateaus' spread with the very model that rendered them, 1.05 without the compression).

So each photograph gets a twin: the board rendered by :mod:`doorloc.sim.photometric` at the photograph's pose
(from its corners and the calibration), through the camera's photometric model, with the photograph's blur,
its squares' levels, read noise chosen so that the twin's plateaus spread as the photograph's do after the
compression, and the photograph's own compression (the JPEG quality its quantization tables say; noise is
added to the stored grey, as the plateaus' spread measures it). The twin's
edges are measured and fitted as the photograph's are; the misfit the twin leaves is the one a model that
drew everything the camera does would leave on the photograph. A photograph's misfit over its twin's says how
much of the profiles the model misses: 1 = nothing beyond noise and compression.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from doorloc.calib.calibrate import board_pose
from doorloc.calib.camera import CameraModel
from doorloc.photometric.blur import EdgeBlurs
from doorloc.photometric.board_edges import BoardEdges, measure_board_edges
from doorloc.photometric.fit import Photograph, transition_centres_px
from doorloc.photometric.model import PhotometricModel
from doorloc.photometric.profiles import fit_profiles
from doorloc.sim.boards import BOARD_BLACK, BOARD_WHITE, Checkerboard, render_board
from doorloc.sim.photometric import CameraRendering, PrintedCheckerboard, apply_camera, jpeg_roundtrip
from doorloc.vision.imageio import stored_jpeg_quality

__all__ = [
    "read_jpeg_quality",
    "ProfileTwin",
    "profile_twin",
    "profile_twins",
]


def read_jpeg_quality(path: str | os.PathLike) -> int:
    """The JPEG quality of an image file (:func:`doorloc.vision.imageio.stored_jpeg_quality`), 0 for a file
    that is not a JPEG (or cannot be read: the twin is then rendered without compression)."""
    try:
        data = Path(path).read_bytes()
    except OSError:
        return 0
    return stored_jpeg_quality(data)


#: bisection steps on the twin's read noise (each a render and a measure; the spread matched to ~1/2^steps of
#: three times the photograph's)
TWIN_NOISE_STEPS = 7


@dataclass(frozen=True)
class ProfileTwin:
    """A photograph's twin (module docstring): how it was rendered and the misfit it leaves.

    ``blur_px``: Gaussian sigma of the optics at the image centre; ``read_noise``: grey levels (1-sigma)
    added to the stored grey, after the response and before the compression; ``jpeg_quality``: 0 = none;
    ``plateau_spread``: the twin's plateaus' spread (grey, RMS over the windows; the photograph's is matched);
    ``misfit``: the twin's profile misfit with the model it was rendered with (grey, RMS over the windows)."""

    blur_px: float
    read_noise: float
    jpeg_quality: int
    plateau_spread: float
    misfit: float


def _centre_blur_px(
    photo: Photograph, model: PhotometricModel, keep: np.ndarray, fields_px: tuple[float, float]
) -> float:
    """The photograph's blur at the image centre (px): its edges' fitted blur (as the check fits them: centred
    where the model places them, through its fields' offset) with what the model's blur field and direction
    term add at each edge taken off in variance, averaged as :mod:`doorloc.photometric.blur` fits them."""
    e = photo.edges
    b = fit_profiles(e, model, keep, transition_centres_px(photo, model), fields_px).blur_px
    features = EdgeBlurs(b, e.mid_px, e.normal, e.image_size).features()
    var = b**2 - model.blur_field * features[:, 0] - model.blur_anisotropy * features[:, 1]
    ok = np.isfinite(var)
    return float(np.sqrt(max(float(np.mean(var[ok])), 0.04))) if ok.any() else 1.0


def _levels_light(photo: Photograph, model: PhotometricModel) -> tuple[float, float]:
    """The photograph's dark and light squares' light (model's linear light): medians over its edges' plateaus."""
    e = photo.edges
    d = np.nanmedian(e.dark_by_edge)
    b = np.nanmedian(e.bright_by_edge)
    # a level at or under the model's pedestal is no light, which the model stores at 0: the twin's squares
    # are kept a grey level above it, where the model's response is defined both ways
    floor = 255.0 * max(model.black_level, 0.0) + 1.0
    light = model.light_from_grey(np.maximum(np.array([d, b]), floor) / 255.0)
    return float(light[0]), float(light[1])


def profile_twin(
    photo: Photograph,
    camera: CameraModel,
    board: Checkerboard,
    model: PhotometricModel,
    *,
    fields_px: tuple[float, float] = (0.0, 0.0),
    seed: int = 0,
) -> ProfileTwin:
    """Render ``photo``'s twin (module docstring) and fit its profiles with ``model``.

    The pose comes from the photograph's corners (``photo.corners_px``, in ``board``'s order) through
    ``camera``, the compression from ``photo.jpeg_quality``; ``fields_px``: the photograph's interlaced
    fields' offset (image px). Raises ValueError for a photograph without corners."""
    if photo.corners_px is None:
        raise ValueError(f"{photo.name}: its corners were not kept, so it has no pose to render its twin at")
    rvec, tvec = board_pose(camera, board.object_points(), photo.corners_px)
    jpeg_quality = photo.jpeg_quality
    keep = np.isfinite(photo.edges.offset_px)
    target = photo.edges.plateau_spread_rms(photo.settings.plateau, keep)
    blur = _centre_blur_px(photo, model, keep, fields_px)
    dark, light = _levels_light(photo, model)
    printed = PrintedCheckerboard(
        board.cols, board.rows, board.square_mm, board.margin_mm, model.print_spread_mm
    )
    rb = render_board(camera, printed, rvec, tvec)
    # the board's reflectances mapped onto the photograph's squares' light (the margin and surround with them)
    radiance = dark + (rb.radiance - BOARD_BLACK) * ((light - dark) / (BOARD_WHITE - BOARD_BLACK))

    # the optics' image as the camera stores it, before its noise; the noise is added to the stored grey (as
    # the plateaus' spread is measured: through a response with a toe, noise added to the light would be
    # amplified at the dark squares alone) and rounded, then the compression
    clean = apply_camera(radiance, model, CameraRendering(blur, 1.0, 0.0, 0, fields=fields_px), seed)
    pattern = np.random.default_rng([seed, 7919]).standard_normal(clean.shape)

    def rendered(read_noise: float) -> tuple[BoardEdges, np.ndarray, float]:
        noisy = np.rint(np.clip(clean + read_noise * pattern, 0.0, 255.0)).astype(np.uint8)
        img = jpeg_roundtrip(noisy, jpeg_quality)
        e = measure_board_edges(
            img, rb.corners_px, board.cols, board.rows, board.square_mm, camera, settings=photo.settings
        )
        k = np.isfinite(e.offset_px)
        return e, img, e.plateau_spread_rms(photo.settings.plateau, k)

    # the spread after the compression grows with the read noise, but not in any closed form (JPEG's
    # quantization takes small noise away and lets large noise through): bisection on the read noise, the
    # same noise pattern scaled (the spread then follows it smoothly)
    lo, hi = 0.0, 3.0 * float(target) if np.isfinite(target) and target > 0 else 0.0
    edges, img, spread = rendered(0.0)
    noise = 0.0
    if hi > 0 and spread < target:
        for _ in range(TWIN_NOISE_STEPS):
            mid = 0.5 * (lo + hi)
            e_mid, i_mid, s_mid = rendered(mid)
            if s_mid < target:
                lo = mid
            else:
                hi = mid
            if abs(s_mid - target) < abs(spread - target):
                edges, img, spread, noise = e_mid, i_mid, s_mid, mid
    shifts = transition_centres_px(Photograph(img, edges, photo.settings), model)
    misfit = fit_profiles(edges, model, np.isfinite(edges.offset_px), shifts, fields_px).rms_over_windows()
    return ProfileTwin(blur, noise, int(jpeg_quality), float(spread), float(misfit))


def profile_twins(
    photos: Sequence[Photograph],
    camera: CameraModel,
    board: Checkerboard,
    model: PhotometricModel,
    fields_px: Sequence[tuple[float, float]] | None = None,
) -> list[ProfileTwin | None]:
    """Each photograph's twin (:func:`profile_twin`) through ``model``, with its own fields' offset
    (``fields_px``, one per photograph; None: none) and the compression its file says; None for a photograph
    whose corners were not kept or whose twin cannot be rendered (no pose from its corners: the figures that
    need a twin then leave it out rather than the check failing)."""
    out: list[ProfileTwin | None] = []
    for i, p in enumerate(photos):
        try:
            fields = fields_px[i] if fields_px is not None else (0.0, 0.0)
            out.append(profile_twin(p, camera, board, model, fields_px=fields, seed=i))
        except (ValueError, cv2.error):
            out.append(None)
    return out
