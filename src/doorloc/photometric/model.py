"""The camera's photometric model: how linear light on the sensor becomes stored grey levels, and what
the print and the optics add to a straight black-white edge.

Parameters (each 0 or 1 switches its effect off; :data:`PLAIN` is the plain model: linear response,
even blur, a perfect print):

- ``gamma``: power-law response, ``light = g ** gamma`` for the stored grey ``g`` in [0, 1];
- ``black_level``: the grey level zero light is stored at (a pedestal), fraction of full scale; the
  power law applies above it. The model check holds it at or below the dark squares its photographs store
  (:meth:`PhotometricModel.pedestal_over_darks_ln_grey`);
- ``shoulder``: the level (fraction of full scale, above the pedestal) where the response's shoulder starts
  compressing highlights towards full scale: above it ``g = W - (W - k) (1 - (x - k) / (p (W - k)))^p``
  (``x`` the power law's output, ``W`` the white level, below, ``p`` the ``shoulder_order``), which leaves
  the power law with its slope and reaches ``W`` with none at the finite light ``x = k + p (W - k)``, as a
  sensor's full well or a tone curve's roll-off does; 1 = no shoulder;
- ``shoulder_order``: ``p`` above, how the shoulder rolls off: 1 keeps the power law up to a hard
  saturation at ``W``, 2 (the default) a quadratic roll-off reaching ``W`` at twice the knee's headroom,
  larger orders spread the compression over more light and approach an exponential's ``1 - e^-u``.
  The model check frees it only once a soft saturation is named, and keeps it where the held-out offsets
  fall by more than a standard error (:data:`doorloc.photometric.catalogue.REFINED_FORMS`): on OpenCV's
  photographs it reads 2.5 +- 0.3 and lowers them from 0.079 to 0.067 px by edge direction, 1.9 standard
  errors (each photograph's median 0.064 -> 0.050 px): their highlights roll off over more light than a
  quadratic draws;
- ``white_level``: the stored grey level (fraction of full scale) the shoulder ends at, instead of full scale
  (a sensor's full well reached softly, or a tone curve whose knee ends below 255, as many cameras' do
  10-15 levels below it); levels at or above it carry no more highlight. 1 = full scale; a shoulder at or
  above it is a hard saturation at ``W``. Unlike ``clip_level`` it bends the response below the
  saturation, so edges whose bright level sits in the last part below it move too. (A shoulder that only
  approaches ``W`` as the light grows without bound, ``tanh``'s, was the first form: reading it back, the
  last levels below ``W`` stand for any light at all: on Bouguet's set one photograph's edges of one direction,
  held out, were read 1.15 px off through a shoulder fitted on the others, and the form lost to a toe; with
  the finite form both public sets' held-out offsets fall, OpenCV's 0.082 -> 0.064 px and Bouguet's 0.104 ->
  0.063 px, on 2026-11-29.);
- ``curvature``: toe/shoulder of the response beyond a power law, ``ln light = gamma ln g' + curvature (ln g')^2``
  (``g'`` the grey above the pedestal): a characteristic curve that bends in log-log as film's and many
  camera tone curves do;
- ``tone_1`` .. ``tone_6``: a tone curve no closed form above describes, measured free: ``ln light`` is
  raised by a piecewise-linear function of the stored grey through 0 at black and these values at the grey
  levels 1/6, 2/6, .. 1 (:data:`TONE_KNOTS`), as photometric calibration measures a response without
  assuming its form (Debevec and Malik's free response, Grossberg and Nayar's empirical curves). On Bouguet's
  photographs the closed forms leave each photograph's edges off by an amount that follows its exposure
  (correlation -0.86 with its dark level), which this curve takes from 0.063 to 0.023 px held out (2026-11-29);
  0 everywhere = no correction;
- ``clip_level``: the stored grey level (fraction of full scale) at which the sensor or its tone curve
  saturates: light beyond it is stored at this level, so an overexposed square's plateau is its clip and not
  its light; 1 = no clipping. It cannot be undone by a table: an edge whose bright square is clipped is placed
  from its unclipped samples (:mod:`doorloc.photometric.clipping`);
- ``clipped_blur_px``: the optics' blur (Gaussian sigma, px) such an edge is read with in a photograph whose
  squares are nearly all clipped (it has no edges of its own to measure the blur on): measured on the
  unclipped edges of the photographs the clip level was fitted on; 0 = the photograph's own edges';
- ``clipped_contrast``: the board's light squares' light over its dark squares' (linear light) such an edge's
  true step is read with in such a photograph: measured on the unclipped edges of the photographs the clip
  level was fitted on; 0 = the photograph's own edges';
- ``print_spread_mm``: the printed dark squares are larger than the board's geometry by this much on each
  side (toner or ink spread; negative: the light squares are larger), board millimetres;
- ``edge_shift_u_px``, ``edge_shift_v_px``: a point spread that is not point-symmetric (a one-sided smear
  along the lines of an analogue or rolling read-out, coma, a demosaicking lag) moves every edge by the
  projection of this vector (image px) on its normal, while the X-junctions, which see only the spread's
  symmetric part, stay nearer: the edges' displacement from the corners' frame;
- ``psf_tail``: fraction of the point spread's light in a wide halo (exponential, ``psf_tail_px`` scale)
  beside the Gaussian core;
- ``blur_field``: blur growing towards the image corners: the blur's variance grows by this much (px^2) from
  the image centre to its corner, in proportion to ``(r / r_corner)^2``;
- ``blur_anisotropy``: the blur's variance (px^2) added across vertical edges and taken off across
  horizontal ones (``cos 2 phi``, ``phi`` the edge normal's angle from the image u axis): astigmatism, or a
  sensor's or demosaicking's direction preference;
- ``field_offset_u_px``, ``field_offset_v_px``: an interlaced camera's two fields out of register: the even
  image rows (0, 2, ..) sample the scene half this vector (image px) further along it than the geometry
  puts them, the odd rows half of it back (a frame grabber's field timing, or the scene or camera moving
  between the two fields' exposures), the mean over the photographs; ``field_offset_scatter_px`` their RMS
  about it, per component (each photograph's own offset, as the check fitted it, varies: motion between
  fields is one photograph's). An edge along the rows then has profiles down the columns whose samples
  alternate between the fields (a point spread that alternates from row to row), an edge across them scan
  lines that alternate. The median over an edge's scan lines is not moved (as many of each field), the
  profiles are: a per-pixel misfit in proportion to the edge's slope. On Bouguet's photographs the even
  rows sample the scene 0.202 +- 0.004 px further down the columns than the odd rows (0.16-0.23 px on each
  of the 20, none across them: an interlaced camera's field registration, 2026-12-02);
- ``residual_edge_px``: what the model leaves unexplained on the camera's real edges, px: the RMS over
  photographs held out of their median edge offset from the board's corner lines, with the model
  (``doorloc check-model --boards``), or, where larger, the RMS of those medians taken by edge direction
  (their noise taken off): a door's edge faces one way, and a bias whose direction changes from photograph
  to photograph cancels in the median over all directions only; not an effect but the model's measured
  error, which locate counts in every edge's doubt. 0 = not measured;
- ``response_measured_to``: the level (fraction of full scale, above the pedestal) up to which the
  photographs the model was measured on read the response: where the brightest tenth of their edges' bright
  plateaus begins (their 90th percentile). A response the model finds a power law is not measured above it,
  so locate doubts a shoulder from there (:mod:`doorloc.vision.response_shoulder`), as it doubts one from
  ``locate.response_shoulder_knee`` in a camera nobody measured. 1 = up to full scale (also where a model
  file does not say).

Only the response, its clipping, the print and the spread's asymmetry move an edge placed in linear light; the others change its profile (and so
what an estimator that is not unbiased for them reports). Veiling glare (light scattered over the whole
image) adds the same light on both sides of an edge: in linear light it neither moves nor reshapes an edge,
so board edges cannot tell it from the black squares' own reflectance, and it is not a parameter here. The response maps are written here by hand because
no library models a camera response of this form; they are small closed forms.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace
from functools import cached_property

import numpy as np

__all__ = [
    "PhotometricModel",
    "PLAIN",
    "PARAMETER_UNITS",
    "CLIPPED_CONTRAST_MAX",
    "SHOULDER_ORDER_MAX",
    "TONE_KNOTS",
    "TONE_NAMES",
]

#: the largest board contrast (light over dark, linear light) a model file holds as ``clipped_contrast``: far
#: beyond any print's (a matt black and white print reflect about 1:20-1:50)
CLIPPED_CONTRAST_MAX = 1e4
#: the largest order of the shoulder's roll-off (``shoulder_order``): beyond it the curve is an exponential's
SHOULDER_ORDER_MAX = 8.0

#: the stored grey levels (fraction of full scale) where the free tone curve's values ``tone_1..6`` sit
TONE_KNOTS = np.arange(1, 7) / 6.0
#: the free tone curve's parameters, in the order of :data:`TONE_KNOTS`
TONE_NAMES = tuple(f"tone_{k}" for k in range(1, 7))
_TONE_GREY = np.concatenate([[0.0], TONE_KNOTS])  # the curve is 0 at black: it bends, it does not scale

#: each parameter's unit, for reports and files
PARAMETER_UNITS = {
    "gamma": "exponent",
    "black_level": "fraction of full scale",
    "shoulder": "fraction of full scale",
    "white_level": "fraction of full scale",
    "shoulder_order": "order",
    "curvature": "1/ln^2",
    "clip_level": "fraction of full scale",
    **dict.fromkeys(TONE_NAMES, "ln light"),
    "clipped_blur_px": "px",
    "clipped_contrast": "ratio of light",
    "print_spread_mm": "mm on the board",
    "edge_shift_u_px": "px",
    "edge_shift_v_px": "px",
    "psf_tail": "fraction of light",
    "psf_tail_px": "px",
    "blur_field": "px^2",
    "blur_anisotropy": "px^2",
    "field_offset_u_px": "px",
    "field_offset_v_px": "px",
    "field_offset_scatter_px": "px",
    "residual_edge_px": "px",
    "response_measured_to": "fraction of full scale",
}


@dataclass(frozen=True)
class PhotometricModel:
    """A camera's photometric model (module docstring); the defaults are the plain model."""

    gamma: float = 1.0
    black_level: float = 0.0
    shoulder: float = 1.0
    white_level: float = 1.0
    shoulder_order: float = 2.0
    curvature: float = 0.0
    tone_1: float = 0.0
    tone_2: float = 0.0
    tone_3: float = 0.0
    tone_4: float = 0.0
    tone_5: float = 0.0
    tone_6: float = 0.0
    clip_level: float = 1.0
    clipped_blur_px: float = 0.0
    clipped_contrast: float = 0.0
    print_spread_mm: float = 0.0
    edge_shift_u_px: float = 0.0
    edge_shift_v_px: float = 0.0
    psf_tail: float = 0.0
    psf_tail_px: float = 4.0
    blur_field: float = 0.0
    blur_anisotropy: float = 0.0
    field_offset_u_px: float = 0.0
    field_offset_v_px: float = 0.0
    field_offset_scatter_px: float = 0.0
    residual_edge_px: float = 0.0
    response_measured_to: float = 1.0

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if not np.isfinite(v):
                raise ValueError(f"photometric model: {f.name} must be a finite number, got {v}")
        if not 0.2 <= self.gamma <= 5.0:
            raise ValueError(f"photometric model: gamma {self.gamma} outside 0.2..5")
        if not -0.2 <= self.black_level < 0.5:
            raise ValueError(f"photometric model: black_level {self.black_level} outside -0.2..0.5")
        if not 0.05 <= self.shoulder <= 1.0:
            raise ValueError(f"photometric model: shoulder {self.shoulder} outside 0.05..1")
        if not 0.5 <= self.white_level <= 1.0:
            raise ValueError(f"photometric model: white_level {self.white_level} outside 0.5..1")
        if not 1.0 <= self.shoulder_order <= SHOULDER_ORDER_MAX:
            raise ValueError(
                f"photometric model: shoulder_order {self.shoulder_order} outside 1..{SHOULDER_ORDER_MAX:g}"
            )
        if not self.white_level > self.black_level + 0.05:
            raise ValueError("photometric model: white_level must lie above black_level")
        if any(not -3.0 <= v <= 3.0 for v in self.tone):
            raise ValueError(f"photometric model: tone values {self.tone} outside -3..3 (ln light)")
        if not 0.2 <= self.clip_level <= 1.0:
            raise ValueError(f"photometric model: clip_level {self.clip_level} outside 0.2..1")
        if not 0.0 <= self.clipped_blur_px <= 10.0:
            raise ValueError(f"photometric model: clipped_blur_px {self.clipped_blur_px} outside 0..10")
        if not (self.clipped_contrast == 0.0 or 1.0 < self.clipped_contrast <= CLIPPED_CONTRAST_MAX):
            raise ValueError(
                f"photometric model: clipped_contrast {self.clipped_contrast} is 0 (unset) or a ratio in "
                f"1..{CLIPPED_CONTRAST_MAX:g}"
            )
        if not 0.0 <= self.psf_tail < 1.0:
            raise ValueError("photometric model: psf_tail is a fraction in [0, 1)")
        if not self.psf_tail_px > 0:
            raise ValueError("photometric model: psf_tail_px must be positive")
        if not (abs(self.field_offset_u_px) <= 2.0 and abs(self.field_offset_v_px) <= 2.0):
            raise ValueError("photometric model: a field offset's components lie within -2..2 px")
        if not 0.0 <= self.field_offset_scatter_px <= 2.0:
            raise ValueError(
                f"photometric model: field_offset_scatter_px {self.field_offset_scatter_px} outside 0..2 px"
            )
        if not 0.0 <= self.residual_edge_px <= 5.0:
            raise ValueError(f"photometric model: residual_edge_px {self.residual_edge_px} outside 0..5 px")
        if not 0.05 <= self.response_measured_to <= 1.0:
            raise ValueError(
                f"photometric model: response_measured_to {self.response_measured_to} outside 0.05..1"
            )

    @property
    def interlaced(self) -> bool:
        """True where the model's camera has interlaced fields out of register (a mean offset or a scatter)."""
        return bool(self.field_offset_u_px or self.field_offset_v_px or self.field_offset_scatter_px)

    @property
    def is_plain(self) -> bool:
        return self == PLAIN

    @property
    def linear_response(self) -> bool:
        """True where stored grey is proportional to light above zero (no table is needed to read it), up to
        the clip level where there is one."""
        return (
            self.gamma == 1
            and self.black_level == 0
            and self.curvature == 0
            and self.shoulder == 1
            and self.white_level == 1
            and not self.has_tone
        )

    @property
    def tone(self) -> tuple[float, ...]:
        """The free tone curve's values at :data:`TONE_KNOTS` (ln light)."""
        return tuple(getattr(self, n) for n in TONE_NAMES)

    @property
    def has_tone(self) -> bool:
        return any(v != 0.0 for v in self.tone)

    def to_dict(self) -> dict[str, float]:
        return {k: float(v) for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, d: dict) -> PhotometricModel:
        """Read the parameters of a file's ``photometric_model`` mapping; unknown keys are errors."""
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - names)
        if unknown:
            raise ValueError(
                f"photometric model: unknown parameter(s) {', '.join(unknown)}; known: {', '.join(sorted(names))}"
            )
        try:
            return cls(**{k: float(v) for k, v in d.items()})
        except (TypeError, ValueError) as e:
            raise ValueError(f"photometric model: {e}") from None

    def with_values(self, **values: float) -> PhotometricModel:
        return replace(self, **values)

    # --- response -------------------------------------------------------------------------------------
    def light_from_grey(self, g: np.ndarray) -> np.ndarray:
        """Relative linear light (0 at zero light, 1 at full scale) from stored grey ``g`` in [0, 1]."""
        g = np.asarray(g, float)
        gp = np.clip((g - self.black_level) / (1.0 - self.black_level), 1e-6, None)
        # the white level on the power law's scale (above the pedestal); a knee above it is a hard saturation
        w = (self.white_level - self.black_level) / (1.0 - self.black_level)
        k = min(self.shoulder, w)
        if k < w:
            # undo the shoulder: the white level (and any level above it) is the light k + p (w - k)
            p = self.shoulder_order
            q = np.clip((w - gp) / (w - k), 0.0, 1.0)
            root = np.sqrt(q) if p == 2.0 else q ** (1.0 / p)  # (the quadratic's, as it always was)
            gp = np.where(gp > k, k + p * (w - k) * (1.0 - root), gp)
        elif w < 1.0:
            gp = np.minimum(gp, w)
        lg = np.log(gp)
        if self.curvature != 0.0:
            # the log-log parabola turns back where gamma + 2 curvature ln g' = 0: a response never falls,
            # so the curve is held flat beyond that level (dark end for curvature > 0, bright end below 0)
            turn = -self.gamma / (2.0 * self.curvature)
            lg = np.maximum(lg, turn) if self.curvature > 0 else np.minimum(lg, turn)
        ln_light = self.gamma * lg + self.curvature * lg * lg
        if self.has_tone:
            ln_light = ln_light + np.interp(g, _TONE_GREY, np.concatenate([[0.0], self.tone]))
        return np.exp(ln_light) * (g > self.black_level)

    def flat_response_ln_grey(self) -> float:
        """How far above the lowest stored level (1/255 of full scale over the pedestal)
        :meth:`light_from_grey` holds the response flat, in ln of the grey level: a curvature > 0 turns the
        log-log parabola back at ``ln g' = -gamma / (2 curvature)``. 0 where the response rises over every
        stored level, as a camera's does (a fit whose response ends flat over the darker levels has taken
        darks stored at 0, or a bend that no edge's levels reach, for the camera's response)."""
        if self.curvature <= 0.0:
            return 0.0
        return max(0.0, math.log(255.0) - self.gamma / (2.0 * self.curvature))

    def pedestal_over_darks_ln_grey(self, darkest_plateau: float) -> float:
        """How far the pedestal (``black_level``, which :meth:`light_from_grey` reads as no light) lies above
        ``darkest_plateau``, the darkest level (fraction of full scale) a camera's photographs store on their
        dark squares (at least the lowest stored level, 1/255), in ln of the grey level; 0 where it lies at
        or below. A pedestal above stored plateaus reads a dark square as no light at all and cannot draw it
        (Bouguet's toe, fitted to the edges' places, put it at 36 grey while a twentieth of its dark squares
        lie at or below 32: their profiles were drawn at 36)."""
        floor = max(darkest_plateau, 1.0 / 255.0)
        return max(0.0, math.log(max(self.black_level, floor) / floor))

    @property
    def clips(self) -> bool:
        """True where the sensor saturates below full scale (``clip_level`` < 1)."""
        return self.clip_level < 1.0

    def grey_from_light(self, light: np.ndarray) -> np.ndarray:
        """Stored grey in [0, 1] from relative linear light (inverse of :meth:`light_from_grey`, tabulated),
        held at the clip level."""
        L, g = self.response_table()
        grey = np.interp(np.clip(np.asarray(light, float), 0.0, None), L, g)
        return np.minimum(grey, self.clip_level) if self.clips else grey

    def response_table(self, n: int = 4097) -> tuple[np.ndarray, np.ndarray]:
        """``(light, grey)`` at ``n`` grey levels in [0, 1], where the light rises (all of it for sane curves)."""
        g = np.linspace(0.0, 1.0, n)
        L = self.light_from_grey(g)
        ok = np.concatenate([[True], np.diff(L) > 0])
        return L[ok], g[ok]

    @property
    def beyond_power_law(self) -> bool:
        """True where the response has a part no power law describes (a pedestal, a shoulder, a white level
        below full scale, curvature in log-log): what a cell's ``response_gamma`` alone cannot carry."""
        return not (
            self.black_level == 0.0
            and self.shoulder == 1.0
            and self.white_level == 1.0
            and self.curvature == 0.0
            and not self.has_tone
        )

    @property
    def moves_edges(self) -> bool:
        """True where the point spread's asymmetry moves every edge against the corners' frame
        (``edge_shift_u_px``, ``edge_shift_v_px``): the calibration's geometry, made from corners, then
        places edges by that much off."""
        return self.edge_shift_u_px != 0.0 or self.edge_shift_v_px != 0.0

    @property
    def used_by_locate(self) -> bool:
        """True where the model says something locate uses: a response beyond a power law, a clip below full
        scale, edges moved by the point spread's asymmetry, or its measured error on real edges."""
        return self.beyond_power_law or self.clips or self.moves_edges or self.residual_edge_px > 0

    def locate_parameters(self) -> dict[str, float]:
        """What locate takes of the model (the response and its clip, the edges' shift and the residual on real
        edges), as files and results name them."""
        return {
            k: float(getattr(self, k))
            for k in (
                "gamma",
                "black_level",
                "shoulder",
                "white_level",
                "shoulder_order",
                "curvature",
                *TONE_NAMES,
                "clip_level",
                "edge_shift_u_px",
                "edge_shift_v_px",
                "residual_edge_px",
                "response_measured_to",
            )
        }

    def power_law_levels(self, gamma: float, top_in: int) -> np.ndarray:
        """Each stored level ``0..top_in`` as the level a camera of the power law ``grey = light ** (1 /
        gamma)`` would store for the same light, on ``0..65535`` (uint16; full scale where this response's
        full scale lies): ``65535 (L(g) / L(1)) ** (1 / gamma)``, ``L`` :meth:`light_from_grey`. Through
        it, a pipeline that linearises with the power law ``gamma`` reads this camera's light."""
        g = np.arange(top_in + 1, dtype=np.float64) / top_in
        light = self.light_from_grey(g)
        top_light = float(light[-1])
        if not top_light > 0.0:
            raise ValueError("photometric model: the response stores no light at full scale")
        v = np.clip(light / top_light, 0.0, 1.0) ** (1.0 / gamma)
        return np.rint(v * 65535.0).astype(np.uint16)

    def linearizing_lut(self, top: int = 255) -> np.ndarray:
        """Table from each stored level (0..top) to linear light on the same scale (float32, read-only), for
        :func:`doorloc.vision.edges.subpixel_edges`'s ``lut``."""
        return self._lut_8bit if top == 255 else self._lut(top)

    @cached_property
    def _lut_8bit(self) -> np.ndarray:
        # made once per model: a fit places every photograph's edges with each model it tries
        return self._lut(255)

    def _lut(self, top: int) -> np.ndarray:
        table = (self.light_from_grey(np.arange(top + 1) / top) * top).astype(np.float32)
        table.flags.writeable = False  # (the 8-bit table is shared by every caller)
        return table


PLAIN = PhotometricModel()
