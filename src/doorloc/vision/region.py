"""Where to look: scan lines across each door edge, from the cell model, the envelope and the door size.

Two kinds of region:

- the **search region** (:meth:`SearchRegion.coarse_bands`): everything a door inside the placement
  envelope plus a margin could cover, per edge; the coarse step finder looks only there;
- **tracks** (:meth:`SearchRegion.tracks`): given a pose estimate, the scan lines that cross each
  edge away from the corner and the image border, and where on each scan line the edge is predicted.

All geometry is done on the hinge-face plane (mm) and projected through the full camera model, so
the regions follow lens distortion.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from doorloc.calib.camera import PosedCamera
from doorloc.cell import Cell, DoorSize, Envelope, Fixture
from doorloc.vision.arris_geometry import ArrisGeometry
from doorloc.vision.jit import kernel
from doorloc.vision.metric import PlaneMap
from doorloc.vision.sampling import Axis

__all__ = ["EdgeLayout", "Band", "Track", "SearchRegion", "EDGE_NAMES", "HUMAN"]

EDGE_NAMES = ("bottom", "reference", "far")

#: each line as a person names it, in refusals
HUMAN = {
    "bottom": "bottom end of the door (X-line)",
    "reference": "reference-face arris (Z-line)",
    "far": "far arris (door thickness)",
}


@dataclass(frozen=True)
class EdgeLayout:
    """How one door edge appears in the image.

    ``axis``: scan columns (``"col"``, edge near-horizontal) or rows (``"row"``).
    ``polarity``: +1 when the grey level rises across the edge with increasing ``along``.
    ``along_x``: True for the bottom end (runs along door +X), False for the arrises.
    """

    name: str
    axis: Axis
    polarity: int
    along_x: bool

    def door_side(self, door_brighter: bool) -> int:
        """+1 where the door lies at increasing ``along`` (the grey level rises into it when it is the
        brighter side, ``locate.door_brighter``), else -1."""
        return self.polarity * (1 if door_brighter else -1)


@dataclass(frozen=True)
class Band:
    """Search interval ``[lo, hi]`` (px, along the scan) on each scan line ``scan``."""

    scan: np.ndarray
    lo: np.ndarray
    hi: np.ndarray


@dataclass(frozen=True)
class Track:
    """Scan lines crossing one edge and the predicted edge position on each (px).

    ``beside_far_face``: the door's far face is visible beside this edge (the camera is beyond the far
    face's plane, as for a thin door shifted towards -X); its scan lines are then limited to where the
    far face's band is wide enough for the window, and the edge is measured between the hinge face
    and the far face.
    """

    scan: np.ndarray
    centre: np.ndarray
    beside_far_face: bool = False
    band_px: np.ndarray | None = None  # width of the arris strip / far-face band beside the edge, px
    band_slope: float = 0.0  # change of band_px per px the edge moves outwards (far face: -(1 - k))
    outline_shift_px: np.ndarray | None = (
        None  # arris: sharp corner's line minus the strip's outer border, px
    )
    #: beside the far face, an arris: the strip's width on the hinge-face side of the far face's border, px
    strip_px: np.ndarray | None = None


def _along_scan(uv: np.ndarray, axis: Axis) -> tuple[np.ndarray, np.ndarray]:
    """Split image points into (scan, along) coordinates for ``axis``."""
    return (uv[:, 0], uv[:, 1]) if axis == "col" else (uv[:, 1], uv[:, 0])


def _sorted_polyline(uv: np.ndarray, axis: Axis) -> tuple[np.ndarray, np.ndarray]:
    """The finite points of the polyline ``uv`` as (scan, along), ordered by scan."""
    s, a = _along_scan(uv, axis)
    ok = np.isfinite(s) & np.isfinite(a)
    if not ok.all():
        s, a = s[ok], a[ok]
    # A polyline along an edge is usually monotonic in scan: strictly increasing (or decreasing) keys
    # have one sorted order, the one argsort would give.
    d = np.diff(s)
    if (d > 0).all():
        return s, a
    if (d < 0).all():
        return s[::-1], a[::-1]
    order = np.argsort(s)
    return s[order], a[order]


def _linspace(start: float, stop: float, num: int) -> np.ndarray:
    """``np.linspace(start, stop, num)`` (num >= 2), the same numbers without its generic machinery."""
    step = (stop - start) / (num - 1)
    if step == 0 or not math.isfinite(step):
        return np.linspace(start, stop, num)
    y = np.arange(num, dtype=np.float64) * step
    y += start
    y[-1] = stop
    return y


def _interp_sorted(s: np.ndarray, a: np.ndarray, scans: np.ndarray) -> np.ndarray:
    """Along-coordinate on each scan line of a polyline from :func:`_sorted_polyline` (NaN outside its span)."""
    if s.size < 2:
        return np.full(len(scans), np.nan)
    out = np.interp(scans, s, a)
    return np.where((scans >= s[0]) & (scans <= s[-1]), out, np.nan)


def _interp_on_scans(uv: np.ndarray, axis: Axis, scans: np.ndarray) -> np.ndarray:
    """Along-coordinate of the polyline ``uv`` on each scan line (NaN outside the polyline's span)."""
    out, monotonic = _interp_monotonic(uv, axis == "col", scans)
    if monotonic:
        return out
    s, a = _sorted_polyline(uv, axis)
    return _interp_sorted(s, a, scans)


def _interp_monotonic_warm_up(k) -> None:
    uv = np.column_stack([np.linspace(0.0, 9.0, 10), np.linspace(5.0, 6.0, 10)])
    for pts in (uv, uv[:, ::-1], np.asfortranarray(uv)):
        k(pts, True, np.arange(12))


@kernel(_interp_monotonic_warm_up)
def _interp_monotonic(uv, scan_is_u, scans):
    """:func:`_interp_sorted` of :func:`_sorted_polyline` for a polyline whose finite points are strictly
    monotonic in scan (the usual case: a projected edge), compiled: ``(along on each scan, True)``, or
    ``(anything, False)`` for any other polyline (the caller sorts it).

    The interpolation is np.interp's, operation for operation (the slope of the segment ``s[j] <= x <
    s[j + 1]`` times ``x - s[j]`` plus ``a[j]``; a scan on a point or at the last point takes its value).
    """
    js, ja = (0, 1) if scan_is_u else (1, 0)
    n = uv.shape[0]
    s = np.empty(n)
    a = np.empty(n)
    m = 0
    for i in range(n):
        si, ai = uv[i, js], uv[i, ja]
        if np.isfinite(si) and np.isfinite(ai):
            s[m] = si
            a[m] = ai
            m += 1
    out = np.full(scans.size, np.nan)
    if m < 2:
        return out, True
    up = s[1] > s[0]
    for i in range(m - 1):
        if (s[i + 1] > s[i]) != up or s[i + 1] == s[i]:
            return out, False
    if not up:
        s[:m] = s[:m][::-1].copy()
        a[:m] = a[:m][::-1].copy()
    j = 0
    for i in range(scans.size):
        x = float(scans[i])
        if not (x >= s[0] and x <= s[m - 1]):
            continue
        if x == s[m - 1]:
            out[i] = a[m - 1]
            continue
        while s[j + 1] <= x:  # scans increase: the segment only moves on
            j += 1
        while s[j] > x:  # (unless they do not)
            j -= 1
        if s[j] == x:
            out[i] = a[j]
            continue
        slope = (a[j + 1] - a[j]) / (s[j + 1] - s[j])
        v = slope * (x - s[j]) + a[j]
        if np.isnan(v):
            v = slope * (x - s[j + 1]) + a[j + 1]
            if np.isnan(v) and a[j] == a[j + 1]:
                v = a[j]
        out[i] = v
    return out, True


@dataclass(frozen=True)
class SearchRegion:
    """The search region of one cell and door size.

    Build it with :meth:`build`; it holds the geometry, the edge layouts and the margins.
    """

    posed: PosedCamera
    face_y: float
    edge_depth_y: float
    door: DoorSize
    image_size: tuple[int, int]
    x_range_mm: float
    z_range_mm: float
    yaw_range_rad: float
    layouts: dict[str, EdgeLayout]
    z_top_mm: float
    nominal_scale: float
    plane_map: PlaneMap
    face_map: PlaneMap
    border_px: int = 2
    # Results that depend only on the fields above (bands, maps at other depths), kept for the next
    # image of the same cell and door: see :meth:`cached`.
    _memo: dict[Any, Any] = field(default_factory=dict, compare=False, repr=False)

    def image_points(self, xz: np.ndarray) -> np.ndarray:
        """``(X, Z)`` on the outline plane -> pixels."""
        return self.plane_map.to_image(xz)

    def plane_points(self, uv: np.ndarray) -> np.ndarray:
        """Pixels -> ``(X, Z)`` on the outline plane."""
        return self.plane_map.to_plane(uv)

    @classmethod
    def build(
        cls, cell: Cell, door: DoorSize, margin_mm: float, margin_deg: float, door_brighter: bool = True
    ) -> SearchRegion:
        """Search region for a door of size ``door`` in ``cell``, widened by the margins beyond the envelope."""
        posed = cell.posed_camera
        face_y = cell.face_y(door)
        depth = face_y + door.arris_mm
        pm = PlaneMap(posed, depth)
        o = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
        uv = pm.to_image(o)
        dx, dz = uv[1] - uv[0], uv[2] - uv[0]
        ref_axis: Axis = "row" if abs(dz[1]) >= abs(dz[0]) else "col"
        bot_axis: Axis = "col" if abs(dx[0]) >= abs(dx[1]) else "row"
        sign = 1 if door_brighter else -1
        # Direction of increasing `along` relative to the door interior on each edge.
        x_on_ref = dx[0] if ref_axis == "row" else dx[1]
        z_on_bot = dz[1] if bot_axis == "col" else dz[0]
        layouts = {
            "reference": EdgeLayout("reference", ref_axis, sign * int(np.sign(x_on_ref)), False),
            "far": EdgeLayout("far", ref_axis, -sign * int(np.sign(x_on_ref)), False),
            "bottom": EdgeLayout("bottom", bot_axis, sign * int(np.sign(z_on_bot)), True),
        }
        env = cell.envelope
        w, h = cell.camera.image_size
        # Highest Z of the reference line still inside the image (the door goes beyond it).
        zs = np.arange(0.0, 3000.0, 10.0)
        pts = pm.to_image(np.stack([np.zeros_like(zs), zs], 1))
        inside = (pts[:, 0] >= 0) & (pts[:, 0] <= w - 1) & (pts[:, 1] >= 0) & (pts[:, 1] <= h - 1)
        # The first run from the corner up only: beyond the image a distortion polynomial can fold far
        # points back into it (a barrel k1 < 0 does at large radii).
        leaves = np.flatnonzero(~inside)
        run = inside[: leaves[0]] if leaves.size else inside
        z_top = (
            float(zs[: run.size][run].max())
            if run.any()
            else (float(zs[inside].max()) if inside.any() else 0.0)
        )
        z_top = min(z_top, door.height_mm)
        scale = pm.at_depth(face_y).scale_mm_per_px(np.zeros(2))
        return cls(
            posed,
            face_y,
            depth,
            door,
            (w, h),
            env.x_mm + margin_mm,
            env.z_mm + margin_mm,
            math.radians(env.yaw_deg + margin_deg),
            layouts,
            z_top,
            scale,
            pm,
            pm.at_depth(face_y),
        )

    @classmethod
    def cached(
        cls, cell: Cell, door: DoorSize, margin_mm: float, margin_deg: float, door_brighter: bool = True
    ) -> SearchRegion:
        """:meth:`build`, kept for the next call with the same camera, fixture, envelope, door and margins.

        The key is what :meth:`build` reads (camera matrix, distortion, image size, extrinsics, fixture,
        envelope, door, margins), by value: a cell changed in any of these (a new calibration, a
        ``dataclasses.replace``) gets its own region; the cell file's hash is not enough (a replaced
        camera keeps it). At most 32 regions are kept (least recently used first out).
        """
        key = _RegionKey(
            cell.camera.camera_matrix.tobytes(),
            cell.camera.coeffs12.tobytes(),
            cell.camera.image_size,
            cell.extrinsics.rvec.tobytes(),
            cell.extrinsics.tvec_mm.tobytes(),
            cell.fixture,
            cell.envelope,
            door,
            float(margin_mm),
            float(margin_deg),
            bool(door_brighter),
            cell,
        )
        return _cached_region(key)

    def _memoised(self, key: Any, make: Any) -> Any:
        if key not in self._memo:
            value = make()
            for a in value.__dict__.values() if isinstance(value, Band) else (value,):
                if isinstance(a, np.ndarray):
                    a.setflags(write=False)  # shared by every later call: nobody may change it
            self._memo[key] = value
        return self._memo[key]

    @property
    def nominal_corner_px(self) -> np.ndarray:
        """Pixel of the reference corner of a door at the nominal pose (x = z = 0), on the hinge face."""
        return self._memoised("corner0", lambda: self.face_map.to_image(np.zeros((1, 2)))[0])

    # -- search region for the coarse pass -------------------------------------------------------
    def _scans_between(self, uv: np.ndarray, axis: Axis, step: int) -> np.ndarray:
        s, _ = _along_scan(uv, axis)
        n = self.image_size[0] if axis == "col" else self.image_size[1]
        lo = max(int(math.ceil(np.nanmin(s))), self.border_px)
        hi = min(int(math.floor(np.nanmax(s))), n - 1 - self.border_px)
        return np.arange(lo, hi + 1, step)

    def arris_band(self, step: int = 2, height_mm: float = 60.0, start_mm: float = 0.0) -> Band:
        """Where the reference arris can be, on scan lines safely above any possible bottom end.

        Only ``height_mm`` of the arris above the highest possible bottom end (and ``start_mm`` above that)
        is searched: enough for a coarse line, and the band stays narrow (yaw widens it with height).
        """
        return self._memoised(
            ("arris_band", step, height_mm, start_mm), lambda: self._arris_band(step, height_mm, start_mm)
        )

    def _arris_band(self, step: int, height_mm: float, start_mm: float = 0.0) -> Band:
        lay = self.layouts["reference"]
        t = math.tan(self.yaw_range_rad)
        z_lo = self.z_range_mm + (self.door.thickness_mm + self.x_range_mm) * t + 3.0 + start_mm
        z_hi = max(min(self.z_top_mm, z_lo + height_mm), z_lo + 1.0)
        zs = np.linspace(z_lo, z_hi, 24)
        half = self.x_range_mm + (np.abs(zs) + self.z_range_mm) * t
        uv_lo = self.image_points(np.stack([-half, zs], 1))
        uv_hi = self.image_points(np.stack([half, zs], 1))
        scans = self._scans_between(np.vstack([uv_lo, uv_hi]), lay.axis, step)
        a1 = _interp_on_scans(uv_lo, lay.axis, scans)
        a2 = _interp_on_scans(uv_hi, lay.axis, scans)
        return self._band(scans, a1, a2, lay.axis)

    def bottom_band(self, scans: np.ndarray) -> Band:
        """Where the bottom end can be on the given scan lines."""
        lay = self.layouts["bottom"]
        lines = self._memoised("bottom_lines", self._bottom_lines)
        (s_lo, a_lo), (s_hi, a_hi) = lines
        a1 = _interp_sorted(s_lo, a_lo, scans)
        a2 = _interp_sorted(s_hi, a_hi, scans)
        return self._band(np.asarray(scans), a1, a2, lay.axis)

    def _bottom_lines(self) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
        # The two lines that bound the bottom end (the same for every image), ready for _interp_sorted.
        lay = self.layouts["bottom"]
        t = math.tan(self.yaw_range_rad)
        xs = np.linspace(-self.x_range_mm - 30.0, self.x_range_mm + self.door.thickness_mm + 30.0, 48)
        half = self.z_range_mm + (np.abs(xs) + self.x_range_mm) * t
        uv_lo = self.image_points(np.stack([xs, -half], 1))
        uv_hi = self.image_points(np.stack([xs, half], 1))
        return _sorted_polyline(uv_lo, lay.axis), _sorted_polyline(uv_hi, lay.axis)

    def _band(self, scans: np.ndarray, a1: np.ndarray, a2: np.ndarray, axis: Axis) -> Band:
        n_along = self.image_size[1] if axis == "col" else self.image_size[0]
        ok = np.isfinite(a1) & np.isfinite(a2)
        lo = np.clip(np.floor(np.minimum(a1, a2)), self.border_px, n_along - 1 - self.border_px)
        hi = np.clip(np.ceil(np.maximum(a1, a2)), self.border_px, n_along - 1 - self.border_px)
        ok &= hi - lo >= 4
        return Band(scans[ok].astype(int), lo[ok].astype(int), hi[ok].astype(int))

    # -- tracks for the sub-pixel passes ---------------------------------------------------------
    def far_face_visible(
        self, corner: np.ndarray, yaw_rad: float, thickness_mm: float, margin_mm: float = 1.0
    ) -> bool:
        """True when the camera centre lies beyond the far face's plane (that face is then in view), or
        within ``margin_mm`` of it: the thickness being measured decides, so the answer must not flip
        between passes for a face seen nearly edge-on."""
        u_c, u_ref = self._along_door_x(corner, yaw_rad)
        return u_c > u_ref + thickness_mm - margin_mm

    def _along_door_x(self, corner: np.ndarray, yaw_rad: float) -> tuple[float, float]:
        """The camera centre's and the reference corner's coordinates along door +X (cell X-Z plane), mm."""
        n = np.array([math.cos(yaw_rad), math.sin(yaw_rad)])
        return float(n @ self.plane_map.centre[[0, 2]]), float(n @ np.asarray(corner, float))

    def _back_edge_ratio(self, near_depth_y: float) -> float:
        """How much less than on the plane at ``near_depth_y`` a shift along X moves the far face's back edge
        (depth ``face_y + W``) seen through the camera: the ratio of the two depths from it."""
        c_y = self.plane_map.centre[1]
        return (near_depth_y - c_y) / (self.face_y + self.door.width_mm - c_y)

    def thickness_behind_far_face(
        self, corner: np.ndarray, yaw_rad: float, measured_mm: float
    ) -> float | None:
        """The door thickness whose far face's back edge lies ``measured_mm`` beyond the reference arris.

        Seen from beyond the far face's plane, that face is a band beside the far arris whose back edge (at
        the depth ``face_y + W``) projects onto the hinge-face plane at ``u_c + k (u_far - u_c)``, ``k`` the
        ratio of the two depths from the camera. A step found there instead of at the far arris (a far face
        as bright as the hinge face) measures that much more. None where no far face would be in view.
        """
        u_c, u_ref = self._along_door_x(corner, yaw_rad)
        k = self._back_edge_ratio(self.plane_map.depth_y)
        u_far = u_c + (u_ref + measured_mm - u_c) / k
        return u_far - u_ref if u_far < u_c and k > 0 else None

    def tracks(
        self,
        corner: np.ndarray,
        yaw_rad: float,
        thickness_mm: float,
        keep_px: float,
        window_px: float = 0.0,
        arris: dict | None = None,
        visibility_thickness_mm: float | None = None,
    ) -> dict[str, Track]:
        """Scan lines across each edge of a door at this pose, and the predicted edge on each.

        Scan lines closer than ``keep_px`` to the other edges (the corners) or to the image border
        are left out: there the profile is not a clean straight step. ``arris`` (edge name ->
        :class:`doorloc.vision.arris_model.ArrisGeometry`) places an arris strip exactly: the predicted
        edge is then the strip's outer border, and ``outline_shift_px`` moves it to the sharp corner's line.
        ``visibility_thickness_mm`` (default ``thickness_mm``) is the thickness that decides whether the far
        face is in view.
        """
        ex = np.array([math.cos(yaw_rad), math.sin(yaw_rad)])
        ez = np.array([-math.sin(yaw_rad), math.cos(yaw_rad)])
        corner = np.asarray(corner, float)
        far_corner = corner + thickness_mm * ex
        out: dict[str, Track] = {}
        tz = self._memoised(
            "track_tz",
            lambda: np.linspace(0.0, self.z_top_mm + 40.0, max(int((self.z_top_mm + 40.0) / 2.0), 8)),
        )
        tx = _linspace(-1.0, thickness_mm + 1.0, max(int(thickness_mm / 2.0), 8))
        polylines = {
            "bottom": corner[None] + tx[:, None] * ex[None],
            "reference": corner[None] + tz[:, None] * ez[None],
            "far": far_corner[None] + tz[:, None] * ez[None],
        }
        # every point projected in one call (the projection is point by point: the same numbers)
        uv_all = self.image_points(np.vstack([*polylines.values(), corner[None], far_corner[None]]))
        uv_ends = uv_all[-2:]  # corner, far corner
        first = 0
        for name in EDGE_NAMES:
            lay = self.layouts[name]
            pl = polylines[name]
            uv = uv_all[first : first + len(pl)]
            first += len(pl)
            scans, centre, ok = self._scan_lines(name, uv, uv_ends, keep_px)
            beside = name == "far" and self.far_face_visible(
                corner, yaw_rad, thickness_mm if visibility_thickness_mm is None else visibility_thickness_mm
            )
            band = None
            slope = 0.0
            if beside:
                _, a_ends = _along_scan(uv_ends, lay.axis)
                outward = 1.0 if a_ends[1] >= a_ends[0] else -1.0  # door +X, along the scan line
                ok_band, width = self._far_face_band(pl, uv, scans, centre, window_px, lay.axis, outward)
                ok &= ok_band
                band = width[ok]
                # The band's outer edge (the far face's back edge) is W farther away: it moves k times
                # as far as the arris when the thickness changes.
                slope = -(1.0 - self._back_edge_ratio(self.face_y))
            a = self.door.arris_mm
            shift = None
            strip = None
            if a > 0 and not beside and arris is not None and name in arris:
                inward = ez if name == "bottom" else (ex if name == "reference" else -ex)
                ok, centre, band, shift = self._strip_borders(
                    pl, lay.axis, scans, centre, ok, inward, arris[name]
                )
            elif a > 0:
                # The arris strip runs from the outline (depth face_y + a) to the hinge face's own edge,
                # a mm inwards at depth face_y. Beside the far face it lies between the hinge face and the
                # far face, which begins at the outline (on its plane): the far-face fit takes its width.
                inward = ez if name == "bottom" else (ex if name == "reference" else -ex)
                inner = self.face_map.to_image(pl + a * inward[None])
                width = np.abs(_interp_on_scans(inner, lay.axis, scans[ok]) - centre[ok])
                if beside:
                    strip = width
                else:
                    band = width
            out[name] = Track(scans[ok], centre[ok], beside, band, slope, shift, strip)
        return out

    def _scan_lines(
        self, name: str, uv: np.ndarray, uv_ends: np.ndarray, keep_px: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The scan lines across the edge ``name`` whose image polyline is ``uv`` (px), ``uv_ends`` the image
        corner and far corner: ``(scans, centre, ok)``, the integer scan lines between the corners
        (``keep_px`` inside them) and the image border, the predicted edge on each (px along the scan line)
        and where it lies inside the image."""
        lay = self.layouts[name]
        s, _ = _along_scan(uv, lay.axis)
        n_scan = self.image_size[0] if lay.axis == "col" else self.image_size[1]
        n_along = self.image_size[1] if lay.axis == "col" else self.image_size[0]
        e_uv = uv_ends if name == "bottom" else uv_ends[[0, 0]] if name == "reference" else uv_ends[[1, 1]]
        e_s, _ = _along_scan(e_uv, lay.axis)
        if name == "bottom":
            s_lo, s_hi = np.sort(e_s)
            s_lo, s_hi = s_lo + keep_px, s_hi - keep_px
        else:
            # From the corner towards the door's far end (the direction of increasing tz).
            d = np.sign(s[-1] - s[0]) or 1.0
            if d > 0:
                s_lo, s_hi = e_s[0] + keep_px, np.fmax.reduce(s)  # = np.nanmax, less dispatch
            else:
                s_lo, s_hi = np.fmin.reduce(s), e_s[0] - keep_px
        s_lo = max(s_lo, self.border_px)
        s_hi = min(s_hi, n_scan - 1 - self.border_px)
        scans = np.arange(int(math.ceil(s_lo)), int(math.floor(s_hi)) + 1)
        centre = _interp_on_scans(uv, lay.axis, scans)
        ok = np.isfinite(centre) & (centre >= 0) & (centre <= n_along - 1)
        return scans, centre, ok

    def _strip_borders(
        self,
        pl: np.ndarray,
        axis: Axis,
        scans: np.ndarray,
        centre: np.ndarray,
        ok: np.ndarray,
        inward: np.ndarray,
        g: ArrisGeometry,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """An arris strip placed exactly by its geometry ``g`` on the edge's polyline ``pl`` (cell X-Z on the
        hinge-face plane, mm; ``inward`` the unit direction into the hinge face):
        ``(ok, centre, band, shift)``, the scan lines kept (both borders in view), the predicted edge moved to
        the strip's outer border (px), the strip's width and the sharp corner's line minus the outer border on
        the kept lines, px."""
        nominal = centre[ok]
        outer = _interp_on_scans(self.image_points(pl + g.w_outer_mm * inward[None]), axis, scans[ok])
        inner = _interp_on_scans(self.image_points(pl + g.w_inner_mm * inward[None]), axis, scans[ok])
        good = np.isfinite(outer) & np.isfinite(inner)
        sel = np.nonzero(ok)[0][good]
        ok = np.zeros_like(ok)
        ok[sel] = True
        centre = centre.copy()
        centre[sel] = outer[good]
        band = np.abs(inner[good] - outer[good])
        shift = nominal[good] - outer[good]
        return ok, centre, band, shift

    def _far_face_band(
        self, pl, uv, scans, centre, window_px, axis, outward: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Scan lines beside the visible far face (above its bottom edge) and the face's band width there, px.

        The width is signed: positive where the band lies beyond the arris (``outward``, door +X along the
        scan line); <= 0 where the far face is seen edge-on or from behind (no band in view).
        """
        back = self._memoised("back_map", lambda: self.plane_map.at_depth(self.face_y + self.door.width_mm))
        # The far face's back edge: the same (X, Z) line at the door's far side, seen smaller (farther):
        # extend it up the door so that it spans the image.
        d = pl[-1] - pl[0]
        t = np.linspace(0.0, max(self.door.height_mm / max(float(np.hypot(*d)), 1e-9), 1.0), 200)
        uv_back = back.to_image(pl[0][None] + t[:, None] * d[None])
        band = (_interp_on_scans(uv_back, axis, scans) - centre) * outward
        # Below the far face's bottom edge (it rises towards the back) there is no band.
        s_corner, _ = _along_scan(uv[:1], axis)
        s_back, _ = _along_scan(uv_back[:1], axis)
        d = np.sign(s_back[0] - s_corner[0])
        above = (scans - s_back[0]) * d >= window_px if d != 0 else np.ones(scans.size, bool)
        return above & np.isfinite(band), np.where(np.isfinite(band), band, 0.0)


@dataclass(frozen=True)
class _RegionKey:
    """What :meth:`SearchRegion.build` depends on, by value; ``cell`` (not compared) builds the first one."""

    camera_matrix: bytes
    dist_coeffs: bytes
    image_size: tuple[int, int]
    rvec: bytes
    tvec: bytes
    fixture: Fixture
    envelope: Envelope
    door: DoorSize
    margin_mm: float
    margin_deg: float
    door_brighter: bool
    cell: Cell = field(compare=False, hash=False)


@functools.lru_cache(maxsize=32)
def _cached_region(key: _RegionKey) -> SearchRegion:
    return SearchRegion.build(key.cell, key.door, key.margin_mm, key.margin_deg, key.door_brighter)
