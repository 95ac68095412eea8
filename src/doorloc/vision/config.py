"""Settings of the locate pipeline: the cell file's ``locate:`` section (shared/SPEC.md section 2).

Kept apart from :mod:`doorloc.vision.locate` so that the cell file can validate its ``locate:`` section
against these fields without importing the pipeline (and OpenCV). The camera's response curve is not
here: it is a property of the camera, ``camera.response_gamma`` in the cell file (:attr:`doorloc.cell.Cell.response_gamma`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

__all__ = ["LocateConfig"]


@dataclass(frozen=True)
class LocateConfig:
    """Thresholds and sizes of the locate pipeline. Grey levels are on the 0-255 scale.

    Attributes
    ----------
    search_margin_mm, search_margin_deg : float
        How far beyond the placement envelope the search region reaches (so a badly placed door is
        found and refused as such, not missed).
    envelope_margin_mm, envelope_margin_deg : float
        Tolerance beyond the envelope before a pose is refused.
    door_brighter : bool
        The hinge face is brighter than the background (the cell's lighting design).
    min_contrast : float
        Smallest grey-level step accepted for an edge.
    half_window_max, half_window_min : int
        Bounds of the sub-pixel window half-size, px (the second pass sizes it to the measured blur).
    window_blur_factor : float
        Final window half-size = ceil(factor * blur sigma + 1) px: wide enough for the transition's
        tails (a centred window makes what it misses cancel), no wider: each extra pixel adds noise, and
        surface texture beside the edge (wood grain along it) biases the area estimate by the difference
        between the texture under the window and at the plateaus, which grows with their distance (issue
        11: 1.5 with 2-px plateaus takes the wood-grain RMS from 0.033 to 0.019 mm; clean images unchanged).
    plateau : int
        Samples on each side of the window used for the two grey levels, right next to it (see
        ``window_blur_factor``; ``level_smooth`` averages them along the edge against noise).
    step_fit : bool
        In the final pass, refine each plain edge point by fitting a blurred step with free levels to its
        window (:func:`doorloc.vision.blurred_step.refine_step_fit`): robust to texture along the edge (wood
        grain); False keeps the area estimator alone.
    slope_smooth : int
        Scan lines on each side over which the plateau slopes are averaged (0: flat plateaus, the
        default: a centred window cancels linear shading, and noisy slopes cost more than they give).
    level_smooth : int
        Scan lines on each side over which the plateau levels are averaged (0: per scan line); fewer on an
        edge whose levels change along it beyond their noise (texture across the edge,
        :func:`doorloc.vision.plateau_levels.level_smoothing`).
    min_thickness_mm, thickness_search_mm : float
        The far arris is looked for between these distances beyond the reference arris
        (``min_thickness_mm`` .. door thickness + ``thickness_search_mm``).
    thickness_tolerance_mm : float
        Refuse when the measured thickness differs from the door's by more.
    thickness_check : ``"refuse"`` or ``"report"``
        What an answer whose thickness the image cannot verify gets (its measurement's 3 sigma reach past
        ``thickness_tolerance_mm``: a rounded far arris against a background of nearly its shade, a far face
        seen edge-on, a far arris whose strip shows one step that its other reading puts on the recipe's
        thickness). ``"refuse"`` (the default): refused ``uncertain``, the sentence saying why. ``"report"``:
        answered, with ``thickness_verified: false`` and the reason in ``thickness_unverified_reason``, for a
        line that checks the door's thickness elsewhere. Under either a door that measures wrong beyond the
        tolerance at confidence is refused ``thickness_mismatch``; nothing passes silently.
    untold_arris_shift_px : float
        For a door whose recipe gives no arris: refuse ``arris_mismatch`` where both the bottom end and the
        reference arris move by at least this (and 5 of its standard errors) when their transitions are read
        between plateaus 20 px out, as the strip of a chamfer or rounding the recipe does not give makes them
        (:mod:`doorloc.vision.untold_arris`). 0.4 px: sharp-edged doors of every bench set moved their bottom
        end by 0.29 px at most (wood grain moves the long arrises more, but not the bottom end); 0 turns the
        check off.
    light_direction_deg : (float, float) or None
        Direction towards the cell's main light, ``[azimuth, elevation]`` in degrees in the cell frame: the
        unit vector ``(cos el sin az, -cos el cos az, sin el)`` (azimuth 0 towards the camera's side of the
        hinge face, -Y; positive towards +X; elevation towards +Z; :func:`doorloc.pose.direction_cell`). Measured once where the lamps are fixed.
        Where it is given, a rounded arris's strip is shaded as a Lambertian arc under that light (its albedo
        and the background's share free) instead of a free shading whose level trades off with the strip's
        border; a finish that is no Lambertian, or a light that is no single direction, costs
        ``arris_model.LIT_DEFICIT_FLOOR`` of the strip's width in its doubt. None (the default): the free
        shading.
    light_direction_sigma_deg : float
        How far the true light may lie from ``light_direction_deg``, 1 sigma, degrees, any way round (a lamp
        whose position was measured with a tape: a few degrees; a broad panel or a lamp guessed at: more).
        Each rounded strip is fitted again under the light turned by it four ways, and what its border
        moves goes into its doubt. Default 10; 0 takes the stated light as exact (a 0.74 mm rounding's
        door whose light was stated 40 degrees off was then answered 0.11 mm wrong at 3.2 sigma). A strip
        the stated light fits far worse than a free shading does is fitted as if no light were stated
        (``stated_light.STATED_LIGHT_MISFIT_RATIO``; ``diagnostics.arris_fit.<line>.stated_light``).
    direction_check : bool
        After the door's direction is voted, each voting line's own direction is read against it; where they
        disagree beyond their doubts (the Birge ratio above 1) every voting line's direction doubt is widened
        by the ratio, and a line that itself departs beyond its doubt is doubted across by its drift
        (:func:`doorloc.vision.direction_vote.direction_spread`; ``diagnostics.direction_spread``, the
        budget's ``direction`` term). Default on; the model check turns it off: lines that disagree because
        the cell's camera is wrong are what it looks for, not an image's noise to weigh poses by.
    light_from_door : bool
        Where no ``light_direction_deg`` is stated, a door with a rounded arris is located with free
        shadings, its light sought from its own rounded strips (:mod:`doorloc.vision.light_search`: the
        direction under which their Lambert arcs fit best, its doubt the width of that least, at least 10
        deg) and located again under that light as if the cell stated it. That answer is given where it
        passes the gate, else the free shadings' answer or refusal (``diagnostics.door_light``;
        ``model.light_source: door`` where the answer is the lit one). Where the strips do not single the
        light out (another direction fits them about as well), the lit answer's uncertainty takes up half of
        how far the free shadings' pose lies from it, and where that passes the cell's limits the door is
        refused unless the free shadings' own doubt holds the distance. One door's strips hardly tell the
        light (they often fit directions far apart about alike): this is no measurement of the cell's lamp,
        but a shading that ties each strip's level to its curvature. True (the default): on the arris
        bench's nine sets (seeds 7900, 8100, 8300; 432 doors) 354 -> 389 answered, the round and small
        sets 69 -> 88 of 96, every answer's x and z within 2 sigma; about 0.4 s more a rounded door.
        False: the free shadings alone.
    min_inliers, min_inlier_fraction, max_rms_residual_px : int, float, float
        Line-fit gate.
    corner_zone_px, min_corner_support : float
        Fraction of edge points within ``corner_zone_px`` of the corner that must fit their line.
    corner_tolerance_px : float
        An edge point next to the corner fits its line when the robust line fit kept it or it lies within
        this distance of the line, px. Something over the corner moves edges by pixels; a line fitted
        to a few hundredths of a pixel (a clean render) rejects points a twentieth of a pixel off, which
        hide nothing, and grain that wanders beside an edge bends it by a few tenths (a thin grained
        door's reference arris ran 0.1-0.32 px off its line next to the corner: at 0.25 px its support
        was 0.59-0.88 as the bottom end's reading moved by 0.02 px).
    response_unmeasured_factor : float
        Where no plain edge of the image could measure the camera's response (every edge an arris), the
        cell's ``response_gamma`` is taken as known within this factor, and the edge shift that spread
        makes goes into the arris lines' uncertainty. 2.2: cameras' exponents lie between a linear
        sensor's 1.0 and video's 2.2-2.4, so an exponent that was not measured (a linear camera assumed,
        or sRGB) may be off by that factor (with 1.5 a gamma-2.2 camera in a cell that says 1.0 had its
        arris answers at up to 3 sigma). Smaller once the response has been measured for this camera:
        ``doorloc calibrate`` measures it on the chessboard photographs and prints the factor they allow
        (``1 + 2 sigma / gamma``; stored as ``response_gamma`` and ``response_gamma_sigma`` in the calibration
        file), or a plain-edged door in the same cell (``diagnostics.camera_response.fitted``).
    response_check : ``"every_image"`` or ``"where_unmeasured"``
        Where the camera's response is read off each image's plain edges. ``"every_image"`` (the default):
        on every image that can show it, the cell's exponent checked and, where the edges show another,
        replaced by theirs (a camera whose settings changed since its calibration is caught on the image).
        ``"where_unmeasured"``: only where the cell's response was not measured (no
        ``camera.response_gamma_sigma``, from ``doorloc calibrate`` or the cell); where it was, every image
        rests on the cell's exponent within ``response_unmeasured_factor`` (its measured 2-sigma range
        unless the cell sets it) and the reading's cost (3 of a realistic 1080p frame's 9 ms) is saved. A
        camera changed since its calibration is then not seen by locate: for a cell whose camera is locked
        and re-calibrated when changed.
    response_shoulder_knee : float
        Where the image could not check the camera's response of an arris door, or a door's plain edges read
        an exponent that replaced the cell's, the response above this level (fraction of full scale) is
        doubted to bend as a shoulder (both public cameras' do, from 0.69 and 0.48) unless the cell's
        photometric model of its camera (``doorloc calibrate --optics``, ``doorloc check-model --boards``)
        measured it there (:func:`doorloc.vision.response_shoulder.doubted_knee`: a model that found a
        shoulder lifts the doubt; one that found none keeps it above the level its board photographs reached,
        where that is higher than this): a door whose image reaches above it is located again as if its camera
        had a shoulder from here to full scale, and the answer's move joins its uncertainty
        (``uncertainty_budget``'s ``response_shoulder``; :mod:`doorloc.vision.response_shoulder`). 1: no such
        doubt (a camera known to keep its power law to full scale).
    max_sigma_mm : float
        Refuse when the fit's standard error of x or z exceeds this.
    max_saturated_fraction : float
        Refuse when more of the search region is white-clipped.
    max_clipped_arris_fraction : float
        Refuse ``overexposed`` when more of an arris strip's scan lines than this have white-clipped pixels
        beside its border (a highlight on the arris the sensor cut off: its shading cannot be read).
    max_strip_other_border_share : float
        Refuse ``uncertain`` where more than this share of an arris line's points (the bottom end's or the
        reference arris's) lie on a second line about the strip's width away, which the line fit left out:
        the strip read at its other border on those scan lines, and either reading may be the right one
        (:func:`doorloc.vision.quality.check_strip_read_twice`). 1: off.
    clipped_flat_share : float
        Refuse ``overexposed`` where the flat patches beside the door's edges hold at least this share of
        their pixels at one grey level on the bright side (or a chamfer strip's inside does), at the
        brightest level the edges see, where the dark side's noise, carried through the camera's response,
        would leave clearly fewer there: the sensor's noise gone from the bright side, as a sensor or tone
        curve that saturates below the top code leaves it (a camera clipping at 240 grey: 0.07-0.28 mm off
        at 2-13 sigma where not refused; :func:`doorloc.vision.quality.check_clipped_flat`).
        Above 1: off.
    min_noise_scale_ratio : float
        Refuse ``sharpened`` when flat patches beside the door's edges hold less noise between 4-px blocks
        than between pixels by more than this, and than between 2 x 2 boxes by two thirds of it
        (:func:`doorloc.vision.quality.noise_scale_ratio`, :func:`~doorloc.vision.quality.check_sharpened`:
        a sensor's white noise gives 1, demosaicking, texture and coarse JPEG more, a camera's sharpening
        less on both, fine JPEG less between pixels only); 0 turns the check off.
    max_uncertainty_mm, max_uncertainty_deg : float
        The cell's tolerance on the answer's 1-sigma uncertainty (:mod:`doorloc.vision.uncertainty`):
        refuse ``uncertain`` when that of x or z exceeds ``max_uncertainty_mm`` or that of the yaw
        ``max_uncertainty_deg``.
    calibration_sigma_px : float
        Default 1-sigma projection error of a camera calibration that carries no covariance, px (the
        floor of the ``calibration`` term); 0 only for a camera known exactly (rendered images).
    door_width_sigma_mm : float
        1-sigma of the doors' real widths about their recipes' (a door maker's tolerance), mm. The recipe's
        width places the hinge face's depth (the fixture's ``face_shift_per_width``), which no pixel shows:
        the answer's x and z take the corner's move over that depth's sigma (``uncertainty_budget``'s
        ``door_width`` term; in the thesis cell about 0.05 mm of x and 0.06 of z per mm of width). 0 (the
        default): the recipe's width taken as exact.
    cell_sigma_mm, cell_sigma_deg : float
        1-sigma of the camera's placement in the cell (the cell check), carried into x, z and yaw.
    optics_edge_sigma_px : float
        Where the cell carries no photometric model of its camera (``camera.photometric_model`` or the
        calibration's, from ``doorloc calibrate --optics`` or ``doorloc check-model --boards``): 1-sigma of
        how far the camera's optics move every edge beyond what a Gaussian blur and the response curve
        explain, image px, counted on every edge as one cause (the ``optics`` term of
        ``diagnostics.uncertainty_budget``). One image cannot see it: a point spread off centre moves the
        door's edges as a moved door would. Measured on the two public cameras' board photographs
        (``../shared/data``): Bouguet's camera moves its edges 0.19 px along the image's rows and 0.05 along
        its columns against the board's corners, OpenCV's left camera none beyond its response. Two cameras
        fix the spread of such shifts only loosely: the RMS of the four, 0.1 px, left the z of doors through
        Bouguet's measured camera, located in a cell that does not describe it, within 2 sigma on 85, 85 and
        91 % of three draws (65 %, worst 11 sigma, with no such doubt); 0.13 (the default) puts the largest
        shift measured at 1.5 sigma of this term alone, so that a door through that camera stays within 2
        sigma once its other doubts join it: 96, 96 and 100 %. Its price: rounded arrises whose sigma lay just
        under ``max_uncertainty_mm`` are refused (3 of 128 on one draw of the arris bench, 0 on another). A
        camera whose photometric model was measured takes that model's held-out ``residual_edge_px`` instead;
        0 only for a camera known exactly (rendered images).
    """

    search_margin_mm: float = 30.0
    search_margin_deg: float = 6.0
    envelope_margin_mm: float = 2.0
    envelope_margin_deg: float = 0.5
    door_brighter: bool = True
    min_contrast: float = 6.0
    half_window_max: int = 9
    half_window_min: int = 3
    window_blur_factor: float = 1.5
    plateau: int = 1
    step_fit: bool = True
    slope_smooth: int = 0
    level_smooth: int = 10
    min_thickness_mm: float = 4.0
    thickness_search_mm: float = 15.0
    thickness_tolerance_mm: float = 1.0
    thickness_check: Literal["refuse", "report"] = "refuse"
    untold_arris_shift_px: float = 0.4
    min_inliers: int = 40
    min_inlier_fraction: float = 0.6
    max_rms_residual_px: float = 1.5
    corner_zone_px: float = 60.0
    min_corner_support: float = 0.6
    corner_tolerance_px: float = 0.5
    response_unmeasured_factor: float = 2.2
    response_check: Literal["every_image", "where_unmeasured"] = "every_image"
    response_shoulder_knee: float = 0.7
    max_sigma_mm: float = 0.05
    max_saturated_fraction: float = 0.5
    max_clipped_arris_fraction: float = 0.1
    max_strip_other_border_share: float = 0.2
    clipped_flat_share: float = 0.95
    min_noise_scale_ratio: float = 0.85
    max_uncertainty_mm: float = 0.1
    max_uncertainty_deg: float = 0.05
    calibration_sigma_px: float = 0.05
    cell_sigma_mm: float = 0.0
    cell_sigma_deg: float = 0.0
    door_width_sigma_mm: float = 0.0
    optics_edge_sigma_px: float = 0.13
    light_direction_deg: tuple[float, float] | None = None
    light_direction_sigma_deg: float = 10.0
    light_from_door: bool = True
    direction_check: bool = True

    def __post_init__(self) -> None:
        if not 0.0 <= self.max_clipped_arris_fraction <= 1.0:
            raise ValueError(
                f"max_clipped_arris_fraction is a share of scan lines in 0..1, got {self.max_clipped_arris_fraction:g}"
            )
        if not 0.0 <= self.max_strip_other_border_share <= 1.0:
            raise ValueError(
                "max_strip_other_border_share is a share of a line's points in 0..1 (1: off), got "
                f"{self.max_strip_other_border_share:g}"
            )
        if not self.clipped_flat_share > 0.0:
            raise ValueError(
                f"clipped_flat_share is a share of a patch's pixels in 0..1 (above 1: off), got {self.clipped_flat_share:g}"
            )
        if not 0.0 <= self.min_noise_scale_ratio < 1.0:
            raise ValueError(
                f"min_noise_scale_ratio is a ratio in 0..1 (0: off), got {self.min_noise_scale_ratio:g}"
            )
        if not 0.05 <= self.response_shoulder_knee <= 1.0:
            raise ValueError(
                "response_shoulder_knee is a level in 0.05..1 of full scale (1: no shoulder doubted), got "
                f"{self.response_shoulder_knee:g}"
            )
        if not 0.0 <= self.door_width_sigma_mm <= 50.0:
            raise ValueError(
                f"door_width_sigma_mm is a 1-sigma width in 0..50 mm, got {self.door_width_sigma_mm:g}"
            )
        if not 0.0 <= self.untold_arris_shift_px <= 10.0:
            raise ValueError(
                f"untold_arris_shift_px is an edge shift in 0..10 px (0: off), got {self.untold_arris_shift_px:g}"
            )
        if not 0.0 <= self.optics_edge_sigma_px <= 5.0:
            raise ValueError(
                f"optics_edge_sigma_px is a 1-sigma edge shift in 0..5 px, got {self.optics_edge_sigma_px:g}"
            )
        if not 0.0 <= self.light_direction_sigma_deg <= 90.0:
            raise ValueError(
                f"light_direction_sigma_deg is an angle in 0..90 degrees, got {self.light_direction_sigma_deg:g}"
            )
        if self.light_direction_deg is not None:
            az, el = self.light_direction_deg
            if not (-180.0 <= az <= 180.0 and -90.0 <= el <= 90.0):
                raise ValueError(
                    f"light_direction_deg is [azimuth, elevation] with azimuth in -180..180 and elevation in "
                    f"-90..90 degrees, got [{az:g}, {el:g}]"
                )
