"""The catalogue of photometric causes: what each frees in the :class:`~doorloc.photometric.model.PhotometricModel`
and the signature by which the board's edges tell it from the others.

Two kinds. **Edge-moving** causes shift an edge that the area estimator places (the estimator is exact for
any blur of a step in linear light, so only a response that is not affine, or a print whose squares are not
the board's geometry, moves it): they are fitted to the edges' offsets from the corner lines and selected by
held-out photographs. **Profile** causes change an edge's shape but not where an estimator in linear light
puts it: they are read from the edges' profiles and blurs (:mod:`doorloc.photometric.profiles`).

Signatures of the edge-moving causes, on the signed offset (+ towards the bright side):

- ``response_gamma``: a power-law response read as linear moves every edge towards the dark side by a length
  proportional to its blur and growing with its contrast ratio;
- ``response_toe``: a pedestal under the power law (black level): the dark side's level matters more than the
  ratio alone says, so dim, low-contrast edges move differently from bright ones at the same ratio;
- ``response_shoulder``: highlights compressed near full scale: only edges whose bright level comes near
  saturation move (towards the dark side), the more the nearer;
- ``response_curvature``: a toe or shoulder bending the log-log response: edges move by an amount that depends
  on where on the grey scale both levels sit, not on their ratio only;
- ``sensor_clipping``: the sensor or tone curve saturates below an overexposed square's light: only edges
  whose bright square reaches the clip level (a plateau piled at that level, a profile that flattens early)
  move, towards the dark side, by an amount growing with how far the square's light lies beyond the clip;
  not with the edge's direction or the board's scale;
- ``soft_saturation``: a shoulder that rolls off to its own white level below full scale, reached at a finite
  light (a full well reached softly, a tone curve's knee ending 10-15 levels below 255): edges whose bright
  level lies in the shoulder move towards the dark side, more the nearer it is to the white level, and no
  stored level lies above it; unlike a clip, the levels below the white level are bent too, so edges whose
  bright square stays under it move as well; once it is named, the order of its roll-off is freed too
  (:data:`REFINED_FORMS`: how much light the shoulder spreads its compression over);
- ``psf_asymmetry``: a fixed image vector projected on each edge's normal: opposite edges of one square move
  opposite ways, so the offset depends on the edge's direction, not on its blur, levels or scale;
- ``print_spread``: a fixed length on the board, so an offset proportional to the board's scale (px per mm)
  and independent of the blur.

One more edge-moving cause is tried last, after the closed forms (:data:`TONE_CAUSE`):

- ``response_tone``: a tone curve that no closed form above describes, free at six grey levels: edges move by
  an amount that follows where their levels sit on the grey scale in any smooth way (photographs of one
  exposure alike, brighter ones otherwise). Six parameters fit much: it is tried only once no closed form
  lowers the held-out offsets any more, and kept on a stricter gain (:data:`TONE_KEEP_SIGMAS`), so that an
  effect a closed form names is named by it. Its values are fitted to each photograph's median offset, the
  closed forms' held at their fit (:attr:`Cause.on_medians`): a response moves the edges of every direction
  alike, and on Bouguet's photographs each edge's offset also carries a bias by direction (+-0.3 px from one
  photograph to the next) that no cause explains, which a fit to the edges follows instead (held out, the
  tone fitted to the edges left the photographs' medians at 0.047 px, fitted to the medians at 0.023 px).
  One number per photograph: it is tried where there are twice as many photographs as its parameters.
"""

from __future__ import annotations

from dataclasses import dataclass

from scipy.stats import norm

from doorloc.photometric.model import SHOULDER_ORDER_MAX, TONE_NAMES

__all__ = [
    "Cause",
    "EDGE_CAUSES",
    "TONE_CAUSE",
    "TONE_KEEP_SIGMAS",
    "PROFILE_CAUSES",
    "CAUSES_BY_NAME",
    "CATALOGUE_NAMES",
    "REFINED_FORMS",
    "REFINE_KEEP_SIGMAS",
    "KEEP_SIGMAS",
    "keep_sigmas",
]

#: a single cause is kept when its held-out gain exceeds this many of its standard errors
KEEP_SIGMAS = 2.0


def keep_sigmas(n_compared: int) -> float:
    """Standard errors a held-out gain must exceed when ``n_compared`` causes are tried at once: the best of
    several candidates passes a fixed threshold by chance more often than one does, so the threshold is
    raised until the chance that any of them passes on noise alone is that of one cause at
    :data:`KEEP_SIGMAS` (Bonferroni; 2.0 for one, 2.40 for three, 2.77 for eight)."""
    return float(norm.isf(norm.sf(KEEP_SIGMAS) / max(1, int(n_compared))))


@dataclass(frozen=True)
class Cause:
    """One catalogue entry: its name, the model parameters it frees (with start values and bounds) and its
    signature in plain words."""

    name: str
    parameters: tuple[str, ...]
    start: tuple[float, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    signature: str
    moves_edges: bool = True
    #: fitted to each photograph's median offset over all its edges (with the other causes' values held), not
    #: to each edge's: for a cause that moves the edges of every direction alike, where the edges carry a bias
    #: by direction that no cause explains
    on_medians: bool = False


EDGE_CAUSES: tuple[Cause, ...] = (
    Cause(
        "response_gamma",
        ("gamma",),
        (1.4,),
        (0.3,),
        (4.0,),
        "edges move towards the dark side in proportion to their blur, more at high contrast ratio",
    ),
    Cause(
        "response_toe",
        ("gamma", "black_level"),
        (1.4, 0.02),
        (0.3, -0.15),
        (4.0, 0.4),
        "a pedestal (black level) under a power-law response: dim edges move unlike bright ones of equal ratio",
    ),
    Cause(
        "response_shoulder",
        ("shoulder",),
        (0.8,),
        (0.05,),
        (1.0,),
        "highlights compressed near full scale: edges with a bright level near saturation move towards the dark side",
    ),
    Cause(
        "response_curvature",
        ("gamma", "curvature"),
        (1.4, 0.0),
        (0.3, -1.5),
        (4.0, 1.5),
        "a toe or shoulder beyond a power law: the move depends on where both levels sit on the grey scale",
    ),
    Cause(
        "sensor_clipping",
        ("clip_level",),
        (0.95,),
        (0.2,),
        (1.0,),
        "overexposed squares stored at a clip level: only edges whose bright plateau sits at that level move, "
        "towards the dark side, the more the further the light lies beyond the clip; not with direction or scale",
    ),
    Cause(
        "soft_saturation",
        ("shoulder", "white_level"),
        (0.8, 0.97),
        (0.05, 0.6),
        (1.0, 1.0),
        "highlights rolled off to a white level below full scale, reached at a finite light: edges whose bright "
        "level lies in the shoulder move towards the dark side, the more the nearer to the white level",
    ),
    Cause(
        "psf_asymmetry",
        ("edge_shift_u_px", "edge_shift_v_px"),
        (0.0, 0.0),
        (-1.0, -1.0),
        (1.0, 1.0),
        "edges move by a fixed image vector projected on their normal: opposite edges of a square move "
        "opposite ways (a point spread that is not point-symmetric)",
    ),
    Cause(
        "print_spread",
        ("print_spread_mm",),
        (0.0,),
        (-2.0,),
        (2.0,),
        "a fixed length on the board (toner or ink spread): offset proportional to px per mm, not to blur",
    ),
)

#: richer forms of named causes: once the selection has named a cause, its richer form (the same name, more
#: parameters free) is tried in its place and kept where it lowers the held-out offsets by more than
#: ``REFINE_KEEP_SIGMAS`` standard errors. The selection itself compares the simple forms, so that a richer
#: one cannot take the name of an effect a simpler cause draws (a soft saturation whose order is free draws
#: a shoulder at full scale as well as ``response_shoulder`` does, and had taken its name on six rendered
#: photographs, 0.0041 against 0.0042 px held out).
REFINED_FORMS: dict[str, Cause] = {
    "soft_saturation": Cause(
        "soft_saturation",
        ("shoulder", "white_level", "shoulder_order"),
        (0.8, 0.97, 2.0),
        (0.05, 0.6, 1.0),
        (1.0, 1.0, SHOULDER_ORDER_MAX),
        "highlights rolled off to a white level below full scale, reached at a finite light, over a range of "
        "light the roll-off's order sets",
    ),
}

#: a richer form of a cause already named is kept where it lowers the held-out offsets by more than this many
#: standard errors: cross-validation's one-standard-error rule between nested forms (Hastie, Tibshirani and
#: Friedman, The Elements of Statistical Learning, 7.10). It names nothing new, so it needs no guard against a
#: control's luck (``KEEP_SIGMAS`` and :func:`keep_sigmas` do, for naming a cause)
REFINE_KEEP_SIGMAS = 1.0

#: the free tone curve, tried after the closed forms (module docstring)
TONE_CAUSE = Cause(
    "response_tone",
    TONE_NAMES,
    (0.0,) * len(TONE_NAMES),
    (-1.5,) * len(TONE_NAMES),
    (1.5,) * len(TONE_NAMES),
    "a tone curve beyond the closed forms: edges move by an amount that follows where both levels sit on the "
    "grey scale, in a way no power law, toe, shoulder or curvature draws",
    on_medians=True,
)

#: the free tone curve is kept when its held-out gain exceeds this many of its standard errors: the threshold of
#: the whole edge catalogue tried at once (it can mimic any one of the closed forms a little)
TONE_KEEP_SIGMAS = keep_sigmas(len(EDGE_CAUSES) + 1)

PROFILE_CAUSES: tuple[Cause, ...] = (
    Cause(
        "blur_field",
        ("blur_field",),
        (0.0,),
        (-5.0,),
        (5.0,),
        "blur changes from the image centre to its corners",
        False,
    ),
    Cause(
        "blur_anisotropy",
        ("blur_anisotropy",),
        (0.0,),
        (-5.0,),
        (5.0,),
        "edges of one direction are blurrier than the others (astigmatism, demosaicking)",
        False,
    ),
    Cause(
        "psf_tail",
        ("psf_tail",),
        (0.0,),
        (0.0,),
        (0.9,),
        "the levels approach their plateaus slowly: a halo beside the Gaussian core of the point spread",
        False,
    ),
    Cause(
        "interlaced_fields",
        ("field_offset_u_px", "field_offset_v_px", "field_offset_scatter_px"),
        (0.0, 0.0, 0.0),
        (-2.0, -2.0, 0.0),
        (2.0, 2.0, 2.0),
        "an interlaced camera's two fields out of register: the even rows sample the scene displaced from the "
        "odd rows', so edges along the rows have profiles that alternate from row to row and edges across them "
        "alternate from scan line to scan line, by the edge's slope times the offset; the edges' medians stay",
        False,
    ),
)

CAUSES_BY_NAME = {c.name: c for c in (*EDGE_CAUSES, TONE_CAUSE, *PROFILE_CAUSES)}
CATALOGUE_NAMES = tuple(CAUSES_BY_NAME)
