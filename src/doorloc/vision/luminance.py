"""One luminance plane from whatever the camera delivered (thesis step 1, "extract luminance plane").

Colour images are turned into luminance with the ITU-R BT.601 weights OpenCV uses
(Y = 0.299 R + 0.587 G + 0.114 B), summed in linear light where the camera's levels are not linear
(:func:`luminance_plane`'s ``light_gamma``). 16-bit images are kept at full depth; ``scale_to_8bit`` tells
callers how to express grey levels on the familiar 0-255 scale, so thresholds mean the same for both. A
camera of 10, 12 or 14 bits that stores its levels from 0 in 16-bit images (``camera.stored_bits``) has
them brought to the 16-bit scale, its full scale at 65535, so that every threshold, clip and response reads
its light as a 16-bit camera's.
A camera whose response goes beyond a power law (its calibration's photometric model) has its levels
mapped to those a power-law camera would store (:func:`camera_levels`), so that the rest of locate, which
linearises with the cell's ``response_gamma``, reads its light.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from doorloc.calib.detect import brightest_level, stored_bits_holding
from doorloc.photometric.model import PhotometricModel
from doorloc.vision.jit import kernel, read_only

__all__ = [
    "BGR_WEIGHTS",
    "LuminancePlane",
    "ImageFormatError",
    "camera_levels",
    "luminance_plane",
]

#: ITU-R BT.601's weights of blue, green and red (OpenCV's ``COLOR_BGR2GRAY``)
BGR_WEIGHTS = (0.114, 0.587, 0.299)
#: steps of the table that stores the summed light as a power-law level, in the light's square root and
#: interpolated between steps: within one 16-bit code of the exact level over the whole scale (the square
#: root keeps the darks' steps fine: a level of 10 in 255 at an exponent of 2.4 lies 1340 steps up)
_ENCODE_STEPS = 65536


class ImageFormatError(ValueError):
    """An array that cannot be an image from this camera; the message says what is wrong."""


@dataclass(frozen=True, eq=False)
class LuminancePlane:
    """Grey image plus the factor that maps its values to the 0-255 scale.

    Attributes
    ----------
    plane : ndarray, shape (H, W), uint8 or uint16
        Luminance, not copied when the input was already grey (nor at the camera's full depth).
    scale_to_8bit : float
        1.0 for 8-bit data, 255/65535 for 16-bit data.
    stored_level_8bit : float or None
        One level of the camera's own on the 0-255 scale where it is coarser than the plane's (a 12-bit
        camera's, 255/4095, brought to 16 bits); None: one level of the plane (``scale_to_8bit``).
    """

    plane: np.ndarray
    scale_to_8bit: float
    #: the level (0-255 scale) at and above which this plane holds light the camera clipped, where the cell's
    #: camera model says it clips below full scale (:func:`camera_levels`); None: at full scale only
    clip_grey: float | None = None
    stored_level_8bit: float | None = None

    @property
    def level_8bit(self) -> float:
        """One level the camera stored, on the 0-255 scale (what the rounding to levels moves edges by)."""
        return self.scale_to_8bit if self.stored_level_8bit is None else self.stored_level_8bit

    @property
    def clipped_from(self) -> float | None:
        """The level (0-255 scale) from which a pixel counts as clipped: half a stored code under
        :attr:`clip_grey`, so that the clip's code and every code above it do; None where there is no clip."""
        return None if self.clip_grey is None else self.clip_grey - 0.5 * self.scale_to_8bit

    @property
    def size(self) -> tuple[int, int]:
        """``(width, height)`` in pixels."""
        return int(self.plane.shape[1]), int(self.plane.shape[0])


def luminance_plane(
    image: np.ndarray, light_gamma: float | None = None, stored_bits: int | None = None
) -> LuminancePlane:
    """Turn a grey, BGR or BGRA image (uint8 or uint16) into one luminance plane.

    ``stored_bits``: the bits of the camera's levels in a 16-bit image (the cell's ``camera.stored_bits``:
    a 12-bit camera stores 0-4095); its levels are brought to the 16-bit scale (``v * 65535 / (2^bits -
    1)``, rounded). None: a 16-bit image's levels span 0-65535.

    ``light_gamma``: where given, a colour image's channels are summed in light, each linearised at that
    exponent (``grey = light ** (1 / gamma)``, the cell's ``camera.response_gamma``). A weighted sum of
    stored levels is no level of the summed light: where the channels differ across an edge (a door of
    another hue than its background, each channel's edge of its own contrast; a single-chip camera, each
    channel interpolated from its own filters' pixels) the sum bends the edge's profile as a wrong exponent
    bends it: a wood-coloured door on a blue-grey fixture was placed 0.0063 mm off (RMS) and its camera's
    exponent read more than 2.5 sigma off on 7 doors in 24, and through a Bayer camera the exponent read
    3.59 +- 0.07 for 1.67 (``bench/bench_colour_doors.py``, ``bench_arris_range.py --demosaic``). So the
    channels are linearised, summed with :data:`BGR_WEIGHTS` and stored again through the power law, as a
    16-bit plane (:func:`_summed_in_light`); at an exponent of 1, or None, the sum is OpenCV's 8-bit one.
    JPEGs too: stored at quality 90 the hued doors came out 0.0019 mm off in light against 0.0068 in stored
    levels (through a Bayer camera as well, 0.0058 and 0.0059). A camera model beyond a power law
    (:func:`camera_levels`) is applied to the sum.

    Raises
    ------
    ImageFormatError
        Not a 2-D grey or 3-D 1/3/4-channel array of uint8/uint16 (floats in [0, 1] or [0, 255] are
        not guessed at: convert them explicitly); a 16-bit image with a level above ``stored_bits``, or
        whose levels all stay within 12 bits where ``stored_bits`` is None
        (:func:`doorloc.calib.detect.stored_bits_holding`, the depth calibrate reads off board photographs).

    Examples
    --------
    >>> bgr = np.zeros((4, 5, 3), np.uint8); bgr[..., 2] = 200        # pure red
    >>> lp = luminance_plane(bgr)
    >>> int(lp.plane[0, 0]), lp.size
    (60, (5, 4))
    """
    import cv2

    img = np.asarray(image)
    if img.dtype not in (np.uint8, np.uint16):
        raise ImageFormatError(
            f"image pixels are {img.dtype}; expected 8- or 16-bit integers from the camera"
        )
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[..., 0]
    top = _stored_top(img, stored_bits)
    if img.ndim == 2:
        plane = img
    elif img.ndim == 3 and img.shape[2] in (3, 4) and light_gamma is not None and light_gamma != 1.0:
        plane = _summed_in_light(img, float(light_gamma), top)
        top = 65535  # (the sum is stored on the 16-bit scale)
    elif img.ndim == 3 and img.shape[2] == 3:
        plane = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    elif img.ndim == 3 and img.shape[2] == 4:
        plane = cv2.cvtColor(img, cv2.COLOR_BGRA2GRAY)
    else:
        raise ImageFormatError(f"image has shape {img.shape}; expected (H, W) grey or (H, W, 3|4) colour")
    if plane.shape[0] < 8 or plane.shape[1] < 8:
        raise ImageFormatError(f"image is only {plane.shape[1]}x{plane.shape[0]} pixels")
    if plane.dtype == np.uint8:
        return LuminancePlane(plane, 1.0)
    if top == 65535:
        return LuminancePlane(plane, 255.0 / 65535.0)
    # cv2.multiply rounds v * 65535 / top to the nearest level exactly as np.rint does at 10, 12 and 14 bits
    # (every level compared, tests/vision/test_luminance.py), in a third of np.take's time on a table
    # (OpenCV's binding takes a number for src2 as a scalar, which its type stubs do not say)
    full = cv2.multiply(plane, 65535.0 / top, dtype=cv2.CV_16U)  # type: ignore[call-overload]
    return LuminancePlane(full, 255.0 / 65535.0, stored_level_8bit=255.0 / top)


def _stored_top(img: np.ndarray, stored_bits: int | None) -> int:
    """The level of the camera's full scale in ``img`` (255 for 8 bits; ``2^stored_bits - 1`` or 65535 for
    16), refusing a 16-bit image whose levels the stated depth, or an unstated one, cannot hold
    (:func:`luminance_plane`)."""
    if img.dtype == np.uint8:
        return 255
    top = 65535 if stored_bits is None else (1 << int(stored_bits)) - 1
    brightest = brightest_level(img)
    if brightest > top:
        raise ImageFormatError(
            f"the image holds level {brightest}, above the {stored_bits} bits the cell states for its camera "
            f"(camera.stored_bits: {stored_bits}, levels 0-{top}): state the depth the camera stores its "
            "levels at, or remove the key for a camera that uses all 16 bits"
        )
    # Levels that all stay within 12 bits (above 255: a black image is the gate's to name) are a 10- or
    # 12-bit camera's far more often than a 16-bit camera's exposed at a sixteenth of its range; read on
    # 65535's scale every threshold would be 16 times too strict (four of a 12-bit camera's rendered doors
    # were refused as "a faint edge, 4.9 grey levels" or "the far arris was not found", each of them)
    bits = stored_bits_holding(brightest) if stored_bits is None else None
    if bits is not None:
        raise ImageFormatError(
            f"the image is 16-bit but its brightest level is {brightest} of 65535, within a {bits}-bit "
            f"camera's 0-{(1 << bits) - 1}: if the camera stores {bits} bits in 16-bit images, state "
            f"camera.stored_bits: {bits} in the cell (doorloc calibrate reads it off the board photographs); "
            f"if it is a 16-bit camera, the image is exposed about {65535 // max(brightest, 1)} times too short"
        )
    return top


def _summed_in_light(bgr: np.ndarray, gamma: float, top: int) -> np.ndarray:
    """The 16-bit power-law levels (H, W) of the light of ``bgr``'s first three channels (uint8 or uint16,
    levels at the exponent ``gamma`` over full scale ``top``) summed with :data:`BGR_WEIGHTS` (compiled:
    :func:`_light_sum_levels`; numpy's float passes took 20 ms on a 1080p frame, the kernel 6)."""
    light, encode = _light_tables(gamma, top)
    # (a view of a larger array, or every other column, is copied: the kernel is compiled for C order)
    return _light_sum_levels(np.ascontiguousarray(bgr), light, encode)


@functools.lru_cache(maxsize=8)
def _light_tables(gamma: float, top: int) -> tuple[np.ndarray, np.ndarray]:
    """Each channel's weighted light by stored level (3, top + 1), and the 16-bit level by the summed
    light's square root in :data:`_ENCODE_STEPS` steps (one more entry: the top); read-only, shared."""
    levels = np.arange(top + 1) / top
    light = np.asarray(BGR_WEIGHTS)[:, None] * levels[None, :] ** gamma
    encode = np.rint((np.arange(_ENCODE_STEPS + 1) / _ENCODE_STEPS) ** (2.0 / gamma) * 65535.0)
    return read_only(light), read_only(encode)


def _light_sum_warm_up(k) -> None:
    light, encode = _light_tables(2.0, 255)
    k(np.zeros((2, 2, 3), np.uint8), light, encode)
    k(np.zeros((2, 2, 4), np.uint8), light, encode)
    light16, _ = _light_tables(2.0, 65535)
    k(np.zeros((2, 2, 3), np.uint16), light16, encode)
    k(np.zeros((2, 2, 4), np.uint16), light16, encode)


@kernel(_light_sum_warm_up)
def _light_sum_levels(bgr, light, encode):
    """:func:`_summed_in_light`'s pass: per pixel the three channels' weighted light from ``light``, its
    square root looked up in ``encode`` (linearly between steps)."""
    H, W = bgr.shape[0], bgr.shape[1]
    n = encode.size - 1
    out = np.empty((H, W), np.uint16)
    for i in range(H):
        for j in range(W):
            total = light[0, bgr[i, j, 0]] + light[1, bgr[i, j, 1]] + light[2, bgr[i, j, 2]]
            s = math.sqrt(total) * n
            q = min(int(s), n - 1)
            out[i, j] = int(encode[q] + (s - q) * (encode[q + 1] - encode[q]) + 0.5)
    return out


def camera_levels(lum: LuminancePlane, response: PhotometricModel | None, gamma: float) -> LuminancePlane:
    """The luminance ``lum`` as a camera of the power law ``grey = light ** (1 / gamma)`` would have stored
    it, where the camera's own response (``response``, a cell's ``camera_photometry``) goes beyond a power
    law; ``lum`` itself where it does not, or ``response`` is None.

    16-bit levels (``scale_to_8bit`` 255/65535), through the model's table
    (:meth:`doorloc.photometric.model.PhotometricModel.power_law_levels`): a camera's shoulder or pedestal
    undone before any edge is placed, and the response check, the doubts and the thresholds then see the
    levels of the power law they model. The mapping keeps the camera's full scale at full scale, so a
    clipped pixel stays at the top code.

    Where the model's sensor or tone curve clips below full scale (``clip_level``), the plane says at which
    of its levels (:attr:`LuminancePlane.clip_grey`): light stored there may be any light beyond it.
    """
    if response is None:
        return lum
    top_in = 255 if lum.plane.dtype == np.uint8 else 65535
    # the lowest stored level a clip at ``clip_level`` holds (a camera storing its clip rounds it)
    clip_in = min(int(np.floor(response.clip_level * top_in + 0.5)), top_in) if response.clips else None
    if not response.beyond_power_law:
        clip = None if clip_in is None else clip_in * lum.scale_to_8bit
        return LuminancePlane(lum.plane, lum.scale_to_8bit, clip, lum.stored_level_8bit)
    import cv2

    table = _power_law_levels(response, float(gamma), top_in)
    # cv2.LUT takes 8-bit images only (0.6 ms a 1080p frame, against 4.3 for numpy's indexing)
    levels = cv2.LUT(lum.plane, table) if top_in == 255 else np.take(table, lum.plane)
    s8 = 255.0 / 65535.0
    clip = None if clip_in is None else float(table[clip_in]) * s8
    return LuminancePlane(levels, s8, clip, lum.stored_level_8bit)


@functools.lru_cache(maxsize=8)
def _power_law_levels(response: PhotometricModel, gamma: float, top_in: int) -> np.ndarray:
    # one table per camera, exponent and depth (a 16-bit one costs more than a locate): read-only, shared
    table = response.power_law_levels(gamma, top_in)
    table.setflags(write=False)
    return table
