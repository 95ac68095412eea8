"""Photometric, optical and sensor effects of the renderer, each with a default that switches it off.

:class:`Effects` is one frozen value that says everything about how an image was made beyond its
geometry, so a data set can be made with exactly one effect switched on and its ``truth.csv`` can
record the effects used (:meth:`Effects.to_dict`, one column per field).

The image formation order (:func:`form_image`):

scene radiance (per-face albedo x (ambient + directional Lambert), wood grain, shadows; rendered by
:mod:`doorloc.sim.raster`) -> illumination gradient and vignetting (smooth, per pixel) -> optical blur
(Gaussian) -> exposure to electrons with shot noise (Poisson, drawn in its Gaussian limit) and read noise -> response curve
(gamma) -> quantization to 8 or 16 bits -> optional JPEG round trip.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any

import numpy as np

from doorloc.photometric.model import PhotometricModel
from doorloc.pose import direction_cell

__all__ = [
    "DEMOSAIC_METHODS",
    "SRGB_STATED_GAMMA",
    "WOOD_TINT_BGR",
    "Effects",
    "bayer_samples",
    "demosaiced",
    "form_image",
    "lambert_shade",
    "srgb_from_linear",
    "wood_grain",
]

#: the exponent a user states for a camera that delivers the sRGB curve (its best power-law match)
SRGB_STATED_GAMMA = 2.2
#: ``Effects.demosaic``'s choices and OpenCV's conversion for each, from an RGGB mosaic (OpenCV names its
#: Bayer codes by the second row's second and third pixels: its ``BayerBG`` is an RGGB sensor)
DEMOSAIC_METHODS = ("none", "bilinear", "edge_aware")
_DEMOSAIC_CODES = {"bilinear": "COLOR_BayerBG2BGR", "edge_aware": "COLOR_BayerBG2BGR_EA"}
#: a light wood's share of the light in each channel, BGR (the colour images' tint)
WOOD_TINT_BGR = (0.80, 0.93, 1.0)


@dataclass(frozen=True)
class Effects:
    """How an image is made beyond its geometry. The defaults give a plain, noise-free 8-bit image.

    Albedos are reflectances in [0, 1]; with the default lighting (ambient 1, no directional light) a
    face's radiance equals its albedo, and radiance 1 maps to the top of the output range.

    Attributes
    ----------
    albedo_hinge, albedo_side, albedo_end, albedo_chamfer, albedo_back, albedo_background : float
        Per-face reflectance: hinge-edge face, the big faces (X=0, X=T), the ends (Z=0, Z=H),
        chamfer/arris facets, the far edge face (Y=W), the background plane.
    light_ambient : float
        Ambient term of the lighting.
    light_directional : float
        Strength of a directional light (0 = off), Lambert: ``albedo * (ambient + k * max(0, n.l))``.
    finish_exponent : float
        The directional term's ``max(0, n.l)`` raised to this power on every face and across the rounded
        arrises: 1 a matt (Lambertian) finish; under 1 a flatter shading, as a rough finish; over 1 a
        shading peaked towards the light, as a satin one. Locate's arc model is Lambertian: this is what it
        meets on finishes that are not.
    light_azimuth_deg, light_elevation_deg : float
        Direction *towards* the light in the cell frame: azimuth from -Y (towards the camera) about +Z,
        positive towards +X; elevation towards +Z.
    gradient_u, gradient_v : float
        Illumination gradient: relative radiance change from the image centre to the right / bottom
        image border (multiplier ``1 + gu*(u-cx)/(w/2) + gv*(v-cy)/(h/2)``).
    vignetting : float
        Relative fall-off at the image corner (``1 - k*(r/r_corner)^2``); 0 = off.
    grain_contrast : float
        Relative amplitude of the wood-grain pattern on the hinge face; 0 = off.
    grain_period_mm : float
        Typical spacing of grain lines across the thickness, mm.
    shadow_strength : float
        Darkening (0..1) of a band across the hinge face (a shadow near the corner); 0 = off.
    shadow_z_mm, shadow_height_mm : float
        Where the band starts above the bottom end, and its height, door frame, mm.
    clamp_albedo : float
        Reflectance of a dark clamp on the background beside the corner; < 0 = off.
    second_edge_offset_mm : float
        A second, parallel vertical edge on the background this far (mm at the hinge-face depth) to the
        left of the reference face; 0 = off.
    second_edge_albedo : float
        Reflectance of the background left of the second edge.
    arris_profile : str
        ``"chamfer"`` (45 degrees) or ``"round"`` for the door's arris of size ``DoorSize.arris_mm``.
    blur_sigma_px : float
        Gaussian optical blur, px; 0 = off.
    blur_halo_fraction, blur_halo_sigma_px : float
        A lens's halo: this share of the light spread by a Gaussian of this sigma (px) instead of
        ``blur_sigma_px``'s, the rest by the core's; 0 = off. Locate's edge models assume one Gaussian.
    blur_disk_px : float
        Defocus: the light spread over a uniform disk of this radius (px) before the Gaussian blur (a lens
        out of focus is a disk, not a Gaussian); 0 = off.
    blur_astigmatism_px : float
        More Gaussian blur along the image's columns than along its rows: this sigma (px) after the lens's
        point spread (a lens whose sagittal and tangential blur differ, or the door moving along the image's
        y while exposed); the door's bottom end is then blurrier than its long edges. 0 = off.
    full_well_e : float
        Electrons at full scale for shot noise (variance = signal / full well); 0 = off.
    read_noise_dn : float
        Gaussian read noise, standard deviation in output DN of the 8-bit scale; 0 = off.
    gamma : float
        Response ``out = in ** (1/gamma)``; 1 = linear.
    response_curve : str
        ``"power"``: the response is ``gamma``'s power law. ``"srgb"``: the sRGB transfer curve of IEC
        61966-2-1 (a linear segment below 0.0031308 of full scale, above it ``1.055 in ** (1/2.4) - 0.055``),
        which most colour and many machine-vision cameras deliver and their users call "gamma 2.2"
        (:data:`SRGB_STATED_GAMMA`); ``gamma`` must then stay 1.
    sharpen_amount, sharpen_radius_px : float
        In-camera sharpening (edge enhancement) of the grey levels after the response, an unsharp mask:
        ``out + amount * (out - gaussian(out, radius))``; 0 = off. Locate assumes it off.
    bit_depth : int
        8 (uint8 output), or 10, 12, 14 or 16: uint16 output whose levels span ``0 .. 2^bit_depth - 1``
        (a 12-bit camera that stores its levels from 0 in 16-bit images, as machine-vision cameras' Mono12
        frames are often saved).
    jpeg_quality : int
        JPEG round trip at this quality (1-100, 8-bit only); 0 = off.
    color : bool
        Return a 3-channel BGR image (wood tint) instead of grey.
    demosaic : str
        ``"none"``: every pixel sees the light itself. ``"bilinear"`` or ``"edge_aware"``: a single-chip colour
        camera's: the lens's light, times the wood tint's share of each channel, is sampled through a Bayer
        colour filter (one channel a pixel, RGGB), the sensor's noise drawn on those samples, and the
        missing two channels of every pixel interpolated by OpenCV's demosaicing (bilinear, or its
        edge-aware variant) from a 16-bit linear raw before the response; the image is colour (BGR)
        whatever ``color`` says. The interpolation widens the blur unevenly by channel and phase, and
        correlates the noise of neighbouring pixels (locate reads one grey plane of the three).
    """

    albedo_hinge: float = 0.78
    albedo_side: float = 0.55
    albedo_end: float = 0.45
    albedo_chamfer: float = 0.66
    albedo_back: float = 0.5
    albedo_background: float = 0.12
    light_ambient: float = 1.0
    light_directional: float = 0.0
    finish_exponent: float = 1.0
    light_azimuth_deg: float = 30.0
    light_elevation_deg: float = 30.0
    gradient_u: float = 0.0
    gradient_v: float = 0.0
    vignetting: float = 0.0
    grain_contrast: float = 0.0
    grain_period_mm: float = 2.5
    shadow_strength: float = 0.0
    shadow_z_mm: float = 30.0
    shadow_height_mm: float = 40.0
    clamp_albedo: float = -1.0
    second_edge_offset_mm: float = 0.0
    second_edge_albedo: float = 0.35
    arris_profile: str = "chamfer"
    blur_sigma_px: float = 0.0
    blur_halo_fraction: float = 0.0
    blur_halo_sigma_px: float = 0.0
    blur_disk_px: float = 0.0
    blur_astigmatism_px: float = 0.0
    full_well_e: float = 0.0
    read_noise_dn: float = 0.0
    gamma: float = 1.0
    response_curve: str = "power"
    sharpen_amount: float = 0.0
    sharpen_radius_px: float = 0.0
    bit_depth: int = 8
    jpeg_quality: int = 0
    color: bool = False
    demosaic: str = "none"

    def __post_init__(self) -> None:
        if self.bit_depth not in (8, 10, 12, 14, 16):
            raise ValueError(f"bit_depth must be 8, 10, 12, 14 or 16, got {self.bit_depth!r}")
        if self.arris_profile not in ("chamfer", "round"):
            raise ValueError(f"arris_profile must be 'chamfer' or 'round', got {self.arris_profile!r}")
        if not 0 <= self.jpeg_quality <= 100:
            raise ValueError(f"jpeg_quality must be 0 (off) or 1-100, got {self.jpeg_quality!r}")
        if self.jpeg_quality and self.bit_depth != 8:
            raise ValueError("JPEG output needs bit_depth 8")
        if not self.finish_exponent > 0:
            raise ValueError(f"finish_exponent must be > 0, got {self.finish_exponent!r}")
        for name in (
            "blur_sigma_px",
            "blur_halo_sigma_px",
            "blur_disk_px",
            "blur_astigmatism_px",
            "sharpen_amount",
            "sharpen_radius_px",
            "full_well_e",
            "read_noise_dn",
            "grain_contrast",
            "vignetting",
        ):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)!r}")
        if not self.gamma > 0:
            raise ValueError(f"gamma must be > 0, got {self.gamma!r}")
        if self.response_curve not in ("power", "srgb"):
            raise ValueError(f"response_curve must be 'power' or 'srgb', got {self.response_curve!r}")
        if self.demosaic not in DEMOSAIC_METHODS:
            raise ValueError(f"demosaic must be one of {', '.join(DEMOSAIC_METHODS)}, got {self.demosaic!r}")
        if self.response_curve == "srgb" and self.gamma != 1.0:
            raise ValueError("the sRGB curve is the response: gamma must stay 1 with response_curve 'srgb'")
        if not 0 <= self.blur_halo_fraction < 1:
            raise ValueError(f"blur_halo_fraction must be in [0, 1), got {self.blur_halo_fraction!r}")
        if self.blur_halo_fraction > 0 and not self.blur_halo_sigma_px > 0:
            raise ValueError("a halo (blur_halo_fraction > 0) needs its spread, blur_halo_sigma_px > 0")
        if self.sharpen_amount > 0 and not self.sharpen_radius_px > 0:
            raise ValueError("sharpening (sharpen_amount > 0) needs its radius, sharpen_radius_px > 0")
        if not 0 <= self.shadow_strength <= 1:
            raise ValueError(f"shadow_strength must be in [0, 1], got {self.shadow_strength!r}")

    @property
    def stated_gamma(self) -> float:
        """The exponent a cell states for this camera (``camera.response_gamma``): ``gamma``, or 2.2 for the
        sRGB curve (:data:`SRGB_STATED_GAMMA`)."""
        return SRGB_STATED_GAMMA if self.response_curve == "srgb" else self.gamma

    def to_dict(self) -> dict:
        """Plain mapping of every field (scalars only), e.g. for ``truth.csv`` columns."""
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> Effects:
        """Inverse of :meth:`to_dict`; values may be strings (from CSV). Unknown keys are refused."""
        known = {f.name: f for f in fields(cls)}
        unknown = set(d) - set(known)
        if unknown:
            raise ValueError(f"unknown effect(s): {', '.join(sorted(unknown))}; known: {', '.join(known)}")
        kw: dict[str, Any] = {}
        for k, v in d.items():
            default = known[k].default
            try:
                if isinstance(default, bool):
                    kw[k] = v if isinstance(v, bool) else str(v).strip().lower() in ("1", "true", "yes")
                elif isinstance(default, int):
                    kw[k] = int(float(v))
                elif isinstance(default, float):
                    kw[k] = float(v)
                else:
                    kw[k] = str(v)
            except ValueError:
                raise ValueError(f"effect {k} needs a {type(default).__name__}, got {v!r}") from None
        return cls(**kw)

    def finish_term(self, cos_l: float | np.ndarray) -> float | np.ndarray:
        """The directional light's term for ``cos_l = max(0, n.l)`` (scalar or array) under this finish."""
        return cos_l if self.finish_exponent == 1.0 else np.power(cos_l, self.finish_exponent)

    def light_direction_cell(self) -> np.ndarray:
        """Unit vector towards the light, cell frame, shape (3,) (:func:`doorloc.pose.direction_cell`)."""
        return direction_cell(self.light_azimuth_deg, self.light_elevation_deg)


def srgb_from_linear(light: np.ndarray) -> np.ndarray:
    """The sRGB transfer curve (IEC 61966-2-1): linear light in [0, 1] to encoded levels in [0, 1], float32.

    Written out (two lines of the standard) rather than taken from a colour library: scikit-image and
    OpenCV apply it only inside their colour-space conversions, not to one grey channel."""
    x = np.clip(np.asarray(light, np.float32), 0.0, 1.0)
    curve = np.float32(1.055) * np.power(x, np.float32(1 / 2.4)) - np.float32(0.055)
    return np.where(x <= 0.0031308, np.float32(12.92) * x, curve).astype(np.float32)


def lambert_shade(effects: Effects, albedo: float, normal_cell: np.ndarray) -> float:
    """Radiance factor of a face: ``albedo * (ambient + directional * max(0, n.l))``."""
    n = np.asarray(normal_cell, float)
    n = n / np.linalg.norm(n)
    cos = max(0.0, float(n @ effects.light_direction_cell()))
    return float(albedo * (effects.light_ambient + effects.light_directional * effects.finish_term(cos)))


def wood_grain(effects: Effects, seed: int):
    """Smooth multiplicative wood-grain pattern on the hinge face, ``f(s, t) -> array``.

    ``s`` runs across the thickness and ``t`` along the door height (mm); grain lines run along ``t``
    and wander slowly. Returns None when the effect is off.
    """
    if effects.grain_contrast <= 0:
        return None
    rng = np.random.default_rng([seed, 7919])
    k = 5
    periods = effects.grain_period_mm * rng.uniform(0.6, 1.6, k)
    phases = rng.uniform(0, 2 * np.pi, k)
    amps = rng.uniform(0.5, 1.0, k)
    amps = amps / amps.sum()
    wander_len = rng.uniform(150.0, 400.0, k)
    wander_amp = rng.uniform(0.5, 2.0, k)
    c = effects.grain_contrast

    def grain(s: np.ndarray, t: np.ndarray) -> np.ndarray:
        g = np.zeros(np.broadcast(s, t).shape)
        for p, ph, a, wl, wa in zip(periods, phases, amps, wander_len, wander_amp, strict=True):
            g += a * np.sin(2 * np.pi * (s + wa * np.sin(2 * np.pi * t / wl)) / p + ph)
        return 1.0 + c * g

    return grain


def _disk_kernel(radius_px: float) -> np.ndarray:
    """A uniform disk of ``radius_px`` as a normalised float32 kernel, each pixel weighted by the share of it
    the disk covers (8 x 8 samples a pixel), so that a disk of any radius is centred and symmetric."""
    n = int(np.ceil(radius_px))
    sub = (np.arange(8) + 0.5) / 8 - 0.5
    c = np.arange(-n, n + 1, dtype=float)
    x = (c[:, None] + sub[None, :]).ravel()
    inside = (x[:, None] ** 2 + x[None, :] ** 2 <= radius_px**2).reshape(2 * n + 1, 8, 2 * n + 1, 8)
    kern = inside.mean(axis=(1, 3))
    return (kern / kern.sum()).astype(np.float32)


def _lens_blur(img: np.ndarray, effects: Effects) -> np.ndarray:
    """``img`` through the lens's point spread: a defocus disk (``blur_disk_px``), then the Gaussian core
    (``blur_sigma_px``) with its halo (``blur_halo_fraction`` of the light at ``blur_halo_sigma_px``), then
    the astigmatism's Gaussian along the image's columns alone (``blur_astigmatism_px``)."""
    import cv2

    if effects.blur_disk_px > 0:
        img = cv2.filter2D(img, -1, _disk_kernel(effects.blur_disk_px), borderType=cv2.BORDER_REFLECT)
    halo = None
    if effects.blur_halo_fraction > 0:
        halo = cv2.GaussianBlur(img, (0, 0), effects.blur_halo_sigma_px, borderType=cv2.BORDER_REFLECT)
    if effects.blur_sigma_px > 0:
        img = cv2.GaussianBlur(img, (0, 0), effects.blur_sigma_px, borderType=cv2.BORDER_REFLECT)
    if halo is not None:
        f = np.float32(effects.blur_halo_fraction)
        img = (1 - f) * img + f * halo
    if effects.blur_astigmatism_px > 0:
        s = effects.blur_astigmatism_px
        # a kernel one pixel wide: the rows are left as they are
        img = cv2.GaussianBlur(
            img, (1, 2 * math.ceil(4.0 * s) + 1), s, sigmaY=s, borderType=cv2.BORDER_REFLECT
        )
    return img


def bayer_samples(light_bgr: np.ndarray) -> np.ndarray:
    """A single-chip colour sensor's raw samples (H, W) of the light of each channel ``light_bgr`` (H, W, 3,
    BGR): each pixel its filter's channel, the filters laid out RGGB (red at even rows and columns)."""
    raw = np.empty(light_bgr.shape[:2], light_bgr.dtype)
    raw[0::2, 0::2], raw[0::2, 1::2] = light_bgr[0::2, 0::2, 2], light_bgr[0::2, 1::2, 1]
    raw[1::2, 0::2], raw[1::2, 1::2] = light_bgr[1::2, 0::2, 1], light_bgr[1::2, 1::2, 0]
    return raw


def demosaiced(raw: np.ndarray, method: str) -> np.ndarray:
    """The BGR light (H, W, 3, float32) OpenCV's demosaicing ``method`` (``bilinear`` or ``edge_aware``) makes
    of RGGB raw samples ``raw`` in [0, 1] (:func:`bayer_samples`), quantised to 16 bits first (OpenCV
    demosaics integers; a camera's raw has 10-14)."""
    import cv2

    counts = np.rint(raw * 65535.0).astype(np.uint16)
    colour = cv2.demosaicing(counts, getattr(cv2, _DEMOSAIC_CODES[method]))
    return colour.astype(np.float32) * np.float32(1.0 / 65535.0)


def form_image(
    radiance: np.ndarray,
    effects: Effects,
    seed: int = 0,
    principal_point=None,
    response: PhotometricModel | None = None,
) -> np.ndarray:
    """Turn a rendered radiance image into the sensor's output image.

    Parameters
    ----------
    radiance : ndarray, shape (H, W), float
        Box-filtered scene radiance, 1 = full scale.
    effects : Effects
        Which effects to apply.
    seed : int
        Seeds the noise; the same seed gives the same bytes.
    principal_point : (float, float) or None
        Centre of vignetting (defaults to the image centre).
    response : PhotometricModel or None
        A camera response beyond a power law (a cell's ``camera_photometry``): full-scale light is stored at
        full scale and every level below as the model's response stores it
        (:meth:`~doorloc.photometric.model.PhotometricModel.grey_from_light`), in place of
        ``effects.gamma`` and ``effects.response_curve``. None (or a model that is a power law): those.

    Returns
    -------
    ndarray
        uint8 or uint16, shape (H, W) or (H, W, 3) (BGR) with ``effects.color``.
    """
    import cv2

    img: np.ndarray = np.asarray(radiance, dtype=np.float32)
    h, w = img.shape
    if effects.gradient_u or effects.gradient_v or effects.vignetting:
        cx, cy = principal_point if principal_point is not None else ((w - 1) / 2, (h - 1) / 2)
        u = ((np.arange(w) - (w - 1) / 2) / (w / 2)).astype(np.float32)
        v = ((np.arange(h) - (h - 1) / 2) / (h / 2)).astype(np.float32)
        field = (np.float32(effects.gradient_u) * u)[None, :] + (1.0 + np.float32(effects.gradient_v) * v)[
            :, None
        ]
        if effects.vignetting:
            du = (np.arange(w) - cx).astype(np.float32)
            dv = (np.arange(h) - cy).astype(np.float32)
            r2_corner = max((cx + 0.5) ** 2, (w - 0.5 - cx) ** 2) + max((cy + 0.5) ** 2, (h - 0.5 - cy) ** 2)
            k = np.float32(effects.vignetting / r2_corner)
            field *= 1.0 - k * ((du * du)[None, :] + (dv * dv)[:, None])
        img = img * field
    img = _lens_blur(img, effects)
    if effects.demosaic != "none":
        img = bayer_samples(img[..., None] * np.array(WOOD_TINT_BGR, np.float32))
    if effects.full_well_e > 0 or effects.read_noise_dn > 0:
        # Poisson-Gaussian sensor noise: shot noise of variance mean/full_well (the Gaussian limit of
        # Poisson, within 1 % above ~100 electrons) plus read noise, drawn as one normal variate.
        rng = np.random.default_rng([seed, 104729])
        var: np.ndarray | np.floating = np.float32((effects.read_noise_dn / 255.0) ** 2)
        if effects.full_well_e > 0:
            var = np.maximum(img, 0) * np.float32(1.0 / effects.full_well_e) + var
        img = img + np.sqrt(var) * rng.standard_normal(img.shape, dtype=np.float32)
    img = np.clip(img, 0.0, 1.0, out=img if img is not radiance else None)
    if effects.demosaic != "none":
        img = demosaiced(img, effects.demosaic)
    if response is not None and response.beyond_power_law:
        # full-scale light at the response's full scale, as locate's mapping reads it (vision.luminance)
        top_light = float(response.light_from_grey(np.array([1.0]))[0])
        img = response.grey_from_light(img * top_light).astype(np.float32)
    elif effects.response_curve == "srgb":
        img = srgb_from_linear(img)
    elif effects.gamma != 1.0:
        img = cv2.pow(img, 1.0 / effects.gamma)
    if effects.sharpen_amount > 0:
        soft = cv2.GaussianBlur(img, (0, 0), effects.sharpen_radius_px, borderType=cv2.BORDER_REFLECT)
        img = np.clip(img + np.float32(effects.sharpen_amount) * (img - soft), 0.0, 1.0)
    if effects.color and img.ndim == 2:
        img = img[..., None] * np.array(WOOD_TINT_BGR, np.float32)
    top = (1 << effects.bit_depth) - 1
    out: np.ndarray = np.rint(img * top).astype(np.uint8 if effects.bit_depth == 8 else np.uint16)
    if effects.jpeg_quality:
        ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, int(effects.jpeg_quality)])
        if not ok:
            raise RuntimeError("JPEG encoding failed")
        decoded = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
        if decoded is None:
            raise RuntimeError("JPEG decoding failed")
        out = decoded
    return out
