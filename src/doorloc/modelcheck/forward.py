"""Forward models: the pose error each image would show if the world had an effect the cell lacks.

Every image is located once with the nominal cell (:func:`observe`): its measured pose, the stretch of
each edge it saw and the edge points' residuals. Then, for candidate effect values:

- **analytic** (:class:`AnalyticModel`): the true door (reference pose, width, thickness) is projected
  through the *perturbed* cell to pixels and back-projected through the *nominal* cell onto the
  hinge-face plane, where the same joint line fit as locate's gives the pose the nominal model would
  report; minus the reference pose, that is the predicted error. No rendering, a fraction of a
  millisecond per image.
- **relocate** (:class:`RelocateTable`): effects on the grey levels (arris, camera response) have no
  clean geometric signature (the edge shift depends on lighting, blur and view), so the images are located
  again with the cell holding candidate values on a grid; the predicted error at any value is
  interpolated between grid points.

Pose errors are rows ``(x_mm, z_mm, yaw_deg, thickness_mm)``: measured minus reference.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy.interpolate import PchipInterpolator

from doorloc.cell import Cell, DoorSize
from doorloc.modelcheck.catalogue import Effect, Values
from doorloc.modelcheck.dataset import MeasuredImage
from doorloc.pose import DoorPose
from doorloc.vision.config import LocateConfig
from doorloc.vision.lines import fit_rectangle_lines
from doorloc.vision.locate import LocateTrace, locate
from doorloc.vision.metric import PlaneMap
from doorloc.vision.region import EDGE_NAMES

__all__ = [
    "COMPONENTS",
    "Observation",
    "observe",
    "locate_errors",
    "AnalyticModel",
    "RelocateTable",
    "door_for",
]

#: The pose-error components, in the order of every error row.
COMPONENTS = ("x_mm", "z_mm", "yaw_deg", "thickness_mm")
_N_EDGE = 24  # model points per edge: the line fit of straight, smooth edges needs few


def door_for(item: MeasuredImage, cell: Cell, measured_arris: bool) -> DoorSize:
    """The door to locate ``item`` with under ``cell``: its measured size, and its arris unless the data
    set measured none (then the cell's default door's arris, where it fits)."""
    d = item.door
    if measured_arris:
        return d
    a = cell.default_door.arris_mm
    return DoorSize(
        d.width_mm,
        d.thickness_mm,
        d.height_mm,
        a if a < d.thickness_mm / 2 else 0.0,
        cell.default_door.arris_profile,
    )


@dataclass
class Observation:
    """One image located with the nominal cell.

    Attributes
    ----------
    item : MeasuredImage
    image : ndarray or None
        The grey levels (kept for relocation).
    ok : bool
        Whether locate answered; ``refusal`` says why not (``error_code: message``).
    error : ndarray (4,)
        Measured minus reference pose (:data:`COMPONENTS`).
    sigma : ndarray (4,)
        Locate's own 1-sigma uncertainty of the measured values.
    ranges : dict
        Per edge, the stretch seen along it (door-frame mm: px for the bottom end, pz for the arrises).
    edge_uv, edge_residual_mm : ndarray
        Inlier edge points (pixels) and their distance from the fitted lines (mm), for the plots.
    response_absorbed : float
        The camera response exponent locate measured on this image's plain edges and used instead of the
        cell's (``diagnostics.camera_response``), NaN where it kept the cell's.
    jpeg_quality : int
        The JPEG quality the image's file was stored at (0: no JPEG), told to locate again on relocation.
    """

    item: MeasuredImage
    image: np.ndarray | None
    ok: bool
    refusal: str
    error: np.ndarray
    sigma: np.ndarray
    corner_px: np.ndarray
    ranges: dict[str, tuple[float, float]]
    edge_uv: np.ndarray
    edge_residual_mm: np.ndarray
    response_absorbed: float = math.nan
    jpeg_quality: int = 0


def _pose_row(r, ref: DoorPose, door: DoorSize) -> np.ndarray:
    return np.array(
        [r.x_mm - ref.x_mm, r.z_mm - ref.z_mm, r.yaw_deg - ref.yaw_deg, r.thickness_mm - door.thickness_mm]
    )


def observe(
    items: Sequence[MeasuredImage],
    cell: Cell,
    measured_arris: bool,
    read: Callable[[MeasuredImage], tuple[np.ndarray, int]],
    keep_images: bool = True,
) -> list[Observation]:
    """Locate every image with ``cell`` and keep what the forward models need (see :class:`Observation`).

    ``read`` gives an image's grey levels and its file's JPEG quality (0: no JPEG;
    :func:`doorloc.modelcheck.dataset.read_measured_image`), which locate is told. Without the refusals that
    only judge an answer's uncertainty (:func:`locate_errors`): the model check
    needs the pose the cell gives. A cell that lacks the doors' arris doubts every thickness it cannot
    check, and production's gate refused 39 of 40 images of a rounded 0.79 mm arris (thickness 39.73 +-
    1.51 mm against 40): the check then refused the data set as "too far from the images", the very
    case it exists for.
    """
    out = []
    cfg = _ungated(cell.locate)
    for it in items:
        img, quality = read(it)
        door = door_for(it, cell, measured_arris)
        tr = LocateTrace()
        r = locate(img, cell, door, image_name=it.image, trace=tr, config=cfg, jpeg_quality=quality)
        nan4 = np.full(4, np.nan)
        if not r.ok or tr.region is None or tr.pose is None:
            out.append(
                Observation(
                    it,
                    img if keep_images else None,
                    False,
                    f"{r.error_code}: {r.error}" if not r.ok else "internal_error: no traced pose",
                    nan4,
                    nan4,
                    np.full(2, np.nan),
                    {},
                    np.zeros((0, 2)),
                    np.zeros(0),
                    jpeg_quality=quality,
                )
            )
            continue
        err = _pose_row(r, it.reference, door)
        unc = r.uncertainty
        t_sig = float(r.diagnostics.get("thickness_check", {}).get("sigma_mm", np.nan))
        sig = np.array([unc.x_mm, unc.z_mm, unc.yaw_deg, t_sig]) if unc is not None else nan4
        p = tr.pose
        c, s = math.cos(math.radians(p.yaw_deg)), math.sin(math.radians(p.yaw_deg))
        ranges, uvs, res = {}, [], []
        for name in EDGE_NAMES:
            smp = tr.samples[name]
            keep = tr.inliers[name] & smp.valid
            uv = smp.uv()[keep]
            xz = tr.region.plane_points(uv)
            dX, dZ = xz[:, 0] - p.x_mm, xz[:, 1] - p.z_mm
            px, pz = c * dX + s * dZ, -s * dX + c * dZ
            along, across = (
                (px, pz) if name == "bottom" else (pz, px - (p.thickness_mm if name == "far" else 0.0))
            )
            fin = np.isfinite(along)
            if fin.sum() >= 2:
                ranges[name] = (float(np.percentile(along[fin], 2)), float(np.percentile(along[fin], 98)))
            uvs.append(uv[fin][::4])
            res.append(across[fin][::4])
        out.append(
            Observation(
                it,
                img if keep_images else None,
                True,
                "",
                err,
                sig,
                np.asarray(r.corner_px, float),
                ranges,
                np.concatenate(uvs),
                np.concatenate(res),
                _absorbed(r.diagnostics.get("camera_response", {})),
                quality,
            )
        )
    return out


def _absorbed(resp: dict) -> float:
    return float(resp["fitted"]) if resp.get("absorbed") and "fitted" in resp else math.nan


def locate_errors(
    obs: Sequence[Observation],
    cell: Cell,
    measured_arris: bool,
    gated: bool = True,
    reasons: list[str] | None = None,
) -> np.ndarray:
    """Locate the kept images again with ``cell``: error rows ``(n, 4)`` (NaN where refused).

    ``gated=False`` lifts the refusals that only judge an answer's uncertainty (thickness that cannot be
    checked, the pose's 1-sigma beyond the cell's tolerance): a forward model needs the pose a cell gives,
    not production's verdict on it (hidden arris 1.35 mm, seed 481507: one training image's thickness could
    not be checked at any arris, its row of the arris table stayed 0, and focal length was named instead).
    ``reasons``, where given, receives each image's refusal (``error_code: message``; "" where answered).
    """
    cfg = None if gated else _pose_only(cell.locate)
    rows = np.full((len(obs), 4), np.nan)
    for k, o in enumerate(obs):
        if o.image is None:
            continue
        door = door_for(o.item, cell, measured_arris)
        r = locate(o.image, cell, door, image_name=o.item.image, config=cfg, jpeg_quality=o.jpeg_quality)
        if r.ok:
            rows[k] = _pose_row(r, o.item.reference, door)
        if reasons is not None:
            reasons.append("" if r.ok else f"{r.error_code}: {r.error}")
    return rows


@dataclass(frozen=True)
class _Geometry:
    """One image's door points for the analytic model: on the hinge face at the image's reference pose,
    cell (X, Z) mm, every edge's in one array (``xz``, in :data:`EDGE_NAMES` order, ``bounds`` slicing it),
    so that each prediction maps them through the cameras in one call."""

    door: DoorSize
    xz: np.ndarray  # (3 * _N_EDGE, 2)
    bounds: tuple[int, ...]


def _geometry(o: Observation, door: DoorSize) -> _Geometry:
    T = door.thickness_mm
    default = {"bottom": (0.05 * T, 0.95 * T), "reference": (1.0, 60.0), "far": (1.0, 60.0)}
    pts = []
    for name in EDGE_NAMES:
        lo, hi = o.ranges.get(name, default[name])
        a = np.linspace(lo, hi, _N_EDGE)
        if name == "bottom":
            pts.append(np.stack([a, np.zeros_like(a)], 1))
        else:
            pts.append(np.stack([np.full_like(a, 0.0 if name == "reference" else T), a], 1))
    # door frame (px, pz) -> cell (X, Z) at the reference pose: the same for every candidate cell
    pose = o.item.reference
    c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
    door_pts = np.concatenate(pts)
    px, pz = door_pts[:, 0], door_pts[:, 1]
    xz = np.stack([pose.x_mm + px * c - pz * s, pose.z_mm + px * s + pz * c], 1)
    return _Geometry(door, xz, tuple(np.cumsum([0] + [len(q) for q in pts]).tolist()))


def _face_depth(cell: Cell, door: DoorSize) -> float:
    """The plane (cell Y, mm) of the door's outline in ``cell``: its hinge face, moved out by the arris."""
    return cell.fixture.face_y(door.width_mm) + door.arris_mm


def _seen_pose(true_map: PlaneMap, nominal_map: PlaneMap, g: _Geometry) -> np.ndarray:
    """The pose (x, z, yaw, thickness) the nominal cell (``nominal_map``) reports for the door of ``g`` seen
    in the world of the true cell (``true_map``, at the same door's outline plane)."""
    seen = nominal_map.to_plane(true_map.to_image(g.xz))
    if not np.isfinite(seen).all():
        return np.full(4, np.nan)
    b = g.bounds
    groups = {name: (seen[b[i] : b[i + 1]], name == "bottom") for i, name in enumerate(EDGE_NAMES)}
    t, offsets = fit_rectangle_lines(groups, n_iter=1)
    ct, st = math.cos(t), math.sin(t)
    cr, cb = offsets["reference"], offsets["bottom"]
    return np.array([ct * cr - st * cb, st * cr + ct * cb, math.degrees(t), offsets["far"] - cr])


class AnalyticModel:
    """Predicted pose errors of a set of observations for analytic effects, through the camera model.

    ``predict(effects, values)`` applies every effect's values to the nominal cell at once (they compose
    physically) and returns error rows ``(n, 4)`` for the observations given at construction.
    """

    def __init__(self, obs: Sequence[Observation], nominal: Cell, measured_arris: bool) -> None:
        self.nominal = nominal
        self.geom = [_geometry(o, door_for(o.item, nominal, measured_arris)) for o in obs]
        self.maps = [PlaneMap(nominal.posed_camera, _face_depth(nominal, g.door)) for g in self.geom]
        self.base = np.array([_seen_pose(m, m, g) for g, m in zip(self.geom, self.maps, strict=True)])

    def predict(
        self, effects: Sequence[Effect], values: Sequence[Values], rows: np.ndarray | None = None
    ) -> np.ndarray:
        cell = self.nominal
        for e, v in zip(effects, values, strict=True):
            cell = e.apply(cell, v)
        idx = np.arange(len(self.geom)) if rows is None else rows
        posed = cell.posed_camera
        true_maps: dict[float, PlaneMap] = {}  # one per outline plane: the doors come in a few sizes
        out = []
        for k in idx:
            g = self.geom[k]
            depth = _face_depth(cell, g.door)
            if depth not in true_maps:
                true_maps[depth] = PlaneMap(posed, depth)
            out.append(_seen_pose(true_maps[depth], self.maps[k], g))
        return np.array(out).reshape(-1, 4) - self.base[idx]


class RelocateTable:
    """Predicted pose errors for one grey-level effect, from locating the images again on a grid of values.

    The prediction at value ``v`` is ``error(nominal) - error(v)`` (what the candidate model would take
    away), interpolated monotonically (PCHIP) between grid values; a refusal at a grid value is bridged
    from its neighbours. :meth:`with_values` adds grid values (the prediction is exact at a grid value).
    """

    def __init__(
        self,
        effect: Effect,
        obs: Sequence[Observation],
        nominal: Cell,
        measured_arris: bool,
        grid: Sequence[float],
    ) -> None:
        self.effect = effect
        self._obs = list(obs)
        self._nominal = nominal
        self._measured_arris = measured_arris
        self._base = np.array([o.error for o in obs])
        self.grid = np.asarray(sorted(grid), float)
        self._raw = np.array([self._taken_away(v) for v in self.grid])  # (grid, n, 4), NaN where refused
        self._build()

    def _taken_away(self, value: float) -> np.ndarray:
        cell = self.effect.apply(self._nominal, [value])
        if cell == self._nominal:
            # the nominal cell's own poses: nothing to take away (and a locate of every image saved)
            return np.where(np.isfinite(self._base), 0.0, np.nan)
        return self._base - locate_errors(self._obs, cell, self._measured_arris, gated=False)

    def _build(self) -> None:
        T = self._raw.copy()
        for k in range(T.shape[1]):
            for c in range(4):
                col = T[:, k, c]
                bad = ~np.isfinite(col)
                if bad.all():
                    col[:] = 0.0
                elif bad.any():
                    col[bad] = np.interp(self.grid[bad], self.grid[~bad], col[~bad])
        self.table = T
        self._interp = PchipInterpolator(self.grid, T, axis=0, extrapolate=False)

    def with_values(self, values: Sequence[float]) -> RelocateTable:
        """A copy with the images also located at ``values`` (those not yet on the grid)."""
        new = [float(v) for v in values if not np.any(self.grid == float(v))]
        out = copy.copy(self)
        if not new:
            return out
        grid = np.concatenate([self.grid, new])
        raw = np.concatenate([self._raw, np.array([self._taken_away(v) for v in new])])
        order = np.argsort(grid)
        out.grid, out._raw = grid[order], raw[order]
        out._build()
        return out

    def predict(self, value: float, rows: np.ndarray | None = None) -> np.ndarray:
        v = float(np.clip(value, self.grid[0], self.grid[-1]))
        out = np.asarray(self._interp(v))
        return out if rows is None else out[rows]


def _ungated(cfg: LocateConfig) -> LocateConfig:
    """``cfg`` without the refusals that judge only the answer's uncertainty (:func:`locate_errors`), and
    without a rounded door's own light (``locate.light_from_door``): that light is chosen image by image
    among directions its strips often fit about alike, and kept only where its answer passes the gate; with
    the gate's limits lifted it would always stand, and a relocation at another arris or exponent could
    choose another direction, a jump in the relocation tables that no effect of the cell explains. Nor
    with the doubt of a camera's optics that nobody measured (``locate.optics_edge_sigma_px``): one shift
    of every edge on every image of the camera, which the check looks for as an effect, not an image's
    noise to weigh the pose components by; nor, for the same reason, with the doubt of a shoulder in the
    camera's response (``locate.response_shoulder_knee``: the catalogue's ``shoulder`` is such an effect),
    which would locate every bright arris image (and plain one whose edges read an exponent in the
    cell's place) twice for a sigma alone (it never moves a pose). Nor with the refusal of an arris that the
    recipes do not give (``locate.untold_arris_shift_px``): that arris is an effect the check names (the
    catalogue's ``arris``), from the poses the cell gives without it. Nor with the doubt of lines that
    disagree about the door's direction (``locate.direction_check``): a camera the cell models wrong bends
    them apart on every image, an effect the check looks for (a decentred lens, whose tangential
    distortion no catalogue entry makes, was named a lateral offset and a camera roll with it)."""
    big = 1e6
    return replace(
        cfg,
        thickness_tolerance_mm=big,
        max_uncertainty_mm=big,
        max_uncertainty_deg=big,
        max_sigma_mm=big,
        light_from_door=False,
        optics_edge_sigma_px=0.0,
        response_shoulder_knee=1.0,
        untold_arris_shift_px=0.0,
        direction_check=False,
    )


def _pose_only(cfg: LocateConfig) -> LocateConfig:
    """``cfg`` for a pose alone (:func:`locate_errors` with ``gated=False``): without the refusals that judge
    only the answer's uncertainty (:func:`_ungated`), and without sizing the doubt of a response the image
    cannot measure (``response_unmeasured_factor`` 1). That doubt reads every arris strip again at two more
    exponents (:func:`doorloc.vision.refine.arris_response_shifts`): 56 % of the time the relocations took
    in the model check's tests, for a sigma that no caller of an ungated pose reads (the answers, refusals
    and relocation tables are the same with it and without: 2026-11-28, the tables of a pair data set compared
    value for value)."""
    return replace(_ungated(cfg), response_unmeasured_factor=1.0)


def relocate_grid(effect: Effect, nominal: Cell) -> list[float]:
    """The values to relocate at for a grey-level effect: arris offsets (mm, added to the nominal door's)
    or response gammas around the nominal cell's own."""
    if effect.name == "arris":
        return [0.0, 0.3, 0.6, 1.0, 1.5, 2.0, 3.0]
    g0 = nominal.response_gamma
    return sorted({round(g0 * f, 4) for f in (0.7, 0.85, 1.0, 1.25, 1.5, 1.8, 2.2, 2.6)})


def with_default_arris(cell: Cell, arris_mm: float) -> Cell:
    d = cell.default_door
    return replace(
        cell, default_door=DoorSize(d.width_mm, d.thickness_mm, d.height_mm, arris_mm, d.arris_profile)
    )
