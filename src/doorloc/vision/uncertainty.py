"""The 1-sigma standard uncertainty of a located pose: fit noise + edge model + calibrations.

Every ``ok`` answer carries ``uncertainty: {x_mm, z_mm, yaw_deg}``, the quadrature sum of independent
terms (each also reported in ``diagnostics["uncertainty_terms"]``), all of it computed in one place,
:func:`propagate`, which also gives the thickness's sigma and each source's share of both
(``diagnostics["uncertainty_budget"]``: a list of ``{source, x_mm, z_mm, yaw_deg, thickness_mm}``, each the
source's 1-sigma contribution, so that the dominant term can be read off):

``fit``
    The joint line fit's standard errors from the residual scatter (image noise). The corner lies away
    from the centroid of the points that fix each line, so the angle's error moves it too: x and z take
    ``angle_sigma * lever`` in quadrature with the line's offset error.
``edge_model``
    What averaging over many scan lines does not remove, because it is the same on every scan line: the
    difference between the edge model and the real edge. Per line, the quadrature sum of

    - ``EDGE_MODEL_FLOOR_PX``: the area estimator's own residual bias on a clean, sharp step (sampled
      pixel phases, quantisation; the committed noise-free grid fixtures show 0.0004 mm RMS = 0.002 px);
    - ``BLUR_MODEL_FRACTION`` of the measured optical blur (Gaussian sigma, px): on blurred, noise-free
      rendered steps the edge sits 0.005-0.01 px outwards per px of blur (0.001-0.0035 mm at blur
      0.5-1.8 px), the same before and after the plateaus moved next to the window; a real lens's
      blur is not Gaussian nor the same across the edge, so this is kept as a doubt, not corrected;
    - the texture term, :func:`doorloc.vision.texture.texture_bias` (wood grain along the edge, measured
      on the texture beside the window);
    - :func:`jpeg_edge_doubt_px` where the image came from a JPEG file or shows JPEG block artifacts
      (:func:`doorloc.vision.jpeg_blocks.block_artifact_ratio` above ``JPEG_BLOCK_RATIO``), at the file's
      quality where it is known (:func:`jpeg_edge_grey_dn`): the block
      quantization moves an edge that runs along a block row or column the same way on every scan line
      (0.01-0.07 px measured on nearly noise-free quality-88 renders, where no other term sees it; more
      on an edge of little contrast), and
      an edge at a small angle to the blocks by an amount that drifts along it: its tilt
      (:func:`jpeg_tilt_sigma`, and :func:`jpeg_drift_tilt` where the edge keeps nearly one pixel phase
      and its error follows the grey levels beside it) joins the line's texture tilt in the yaw;
    - whatever term an edge model or a correction knows of its own line, contributed as a typed
      :class:`LineDoubt` (source, line, offset and tilt, correlation group): the far-face fit, the arris
      correction, the camera response (one correlation group: a camera exponent moves both arrises
      alike), the camera's optics (one group too: what its photometric model leaves on real edges, or,
      where it has none, ``LocateConfig.optics_edge_sigma_px``). The texture and JPEG terms above are such
      doubts too.

    The line's total is reported as ``lines[i].model_sigma_mm``.
``calibration``
    The camera calibration's own uncertainty, propagated to x, z, yaw at the located corner through the
    projection's Jacobian (rotation-aligned, as ``doorloc calibrate`` reports it: the cell check's camera
    placement takes up what a rotation explains) and the back-projection's
    (:class:`doorloc.vision.metric.PlaneMap`), with the intrinsics' covariance saved in the calibration
    file (``intrinsics_covariance``). A cell whose
    camera carries no covariance (an inline camera matrix, an older calibration file) gets the default
    floor ``LocateConfig.calibration_sigma_px``: an isotropic projection error of that 1-sigma at the
    corner, and for the yaw a smooth error field that changes by ``sqrt(2)`` times it over half the
    image diagonal. Set it to 0 only for a camera known exactly (rendered images).
``cell``
    The camera's placement in the cell (the extrinsics, from the cell check): ``LocateConfig.cell_sigma_mm``
    and ``cell_sigma_deg``, as that check measured them (0 by default: a cell file says what its check found).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import numpy as np

from doorloc.calib.calibrate import Candidate, free_param_names, projection_jacobian
from doorloc.calib.camera import CameraModel, PosedCamera
from doorloc.vision.metric import PlaneMap

__all__ = [
    "BLUR_MODEL_FRACTION",
    "EDGE_MODEL_FLOOR_PX",
    "JPEG_BLOCK_RATIO",
    "JPEG_EDGE_DOUBT_PX",
    "JPEG_EDGE_GREY_DN",
    "JPEG_EDGE_GREY_DN_BY_QUALITY",
    "JPEG_DRIFT_TILT",
    "JPEG_DRIFT_SWEEP_PX",
    "CAMERA_RESPONSE",
    "DOUBT_SOURCES",
    "EdgeModelTerms",
    "Budget",
    "BudgetTerm",
    "LineDoubt",
    "LineLever",
    "propagate",
    "calibration_pose_sigma",
    "combine",
    "corner_fit_sigma",
    "jpeg_edge_doubt_px",
    "jpeg_edge_grey_dn",
    "jpeg_drift_tilt",
    "jpeg_tilt_sigma",
]

#: the area estimator's residual bias on a clean step, px across the edge (module docstring)
EDGE_MODEL_FLOOR_PX = 0.002

#: JPEG block artifacts: the ratio above which an image counts as JPEG-compressed, and the doubt then (px):
#: at least ``JPEG_EDGE_DOUBT_PX``, and ``JPEG_EDGE_GREY_DN`` grey levels over the edge's step (:func:`jpeg_edge_doubt_px`)
JPEG_BLOCK_RATIO = 1.3
JPEG_EDGE_DOUBT_PX = 0.03
JPEG_EDGE_GREY_DN = 2.5
#: the grey levels of that doubt by the file's libjpeg quality (:func:`jpeg_edge_grey_dn`): blurred steps
#: (blur 0.3-1.2 px, steps 20-160, slopes 0-0.05) read by the area estimator, each 8-row block's mean error
#: against the same image unquantised, times the step; the 90th percentile over 120 edges per quality
#: (two draws), made to fall with the quality. Under 75 the flat blocks' own DC error joins (5-7 at 50-70).
JPEG_EDGE_GREY_DN_BY_QUALITY = (
    (30, 12.0),
    (40, 11.0),
    (70, 7.3),
    (75, 3.2),
    (80, JPEG_EDGE_GREY_DN),
    (85, 2.1),
    (88, 2.0),
    (90, 1.9),
    (92, 1.5),
    (95, 1.0),
    (98, 0.31),
    (100, 0.24),
)
#: offset doubts of tilt over a line's length that JPEG gives an edge at nearly one pixel phase, and the
#: phase sweep (px along the line) by which that drift has gone (:func:`jpeg_drift_tilt`)
JPEG_DRIFT_TILT = 3.0
JPEG_DRIFT_SWEEP_PX = 2.0

#: edge-model doubt per px of optical blur (module docstring)
BLUR_MODEL_FRACTION = 0.01

#: OpenCV's order of the distortion coefficients (calibration covariance names)
_DIST_INDEX = {
    "k1": 0,
    "k2": 1,
    "p1": 2,
    "p2": 3,
    "k3": 4,
    "k4": 5,
    "k5": 6,
    "k6": 7,
    "s1": 8,
    "s2": 9,
    "s3": 10,
    "s4": 11,
}


#: the edge-model doubts a line can carry besides the floor and the blur term, in the order a line's total
#: adds them (the order fixes the last bits of the sums)
DOUBT_SOURCES = (
    "texture",
    "far_face",
    "jpeg",
    "quantisation",
    "arris",
    "response",
    "camera",
    "optics",
    "direction",
)

#: the lines a doubt can move
EDGE_LINES = ("bottom", "reference", "far")

#: the correlation group of the camera-response doubts: one camera exponent moves every edge the same way
#: (both arrises outwards or both inwards), so their doubts add linearly where one figure takes both
CAMERA_RESPONSE = "camera_response"


@dataclass(frozen=True)
class LineDoubt:
    """One named 1-sigma doubt of one edge line, contributed by the code that knows it.

    Attributes
    ----------
    source : str
        What it comes from, one of :data:`DOUBT_SOURCES` (``"texture"``: grain beside the edge; ``"far_face"``:
        the far-face model; ``"jpeg"``: block quantisation; ``"quantisation"``: grey-level rounding that no
        noise dithers (:mod:`doorloc.vision.quantisation`); ``"arris"``: the arris correction;
        ``"response"``: the camera response; ``"camera"``: what the camera's photometric model leaves
        unexplained on real edges; ``"optics"``: what an unmeasured camera's optics may move its edges by,
        ``LocateConfig.optics_edge_sigma_px``; ``"direction"``: the lines' own directions disagreeing beyond
        their doubts, :func:`doorloc.vision.direction_vote.direction_spread`).
    line : str
        The line it moves: ``"bottom"``, ``"reference"`` or ``"far"``.
    offset_px : float
        1-sigma of the line's place across the edge, px (the same on every scan line of it).
    tilt : float
        1-sigma of the line's direction, px across per px along (0 where the doubt does not tilt it).
    group : str or None
        Correlation group: doubts of one group on different lines share their cause and add linearly in a
        figure both lines make (the thickness); None for a doubt independent of every other.
    """

    source: str
    line: str
    offset_px: float = 0.0
    tilt: float = 0.0
    group: str | None = None


def _finite(v: float) -> float:
    return v if math.isfinite(v) else 0.0


@dataclass(frozen=True)
class EdgeModelTerms:
    """Edge-model doubts of the lines (the ``edge_model`` term of the module docstring): the floor and the
    blur term every line carries, and the :class:`LineDoubt` s the edge models and detectors contribute.

    Attributes
    ----------
    doubts : tuple of LineDoubt
        At most one per source and line.
    blur_px : float
        Optical blur (Gaussian sigma, px) measured on the image, for the blur term.
    """

    doubts: tuple[LineDoubt, ...] = ()
    blur_px: float = 0.0

    def with_doubts(self, *more: LineDoubt) -> EdgeModelTerms:
        """These terms and ``more``."""
        return EdgeModelTerms(self.doubts + more, self.blur_px)

    @functools.cached_property
    def _in_order(self) -> tuple[LineDoubt, ...]:
        """The doubts in the order of :data:`DOUBT_SOURCES` (sorted once: the budget asks many times)."""
        return tuple(sorted(self.doubts, key=lambda d: DOUBT_SOURCES.index(d.source)))

    @functools.cached_property
    def _by_line(self) -> dict[str, tuple[LineDoubt, ...]]:
        """Each line's doubts in the order of :data:`DOUBT_SOURCES`."""
        return {k: tuple(d for d in self._in_order if d.line == k) for k in EDGE_LINES}

    def of_line(self, line: str, without: tuple[str, ...] = ()) -> list[LineDoubt]:
        """The doubts of one line in the order of :data:`DOUBT_SOURCES`, the sources in ``without`` left out."""
        mine = self._by_line.get(line, ())
        return [d for d in mine if d.source not in without] if without else list(mine)

    def offset_px(self, line: str, source: str) -> float | None:
        """One doubt's offset 1-sigma, px; None where the line carries none from ``source``."""
        return next((d.offset_px for d in self.doubts if d.line == line and d.source == source), None)

    def line_sigma_px(self, line: str, without: tuple[str, ...] = ()) -> float:
        """Total edge-model 1-sigma of one line's offset, px (floor, blur and the line's doubts in quadrature),
        the sources named in ``without`` left out (a caller that combines them otherwise)."""
        blur = BLUR_MODEL_FRACTION * self.blur_px if math.isfinite(self.blur_px) else 0.0
        terms = [EDGE_MODEL_FLOOR_PX, blur, *(d.offset_px for d in self.of_line(line, without))]
        return math.sqrt(sum(v * v for v in terms if math.isfinite(v)))

    def tilt(self, line: str) -> float:
        """1-sigma of one line's direction from its doubts, px per px, in quadrature (non-finite ones as 0)."""
        t = 0.0
        for d in self.of_line(line):
            t = math.hypot(t, _finite(d.tilt))
        return t


def jpeg_edge_grey_dn(quality: int | None = None) -> float:
    """The grey levels (0-255 scale) by which JPEG's quantisation moves an edge, at the file's libjpeg
    ``quality`` (``JPEG_EDGE_GREY_DN_BY_QUALITY``, linear between its qualities; under 30 growing as
    libjpeg's table scale, 30 / quality); quality 80's (``JPEG_EDGE_GREY_DN``) where the quality is not
    known (None or 0: an image whose file was not seen, that shows JPEG's blocks).

    Examples
    --------
    >>> jpeg_edge_grey_dn() == jpeg_edge_grey_dn(80) == JPEG_EDGE_GREY_DN
    True
    >>> jpeg_edge_grey_dn(95), jpeg_edge_grey_dn(15)
    (1.0, 24.0)
    """
    if not quality:
        return JPEG_EDGE_GREY_DN
    q, dn = zip(*JPEG_EDGE_GREY_DN_BY_QUALITY, strict=True)
    if quality < q[0]:
        return dn[0] * q[0] / quality
    return float(np.interp(quality, q, dn))


def jpeg_edge_doubt_px(step_dn: float, grey_dn: float = JPEG_EDGE_GREY_DN) -> float:
    """1-sigma (px) of the offset JPEG's quantisation gives an edge whose grey-level step is ``step_dn``
    (0-255 scale): ``grey_dn / |step_dn|`` (:func:`jpeg_edge_grey_dn`: quality 80's unless the file's
    quality is known), at least ``JPEG_EDGE_DOUBT_PX`` (that alone where the step is unknown).

    Why: the quantisation moves each pixel's grey level by an amount that does not depend on the edge's
    contrast, so the edge moves by that over the edge's slope: a blurred step read by the area estimator,
    JPEG against the same image unquantised, each 8-row block's mean error (what a line fit keeps of it),
    90th percentile over the edge's phase in its block, blur 0.3-1.2 px and steps 20-160: 2.5 grey levels
    at quality 80, 2.0 at 88, 1.0 at 95, 3.2 at 75. A dark door on a dark background (step 10-20) is off
    0.1-0.2 px where the floor allowed 0.03.

    Examples
    --------
    >>> jpeg_edge_doubt_px(200.0) == JPEG_EDGE_DOUBT_PX
    True
    >>> round(jpeg_edge_doubt_px(-10.0), 3)
    0.25
    >>> round(jpeg_edge_doubt_px(-10.0, jpeg_edge_grey_dn(95)), 3)
    0.1
    """
    step = abs(step_dn)
    if not (math.isfinite(step) and step > 0):
        return JPEG_EDGE_DOUBT_PX
    return max(JPEG_EDGE_DOUBT_PX, grey_dn / step)


def _periodic_tilt(doubt_px: float, period_px: float, slope: float, d: np.ndarray, dd: float) -> float:
    """RMS over the phase of the least-squares slope (over ``d``, scan lines from their mean) of an edge
    error of RMS ``doubt_px`` that is a sinusoid of the edge's position with period ``period_px``."""
    k = 2.0 * math.pi * abs(slope) / period_px
    if k == 0.0:
        return 0.0
    return doubt_px * math.hypot(float(d @ np.sin(k * d)), float(d @ np.cos(k * d))) / dd


def jpeg_tilt_sigma(slope: float, scan_px: np.ndarray, doubt_px: float = JPEG_EDGE_DOUBT_PX) -> float:
    """1-sigma of a line's tilt (px per px) that JPEG's block quantisation gives it.

    The quantisation's edge error, ``doubt_px`` RMS, changes with the edge's position in its block, and
    an edge at ``slope`` (px across per px along) to the blocks changes its position along it. Two
    scales of that change, in quadrature: the block's (the edge crosses one block column every
    ``8 / |slope|`` px along) and the pixel's (the edge's sub-pixel phase, which decides which
    coefficients the quantisation rounds which way, turns once every ``1 / |slope|`` px along). Each is
    taken as a sinusoid of its period and any phase, sampled on the line's scan lines ``scan_px`` (N,);
    the RMS over the phase of its least-squares slope is ``doubt_px * |sum d exp(i k d)| / sum d^2``
    (``d`` the scan lines from their mean, ``k = 2 pi |slope| / period``): about ``doubt_px * k`` on a
    short or nearly aligned line (one phase, slowly drifting), small over many periods.

    Why: the offset doubt alone left the yaw of JPEG frames under-claimed; on plain rendered doors (blur
    0.6-1.8 px, noise 0-2 grey levels, quality 80-95) their yaw was within 2 sigma for 80-93 % and up to
    6.2 sigma off, the same doors as PNG 97-100 %. The block's scale alone still left doors within 0.1
    deg of square under-claimed (a sharp plain door, JPEG 80, 6.0 sigma off in yaw): 512-px edges at
    0.001 px per px (step 15, quality 80) placed at 24 phases, read with and without quantisation, had
    their least-squares tilts within 2 sigma of the block's period alone for 54 %, of both for all.

    Examples
    --------
    >>> s = np.arange(600.0)
    >>> jpeg_tilt_sigma(0.0, s)
    0.0
    >>> bool(jpeg_tilt_sigma(0.01, s) > jpeg_tilt_sigma(0.5, s))
    True
    """
    d = np.asarray(scan_px, np.float64)
    if d.size < 3 or not math.isfinite(slope):
        return 0.0
    d = d - d.mean()
    dd = float(d @ d)
    if dd <= 0:
        return 0.0
    return math.hypot(
        _periodic_tilt(doubt_px, 8.0, slope, d, dd), _periodic_tilt(doubt_px, 1.0, slope, d, dd)
    )


def jpeg_drift_tilt(slope: float, scan_px: np.ndarray, doubt_px: float = JPEG_EDGE_DOUBT_PX) -> float:
    """1-sigma of a line's tilt (px per px) from JPEG's error drifting along an edge that keeps nearly one
    pixel phase: ``JPEG_DRIFT_TILT`` times ``doubt_px`` over the line's length (its scan lines
    ``scan_px``), in full where the edge's phase sweeps under 1 px along it, none beyond 2 px, linearly
    between. (:func:`jpeg_tilt_sigma` joins it in quadrature.)

    Why: at one phase the quantisation's error is not constant along the edge: it follows the grey levels
    beside it, which light, vignetting and the door change slowly along its length, and the rounding of a
    block's coefficients flips at thresholds of them, so the error runs in stretches of many blocks (one
    door, 37 grey levels of step, JPEG 80: the far arris's points 0.14 px to one side over its first third
    and 0.2 px to the other over its last), which a line fit takes as tilt, and which the periodic model
    gives none of as the sweep goes to nothing. Measured: 3 plain doors (steps 37-98), each at 8 yaws
    from 0 to 1 deg and 2 phases, their long arrises read with and without quantisation (no noise), the
    tilt's error times the line's length over ``doubt_px``: RMS 2.5 and at most 6.7 where the phase swept
    under 1.5 px; at most 2.5 from 2.4 px on, which the periodic model covers (1 deg: at most 0.7).

    Examples
    --------
    >>> s = np.arange(601.0)
    >>> round(jpeg_drift_tilt(0.0, s, 0.05) * 600 / 0.05, 6)
    3.0
    >>> jpeg_drift_tilt(0.01, s, 0.05)
    0.0
    """
    s = np.asarray(scan_px, np.float64)
    if s.size < 3 or not math.isfinite(slope):
        return 0.0
    length = float(s.max() - s.min())
    if length <= 0.0:
        return 0.0
    share = min(1.0, max(0.0, JPEG_DRIFT_SWEEP_PX - abs(slope) * length))
    return JPEG_DRIFT_TILT * doubt_px / length * share


def corner_fit_sigma(offset_sigma_mm: float, angle_sigma_rad: float, lever_mm: float) -> float:
    """Fit 1-sigma of the corner along one line's normal: the offset's error (at the points' centroid) and
    the angle's error times the distance from that centroid to the corner, in quadrature."""
    return math.hypot(offset_sigma_mm, angle_sigma_rad * lever_mm)


def _candidate(names: tuple[str, ...], camera: CameraModel) -> tuple[Candidate, list[int]] | None:
    """The calibration model whose free intrinsics are ``names``, and the permutation into its order."""
    fixed = "f" in names
    dist = sorted(_DIST_INDEX[n] for n in names if n in _DIST_INDEX)
    if any(i >= camera.dist_coeffs.size for i in dist):
        return None
    c = Candidate("from_file", 0, max(camera.dist_coeffs.size, 5), tuple(dist), fixed)
    order = free_param_names(c)
    if sorted(order) != sorted(names):
        return None
    return c, [list(names).index(n) for n in order]


def calibration_pose_sigma(
    posed: PosedCamera,
    depth_y: float,
    corner_px: np.ndarray,
    yaw_deg: float,
    covariance: np.ndarray | None,
    names: list[str] | tuple[str, ...],
    fallback_sigma_px: float,
    scale_mm_per_px: float,
) -> tuple[float, float, float]:
    """1-sigma of (x_mm, z_mm, yaw_deg) that the camera calibration's uncertainty gives the located pose.

    With a covariance of the intrinsics (``names`` in its order, as :mod:`doorloc.calib.calibrate` saves
    it): how the pixel of a fixed ray moves with each intrinsic, less what a small rotation of the camera
    takes up over the whole image (the cell check fits the camera's placement with the same intrinsics,
    which absorbs that part: :func:`doorloc.calib.calibrate.projection_jacobian` ``aligned=True``), is
    taken at the corner pixel and at a pixel 40 mm along door +X; the plane's local Jacobian (central
    differences through :class:`doorloc.vision.metric.PlaneMap`) turns it into x, z and yaw, and
    ``J C J^T`` gives their covariance. Without one (or with names that no calibration model has), the
    default floor of the module docstring.
    """
    names = tuple(names)
    cand = _candidate(names, posed.camera) if covariance is not None and names else None
    if cand is None or covariance is None:
        s = fallback_sigma_px
        w, h = posed.camera.image_size
        yaw = math.degrees(s * math.sqrt(2.0) / (0.5 * math.hypot(w, h)))
        return s * scale_mm_per_px, s * scale_mm_per_px, yaw
    c, perm = cand
    C = np.asarray(covariance, float)[np.ix_(perm, perm)]
    pm = PlaneMap(posed, depth_y)
    corner = pm.to_plane(np.asarray(corner_px, float).reshape(1, 2))[0]
    t = math.radians(yaw_deg)
    second = corner + 40.0 * np.array([math.cos(t), math.sin(t)])
    pix = pm.to_image(np.stack([corner, second]))
    w, h = posed.camera.image_size
    gu, gv = np.meshgrid(np.linspace(0, w - 1, 9), np.linspace(0, h - 1, 7))
    grid = np.stack([gu.ravel(), gv.ravel()], axis=1)
    Jp = projection_jacobian(posed.camera, c, np.concatenate([pix, grid]), aligned=True)[:2]  # (2, 2, n)
    if not np.all(np.isfinite(Jp)):
        return calibration_pose_sigma(
            posed, depth_y, corner_px, yaw_deg, None, (), fallback_sigma_px, scale_mm_per_px
        )
    # The ray seen at a fixed pixel moves by -J dp: the located plane point moves by -(dXZ/duv) J dp.
    G = []
    for p in pix:
        d = pm.to_plane(np.array([p + [0.5, 0], p - [0.5, 0], p + [0, 0.5], p - [0, 0.5]]))
        G.append(np.stack([d[0] - d[1], d[2] - d[3]], axis=1))  # (2 plane, 2 pixel)
    dA = -G[0] @ Jp[0]  # (2, n): corner X, Z per parameter
    dB = -G[1] @ Jp[1]
    # yaw = atan2(dZ, dX) of B - A, linearised about the nominal direction
    u = np.array([-math.sin(t), math.cos(t)]) / 40.0
    J = np.vstack([dA, np.degrees(u @ (dB - dA))[None, :]])
    cov = J @ C @ J.T
    sx, sz, sy = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return float(sx), float(sz), float(sy)


def combine(terms: dict[str, tuple[float, float, float]]) -> tuple[float, float, float]:
    """Quadrature sum of independent (x_mm, z_mm, yaw_deg) 1-sigma terms."""
    a = np.array([[v if math.isfinite(v) else 0.0 for v in t] for t in terms.values()], float)
    s = np.sqrt((a * a).sum(axis=0))
    return float(s[0]), float(s[1]), float(s[2])


@dataclass(frozen=True)
class LineLever:
    """Where a line's inlier points lie against the corner: what turns the line's tilt into the pose's doubt.

    Attributes
    ----------
    lever_mm : float
        Distance from the points' centroid along the line to the corner, mm.
    spread_px2 : float
        Sum of the squared distances of the points' scan lines from their mean, px^2: the weight the joint
        fit gives the line's direction.
    extent_px : float
        First to last scan line, px.
    vote : float or None
        The line's weight on the direction where it was voted by the lines' doubts
        (:func:`doorloc.vision.direction_vote.voted_by_doubts`); None: ``spread_px2``, the joint fit's.
    """

    lever_mm: float
    spread_px2: float
    extent_px: float
    vote: float | None = None

    @property
    def weight(self) -> float:
        """The line's weight on the door's direction (relative to the other voting lines')."""
        return self.spread_px2 if self.vote is None else self.vote

    @classmethod
    def of_points(cls, scan_px: np.ndarray, corner_scan_px: float, scale_mm_per_px: float) -> LineLever:
        """The lever of the points on scan lines ``scan_px`` (N,) for a corner on scan line ``corner_scan_px``."""
        s = scan_px.astype(float)
        if not s.size:
            return cls(0.0, 0.0, 0.0)
        # integer scan lines: their sum is exact, so this is np.mean's value
        mean = float(s.sum()) / s.size
        return cls(
            abs(mean - corner_scan_px) * scale_mm_per_px,
            float(((s - mean) ** 2).sum()),
            float(s.max() - s.min()),
        )


@dataclass(frozen=True)
class BudgetTerm:
    """One source's 1-sigma contribution to the answer (``diagnostics["uncertainty_budget"]``): x, z (mm) and
    yaw (deg) of the pose, and the thickness (mm; None for a term the thickness's sigma does not count: the
    calibration and the camera's placement move both arrises alike)."""

    source: str
    x_mm: float
    z_mm: float
    yaw_deg: float
    thickness_mm: float | None

    def as_dict(self) -> dict[str, str | float | None]:
        return {
            "source": self.source,
            "x_mm": round(self.x_mm, 7),
            "z_mm": round(self.z_mm, 7),
            "yaw_deg": round(self.yaw_deg, 7),
            "thickness_mm": None if self.thickness_mm is None else round(self.thickness_mm, 7),
        }


@dataclass(frozen=True)
class Budget:
    """The answer's uncertainty, all of it from :func:`propagate`.

    Attributes
    ----------
    x_mm, z_mm, yaw_deg : float
        The pose's 1-sigma.
    thickness_mm : float
        The thickness's 1-sigma the thickness check weighs.
    thickness_reported_mm : float
        The same, reaching a far face's other reading where the image cannot tell the two apart.
    groups : dict[str, tuple[float, float, float]]
        The pose's terms of the module docstring, (x_mm, z_mm, yaw_deg) each
        (``diagnostics["uncertainty_terms"]``).
    terms : tuple of BudgetTerm
        Each source's contribution (``diagnostics["uncertainty_budget"]``); in quadrature they give the
        pose's and the thickness's sigma.
    """

    x_mm: float
    z_mm: float
    yaw_deg: float
    thickness_mm: float
    thickness_reported_mm: float
    groups: dict[str, tuple[float, float, float]]
    terms: tuple[BudgetTerm, ...]

    def with_reported_thickness_term(self, source: str, sigma_mm: float) -> Budget:
        """The same budget whose reported thickness (not the one the check weighs) carries one more term,
        ``sigma_mm`` (1 sigma, mm) from ``source``, in quadrature."""
        return replace(
            self,
            thickness_reported_mm=math.hypot(self.thickness_reported_mm, sigma_mm),
            terms=(*self.terms, BudgetTerm(source, 0.0, 0.0, 0.0, sigma_mm)),
        )


def _yaw_rad(levers: dict[str, LineLever], tilts: dict[str, float]) -> float:
    """The yaw's doubt from the voting lines' tilts (px per px), weighted as the joint fit weighs the lines
    (:attr:`LineLever.weight`)."""
    wsum = sum(lv.weight for lv in levers.values())
    if not wsum > 0:
        return 0.0
    return math.sqrt(sum((levers[k].weight * _finite(tilts[k])) ** 2 for k in tilts)) / wsum


def _source_terms(
    model: EdgeModelTerms, levers: dict[str, LineLever], scale_mm_per_px: float
) -> list[BudgetTerm]:
    """Each edge-model source's contribution: its offsets move x (reference line), z (bottom line) and the
    thickness (reference and far lines); its tilts the yaw and, through the levers, x and z."""
    sc = scale_mm_per_px
    blur = BLUR_MODEL_FRACTION * model.blur_px if math.isfinite(model.blur_px) else 0.0
    wsum = sum(lv.weight for lv in levers.values())
    # per source: its offset (px) and tilt on each line, and whether its doubts share one cause
    shares: dict[str, tuple[dict[str, float], dict[str, float], bool]] = {
        "floor": (
            dict.fromkeys(EDGE_LINES, EDGE_MODEL_FLOOR_PX),
            {k: 2.0 * EDGE_MODEL_FLOOR_PX / max(lv.extent_px, 1.0) for k, lv in levers.items()},
            False,
        ),
        "blur": (dict.fromkeys(EDGE_LINES, _finite(blur)), {}, False),
    }
    for d in model._in_order:
        offset, tilt, linked = shares.setdefault(d.source, ({}, {}, False))
        offset[d.line], tilt[d.line] = _finite(d.offset_px), _finite(d.tilt)
        if d.group is not None and not linked:
            shares[d.source] = (offset, tilt, True)
    out = []
    for source, (offset, tilt, linked) in shares.items():
        yaw = (
            math.sqrt(sum((lv.weight * tilt.get(k, 0.0)) ** 2 for k, lv in levers.items())) / wsum
            if wsum > 0
            else 0.0
        )
        ref, bot, far = (offset.get(k, 0.0) for k in ("reference", "bottom", "far"))
        out.append(
            BudgetTerm(
                source,
                math.hypot(ref * sc, yaw * levers["reference"].lever_mm),
                math.hypot(bot * sc, yaw * levers["bottom"].lever_mm),
                math.degrees(yaw),
                (ref + far) * sc if linked else math.hypot(ref, far) * sc,
            )
        )
    return out


def propagate(
    model: EdgeModelTerms,
    offset_sigma_mm: dict[str, float],
    angle_sigma_rad: float,
    levers: dict[str, LineLever],
    scale_mm_per_px: float,
    camera_terms: dict[str, tuple[float, float, float]],
    other_reading_mm: float | None = None,
) -> Budget:
    """The one place where the answer's doubts become its uncertainty, for the pose and the thickness.

    ``model``: the lines' edge-model doubts; ``offset_sigma_mm``, ``angle_sigma_rad``: the joint line fit's
    standard errors (:class:`doorloc.vision.lines.RectangleFit`); ``levers``: the lines that voted on the
    door's direction (the reference arris and the bottom end, and the far arris where it voted);
    ``camera_terms``: the pose's ``calibration`` and ``cell`` terms, (x_mm, z_mm, yaw_deg) each;
    ``other_reading_mm``: how far a far face's other reading lies, where the image cannot tell which.

    The pose: the ``fit`` term (each line's offset error and the angle's error times the lever, in
    quadrature), the ``edge_model`` term (each pose line's doubts in quadrature, and the yaw that the voting
    lines' tilts give, times the lever) and the camera's terms, in quadrature (:func:`combine`). The
    thickness: both arrises' fit errors and doubts in quadrature, except the doubts of one correlation
    group (:attr:`LineDoubt.group`), which share their cause and add. Every source's share of it all is
    reported as a :class:`BudgetTerm`.
    """
    sc = scale_mm_per_px
    ref, bot = levers["reference"], levers["bottom"]
    fit_t = (
        corner_fit_sigma(offset_sigma_mm["reference"], angle_sigma_rad, ref.lever_mm),
        corner_fit_sigma(offset_sigma_mm["bottom"], angle_sigma_rad, bot.lever_mm),
        math.degrees(angle_sigma_rad),
    )
    # (the floor: a bias that changes by twice the floor from one end of a line to the other)
    tilts = {
        k: math.hypot(model.tilt(k), 2.0 * EDGE_MODEL_FLOOR_PX / max(lv.extent_px, 1.0))
        for k, lv in levers.items()
    }
    yaw_m = _yaw_rad(levers, tilts)
    model_t = (
        math.hypot(model.line_sigma_px("reference") * sc, yaw_m * ref.lever_mm),
        math.hypot(model.line_sigma_px("bottom") * sc, yaw_m * bot.lever_mm),
        math.degrees(yaw_m),
    )
    groups = {"fit": fit_t, "edge_model": model_t, **camera_terms}
    x, z, yaw = combine(groups)
    # the thickness: the doubts of a correlation group add (one camera exponent moves both arrises
    # outwards or both inwards, and the thickness by their sum), the rest in quadrature
    arrises = ("reference", "far")
    linked = sorted(
        {CAMERA_RESPONSE} | {d.group for d in model.doubts if d.group is not None and d.line in arrises}
    )
    linked_sources = tuple({d.source for d in model.doubts if d.group is not None})
    rest = [model.line_sigma_px(k, without=linked_sources) for k in arrises]
    sums = [sum(d.offset_px for k in arrises for d in model.of_line(k) if d.group == g) for g in linked]
    t_sigma = math.hypot(
        offset_sigma_mm["reference"],
        offset_sigma_mm["far"],
        rest[0] * sc,
        rest[1] * sc,
        *(s * sc for s in sums),
    )
    terms = [
        BudgetTerm("fit", *fit_t, math.hypot(offset_sigma_mm["reference"], offset_sigma_mm["far"])),
        *_source_terms(model, levers, sc),
    ]
    t_reported = t_sigma
    if other_reading_mm is not None:
        t_reported = math.hypot(t_sigma, 0.5 * other_reading_mm)
        terms.append(BudgetTerm("far_face_other_reading", 0.0, 0.0, 0.0, abs(0.5 * other_reading_mm)))
    terms += [BudgetTerm(name, *t, None) for name, t in camera_terms.items()]
    return Budget(x, z, yaw, t_sigma, t_reported, groups, tuple(terms))
