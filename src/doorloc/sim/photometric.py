"""Boards rendered as a real camera makes them: a camera's photometric model
(:class:`doorloc.photometric.model.PhotometricModel`) applied to the renderer's exact box-filtered radiance.

Image formation here: the printed board (its dark squares grown by the print's spread,
:class:`PrintedCheckerboard`) -> exact box-filtered radiance (:mod:`doorloc.sim.raster`) -> exposure ->
optics: a Gaussian blur whose variance changes over the field and with direction (``blur_field``,
``blur_anisotropy``) plus the point spread's halo (``psf_tail``) and a ghost (:class:`CameraRendering`, the
spread's asymmetry) -> read noise -> the response (power law,
shoulder and its white level, curvature, pedestal, the sensor's clip level;
:meth:`PhotometricModel.grey_from_light`) -> 8-bit
levels -> optional JPEG.

The Gaussian's change over the field is drawn by blending images blurred at a few sigmas (linear in the
variance between the two nearest), which is exact where the blur is uniform and smooth where it is not.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.ndimage import shift as ndimage_shift
from scipy.special import k0

from doorloc.calib.camera import CameraModel
from doorloc.photometric.model import PhotometricModel
from doorloc.sim.boards import Checkerboard, RenderedBoard, render_board
from doorloc.sim.raster import GridTexture

__all__ = [
    "PrintedCheckerboard",
    "CameraRendering",
    "apply_camera",
    "jpeg_roundtrip",
    "render_photographed_board",
]


@dataclass(frozen=True)
class PrintedCheckerboard(Checkerboard):
    """A :class:`~doorloc.sim.boards.Checkerboard` as printed: the dark squares grown by ``spread_mm`` on each
    side (toner or ink spread; negative: the light squares grow). The inner corners stay where they are (an
    X-junction of grown squares is still point-symmetric)."""

    spread_mm: float = 0.0

    def texture(self) -> GridTexture:
        base = super().texture()
        d = float(self.spread_mm)
        if d == 0.0:
            return base
        a = abs(d)
        s = np.unique(np.concatenate([base.s_lines - a, base.s_lines + a]))
        t = np.unique(np.concatenate([base.t_lines - a, base.t_lines + a]))
        sc = np.concatenate([[s[0] - 1.0], 0.5 * (s[1:] + s[:-1]), [s[-1] + 1.0]])
        tc = np.concatenate([[t[0] - 1.0], 0.5 * (t[1:] + t[:-1]), [t[-1] + 1.0]])
        S, T = np.meshgrid(sc, tc, indexing="ij")
        # grow the dark squares by a (square neighbourhood): the darkest reflectance within a of each cell
        looks = [base.lookup(S + i * 1.01 * a, T + j * 1.01 * a) for i in (-1, 0, 1) for j in (-1, 0, 1)]
        vals = np.min(looks, axis=0) if d > 0 else np.max(looks, axis=0)
        return GridTexture(s, t, vals)


@dataclass(frozen=True)
class CameraRendering:
    """What the camera adds beyond its photometric model, per photograph: ``blur_px`` (Gaussian sigma of the
    optics at the image centre), ``exposure`` (radiance 1 -> this fraction of full scale), ``read_noise``
    (grey levels, 1-sigma, before the response), ``jpeg_quality`` (0: none), ``ghost`` ``(fraction, du,
    dv)``: that fraction of the light displaced by ``(du, dv)`` image px after the blur (an analogue
    read-out's smear or ringing, interlaced fields out of register, a reflection in the optics): a point
    spread that is not point-symmetric. Its light moves a straight edge by the whole displacement's share
    (``fraction`` times its projection on the edge's normal), but an X-junction by less once the
    displacement exceeds the blur (a ghost of 0.3 at 3 px under a 1 px blur: a horizontal edge moves 0.90 px,
    the corner 0.56 px): the edges' displacement from the corners' frame that the catalogue's
    ``psf_asymmetry`` reads (as ``edge_shift_u_px``, ``edge_shift_v_px``). ``fields``: this photograph's
    interlaced fields' offset ``(du, dv)`` image px, the even rows sampling the image (after the optics) half
    of it away and the odd rows half of it the other way; None: the model's mean
    (``field_offset_u_px``, ``field_offset_v_px``)."""

    blur_px: float = 1.0
    exposure: float = 1.0
    read_noise: float = 0.0
    jpeg_quality: int = 0
    ghost: tuple[float, float, float] = (0.0, 0.0, 0.0)
    fields: tuple[float, float] | None = None


def _tail_kernel(scale_px: float) -> np.ndarray:
    """2-D isotropic kernel whose line spread is ``exp(-|x| / b) / (2 b)`` (``K0(r / b) / (2 pi b^2)``)."""
    r_max = int(np.ceil(8 * scale_px))
    y, x = np.mgrid[-r_max : r_max + 1, -r_max : r_max + 1]
    r = np.hypot(x, y)
    kern = k0(np.maximum(r, 0.25) / scale_px)  # the singular centre taken at a quarter pixel
    return (kern / kern.sum()).astype(np.float32)


def _blur(img: np.ndarray, sigma_x: float, sigma_y: float) -> np.ndarray:
    if sigma_x <= 0.05 and sigma_y <= 0.05:
        return img.copy()
    return cv2.GaussianBlur(
        img, (0, 0), max(sigma_x, 0.05), sigmaY=max(sigma_y, 0.05), borderType=cv2.BORDER_REFLECT
    )


def apply_camera(
    radiance: np.ndarray, model: PhotometricModel, rendering: CameraRendering, seed: int = 0
) -> np.ndarray:
    """The 8-bit photograph (H, W) a camera with ``model`` makes of box-filtered ``radiance`` (module docstring)."""
    img = np.asarray(radiance, np.float32) * np.float32(rendering.exposure)
    h, w = img.shape
    var0 = rendering.blur_px**2
    # the model's variance added across vertical edges (x) and taken off across horizontal ones (y)
    ax = model.blur_anisotropy

    def blurred(var: float) -> np.ndarray:
        vx, vy = max(var + ax, 0.0), max(var - ax, 0.0)
        return _blur(img, float(np.sqrt(vx)), float(np.sqrt(vy)))

    if model.blur_field == 0.0:
        out = blurred(var0)
    else:
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
        c = np.array([(w - 1) / 2.0, (h - 1) / 2.0], np.float32)
        r2 = ((xx - c[0]) ** 2 + (yy - c[1]) ** 2) / float((c**2).sum())
        var_map = np.maximum(var0 + model.blur_field * r2, 0.0)
        grid = np.linspace(float(var_map.min()), float(var_map.max()), 6)
        stack = [blurred(float(v)) for v in grid]
        pos = np.clip((var_map - grid[0]) / max(grid[1] - grid[0], 1e-9), 0, len(grid) - 1.000001)
        i0 = np.floor(pos).astype(int)
        f = (pos - i0).astype(np.float32)
        S = np.stack(stack)
        rows, cols = np.mgrid[0:h, 0:w]
        out = (1 - f) * S[i0, rows, cols] + f * S[np.minimum(i0 + 1, len(grid) - 1), rows, cols]
    if model.psf_tail > 0:
        halo = cv2.filter2D(img, -1, _tail_kernel(model.psf_tail_px), borderType=cv2.BORDER_REFLECT)
        out = (1 - model.psf_tail) * out + model.psf_tail * halo
    fraction, du, dv = rendering.ghost
    if fraction > 0:
        moved = cv2.warpAffine(
            out,
            np.array([[1.0, 0.0, du], [0.0, 1.0, dv]], np.float32),
            (w, h),
            flags=cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_REFLECT,
        )
        out = (1 - np.float32(fraction)) * out + np.float32(fraction) * moved
    du, dv = rendering.fields or (model.field_offset_u_px, model.field_offset_v_px)
    if du or dv:
        out = _interlace(out, du, dv)
    if rendering.read_noise > 0:
        rng = np.random.default_rng([seed, 7919])
        out = out + rng.standard_normal(out.shape, dtype=np.float32) * np.float32(
            rendering.read_noise / 255.0
        )
    grey = model.grey_from_light(np.clip(out, 0.0, None))
    u8 = np.rint(np.clip(grey, 0.0, 1.0) * 255).astype(np.uint8)
    return jpeg_roundtrip(u8, rendering.jpeg_quality)


def jpeg_roundtrip(u8: np.ndarray, quality: int) -> np.ndarray:
    """A grey 8-bit image (H, W) as a JPEG of ``quality`` (libjpeg's 1-100; 0: unchanged) stores it."""
    if not quality:
        return u8
    ok, buf = cv2.imencode(".jpg", u8, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    out = cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE) if ok else None
    if out is None:
        raise RuntimeError("JPEG encoding failed")
    return np.asarray(out, np.uint8)


def _interlace(img: np.ndarray, du: float, dv: float) -> np.ndarray:
    """``img`` as two interlaced fields out of register by ``(du, dv)`` px: each even row from the image
    sampled half of it away, each odd row from it sampled half of it the other way. Sampled by cubic splines
    (``scipy.ndimage.shift``; the image is the optics' blurred light, smooth at a pixel's scale): OpenCV's
    bicubic warp rounds the shift to 1/32 px and missed a blurred step by up to 0.9 % of it, which read a
    field offset of 0.159 px back as 0.205."""

    def sampled(su: float, sv: float) -> np.ndarray:
        # (scipy's shift s gives out[y, x] = img[y - s_y, x - s_x]: -(sv, su) samples the image (su, sv) away)
        return ndimage_shift(img, (-sv, -su), order=3, mode="reflect").astype(np.float32)

    out = sampled(0.5 * du, 0.5 * dv)
    out[1::2] = sampled(-0.5 * du, -0.5 * dv)[1::2]
    return out


def render_photographed_board(
    camera: CameraModel,
    board: Checkerboard,
    rvec,
    tvec_mm,
    model: PhotometricModel,
    rendering: CameraRendering = CameraRendering(),
    *,
    seed: int = 0,
    background: float = 0.3,
) -> RenderedBoard:
    """Render ``board`` at pose ``(rvec, tvec_mm)`` as a camera with photometric ``model`` photographs it:
    the print's spread from the model, then :func:`apply_camera`. ``image`` is the photograph; ``radiance``
    the box-filtered radiance of the printed board."""
    printed = PrintedCheckerboard(
        board.cols, board.rows, board.square_mm, board.margin_mm, model.print_spread_mm
    )
    rb = render_board(camera, printed, rvec, tvec_mm, background=background)
    image = apply_camera(rb.radiance, model, rendering, seed)
    return RenderedBoard(image, rb.corners_px, rb.ids, rb.object_points, rb.in_image, rb.radiance)


def random_board_views(
    camera: CameraModel,
    board: Checkerboard,
    model: PhotometricModel,
    n_views: int,
    seed: int,
    *,
    square_px: tuple[float, float] = (30.0, 45.0),
    blur_px: tuple[float, float] = (0.6, 1.4),
    exposure: tuple[float, float] = (0.55, 1.05),
    read_noise: tuple[float, float] = (0.5, 1.5),
    ghost: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> list[tuple[str, np.ndarray]]:
    """``n_views`` photographs ``(name, image)`` of ``board`` by a camera with ``model``, each at a random pose
    that shows the whole board (squares ``square_px`` wide near the middle), with the blur at the centre,
    exposure and read noise drawn per photograph from the given ranges, and the camera's ``ghost`` in every
    one (:class:`CameraRendering`); an interlaced model's fields out of register by its mean offset and, per
    photograph, its scatter (drawn from a generator of its own, so that the views stay those of ``seed``)."""
    rng = np.random.default_rng(seed)
    f = 0.5 * (camera.fx + camera.fy)
    w, h = camera.image_size
    centre = np.array([(board.cols - 1) * board.square_mm / 2, (board.rows - 1) * board.square_mm / 2, 0.0])
    views: list[tuple[str, np.ndarray]] = []
    tries = 0
    while len(views) < n_views:
        tries += 1
        if tries > 50 * n_views:
            raise ValueError("cannot place the board inside the image at the asked scale")
        rvec = np.array([rng.uniform(-0.45, 0.45), rng.uniform(-0.45, 0.45), rng.uniform(-0.3, 0.3)])
        z = f * board.square_mm / rng.uniform(*square_px)
        R = cv2.Rodrigues(rvec)[0]
        off = np.array([rng.uniform(-0.25, 0.25) * w, rng.uniform(-0.25, 0.25) * h]) * z / f
        tvec = -R @ centre + np.array([off[0], off[1], z])
        fields = None
        if model.interlaced:
            jitter = (
                np.random.default_rng([seed, tries, 4243]).standard_normal(2) * model.field_offset_scatter_px
            )
            fields = (model.field_offset_u_px + float(jitter[0]), model.field_offset_v_px + float(jitter[1]))
        look = CameraRendering(
            float(rng.uniform(*blur_px)),
            float(rng.uniform(*exposure)),
            float(rng.uniform(*read_noise)),
            ghost=ghost,
            fields=fields,
        )
        rb = render_photographed_board(camera, board, rvec, tvec, model, look, seed=seed * 1000 + len(views))
        margin = 2 * board.square_mm * f / z
        c = rb.corners_px
        if not (
            c[:, 0].min() > margin
            and c[:, 0].max() < w - 1 - margin
            and c[:, 1].min() > margin
            and c[:, 1].max() < h - 1 - margin
        ):
            continue
        views.append((f"view{len(views):02d}.png", rb.image))
    return views
