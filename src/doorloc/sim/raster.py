"""Exact, area-correct rasterisation of planar surfaces through the OpenCV camera model.

The renderer works in the camera's *ideal* normalized image plane (``(x, y) = (X/Z, Y/Z)``, before
distortion), where a planar polygon projects to a polygon with straight edges and a point on a plane
maps to the plane's own coordinates by a homography. The sensor, however, integrates light over a
unit box in the *distorted* pixel plane. Each pixel's value is therefore the average of the scene over
its box footprint, mapped to the ideal plane through the undistortion:

1. every pixel centre gets an (approximate) ideal coordinate: exact when there is no distortion,
   else Newton on a coarse grid and bilinear interpolation (error ~1e-3 px, used only to tell which
   region a pixel centre lies in and to evaluate smooth shading);
2. pixels whose 3x3 neighbourhood sees more than one region (face, texture colour) are *boundary
   pixels*; for them the ideal coordinate ``q0`` and the Jacobian ``J = dq/d(u, v)`` are computed
   exactly (Newton to 1e-10), so the footprint is the parallelogram ``q0 + J @ delta``,
   ``delta in [-1/2, 1/2]^2`` (its curvature over one pixel is ~1e-5 px);
3. a boundary pixel crossed by one straight boundary gets the analytic box coverage of a half-plane
   (:func:`box_coverage`), which is exact for a box filter; a pixel where two or more boundaries meet
   (polygon vertices, checker corners) is split into 4 x 4 sub-boxes through the same affine footprint
   map and each is treated the same way, twice over; the few 1/16-px boxes that still hold a vertex are
   point-sampled (no per-sample undistortion anywhere).

Scene model: a list of *foreground* surfaces whose visible regions are disjoint convex polygons (the
front faces of a convex solid, or one board) in front of an unbounded *background* surface. Each surface
carries a piecewise-constant texture on a rectilinear grid of its own plane coordinates
(:class:`GridTexture`), a constant shade and an optional smooth multiplicative modulation (wood grain).

Frames: camera frame of OpenCV (mm); surface coordinates ``(s, t)`` in mm along two orthonormal axes of
the plane. Pixel coordinates: origin at the centre of the top-left pixel.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from doorloc.calib.camera import CameraModel

__all__ = [
    "GridTexture",
    "Surface",
    "box_coverage",
    "render_radiance",
    "paint_rectangles",
]

_COARSE_STEP = 8  # px between exact undistortion samples for the approximate per-pixel ideal map
NEAR_MM = 1.0  # surfaces are clipped to Z >= NEAR_MM in the camera frame
#: an outline's edges shorter than this fraction of its extent (ideal plane) are dropped (see :func:`_prepare`)
EDGE_TOLERANCE = 1e-9


# ----------------------------------------------------------------------------------------------
# textures
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class GridTexture:
    """Piecewise-constant reflectance on a rectilinear grid of plane coordinates.

    Cell ``(i, j)`` covers ``s_lines[i-1] <= s < s_lines[i]`` and ``t_lines[j-1] <= t < t_lines[j]``
    (open-ended at the first and last lines).

    Attributes
    ----------
    s_lines, t_lines : ndarray, shapes (ns,), (nt,)
        Sorted grid-line positions along s and t, mm.
    values : ndarray, shape (ns + 1, nt + 1)
        Reflectance of each cell (relative; multiplied by the surface shade).
    exact_s : bool
        A *strip*: a texture of many close s-lines and no t-lines whose first and last cells are 0 and
        lie outside the surface (its outline's edges along t are the first and last lines). Its pixels
        are box-filtered exactly whatever number of lines crosses them (a sum of half-plane coverages,
        :func:`_strip_state`), the outline's edges along t included; only where another outline edge
        crosses a pixel is it subdivided. Used for the shading across a rounded arris.
    """

    s_lines: np.ndarray
    t_lines: np.ndarray
    values: np.ndarray
    exact_s: bool = False
    codes: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        s = np.asarray(self.s_lines, float).ravel()
        t = np.asarray(self.t_lines, float).ravel()
        v = np.asarray(self.values, float).reshape(s.size + 1, t.size + 1)
        if np.any(np.diff(s) <= 0) or np.any(np.diff(t) <= 0):
            raise ValueError("texture grid lines must be strictly increasing")
        _, codes = np.unique(v, return_inverse=True)
        object.__setattr__(self, "s_lines", s)
        object.__setattr__(self, "t_lines", t)
        object.__setattr__(self, "values", v)
        object.__setattr__(self, "codes", codes.reshape(v.shape).astype(np.int32))

    @classmethod
    def uniform(cls, value: float = 1.0) -> GridTexture:
        return cls(np.empty(0), np.empty(0), np.array([[value]]))

    def cells(self, s: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cell indices ``(i, j)`` of plane points, same shapes as ``s``, ``t``."""
        return np.searchsorted(self.s_lines, s, side="right"), np.searchsorted(self.t_lines, t, side="right")

    def lookup(self, s: np.ndarray, t: np.ndarray) -> np.ndarray:
        i, j = self.cells(s, t)
        return self.values[i, j]


def paint_rectangles(base: float, rectangles: list[tuple[float, float, float, float, float]]) -> GridTexture:
    """A :class:`GridTexture` of value ``base`` with axis-aligned rectangles painted on top in order.

    ``rectangles``: ``(s0, s1, t0, t1, value)`` each, mm; later ones cover earlier ones. Unbounded
    sides may use ``-inf``/``inf``.
    """
    s_lines = sorted({v for r in rectangles for v in r[:2] if np.isfinite(v)})
    t_lines = sorted({v for r in rectangles for v in r[2:4] if np.isfinite(v)})
    s_c = _cell_centres(np.array(s_lines))
    t_c = _cell_centres(np.array(t_lines))
    vals = np.full((s_c.size, t_c.size), float(base))
    S, T = np.meshgrid(s_c, t_c, indexing="ij")
    for s0, s1, t0, t1, value in rectangles:
        vals[(S > s0) & (S < s1) & (T > t0) & (T < t1)] = value
    return GridTexture(np.array(s_lines), np.array(t_lines), vals)


def _cell_centres(lines: np.ndarray) -> np.ndarray:
    if lines.size == 0:
        return np.zeros(1)
    return np.concatenate([[lines[0] - 1.0], 0.5 * (lines[1:] + lines[:-1]), [lines[-1] + 1.0]])


# ----------------------------------------------------------------------------------------------
# surfaces
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Surface:
    """A textured plane in the camera frame, optionally bounded by a convex polygon.

    A plane point with surface coordinates ``(s, t)`` (mm) is ``origin + s * s_axis + t * t_axis``
    (camera frame, mm; the axes orthonormal).

    Attributes
    ----------
    origin, s_axis, t_axis : ndarray, shape (3,)
        Camera-frame plane origin (mm) and unit in-plane axes.
    polygon_st : ndarray, shape (m, 2), or None
        Convex outline in surface coordinates (any orientation); None for an unbounded background.
    texture : GridTexture
        Piecewise-constant reflectance.
    shade : float
        Radiance factor (albedo times lighting) multiplying the texture.
    modulation : callable or None
        Smooth multiplicative pattern ``f(s, t) -> array`` (e.g. wood grain), evaluated per pixel centre.
    name : str
        For diagnostics.
    """

    origin: np.ndarray
    s_axis: np.ndarray
    t_axis: np.ndarray
    polygon_st: np.ndarray | None = None
    texture: GridTexture = field(default_factory=GridTexture.uniform)
    shade: float = 1.0
    modulation: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None
    name: str = ""

    @property
    def plane_to_ideal(self) -> np.ndarray:
        """3x3 homography ``(s, t, 1) -> (x, y, 1)`` (ideal normalized), up to scale."""
        return np.column_stack([self.s_axis, self.t_axis, self.origin]).astype(float)

    @property
    def ideal_to_plane(self) -> np.ndarray:
        return np.linalg.inv(self.plane_to_ideal)

    def polygon_cam(self) -> np.ndarray:
        """Outline vertices in the camera frame, shape (m, 3), mm."""
        p = np.asarray(self.polygon_st, float)
        return self.origin + p[:, :1] * self.s_axis + p[:, 1:] * self.t_axis

    def visible_polygon_cam(self, z_near: float = NEAR_MM) -> np.ndarray:
        """The outline clipped to the half-space in front of the camera (``Z >= z_near``), shape (k, 3).

        A long face (the door's 2 m hinge face seen by a tilted camera) may reach behind the camera;
        only its part in front can be imaged, and that part projects to a proper convex polygon.
        """
        v = self.polygon_cam()
        if np.all(v[:, 2] >= z_near):
            return v
        out = []
        for k in range(len(v)):
            p, q = v[k], v[(k + 1) % len(v)]
            dp, dq = p[2] - z_near, q[2] - z_near
            if dp >= 0:
                out.append(p)
            if (dp < 0 <= dq) or (dq < 0 <= dp):
                if dp != dq:
                    out.append(p + (q - p) * (dp / (dp - dq)))
        return np.array(out).reshape(-1, 3)


@dataclass(frozen=True)
class _Prepared:
    """A surface ready for rasterisation: homography and the ideal-plane edge lines of its outline."""

    surface: Surface
    H: np.ndarray  # ideal (x, y, 1) -> plane (s, t, w)
    normals: np.ndarray  # (m, 2) unit inward normals of outline edges in the ideal plane
    offsets: np.ndarray  # (m,)   inside: normals @ q >= offsets
    label_base: int
    s_const: np.ndarray | None = None  # (m,) edges along which s is constant (strips only)


def _prepare(surface: Surface, label_base: int) -> _Prepared:
    H = surface.ideal_to_plane
    if surface.polygon_st is None:
        return _Prepared(surface, H, np.zeros((0, 2)), np.zeros(0), label_base)
    v = surface.visible_polygon_cam()
    if len(v) < 3:  # wholly behind the camera: nothing can be inside
        return _Prepared(surface, H, np.array([[1.0, 0.0], [-1.0, 0.0]]), np.array([1.0, 1.0]), label_base)
    q = v[:, :2] / v[:, 2:]
    area2 = np.sum(q[:, 0] * np.roll(q[:, 1], -1) - np.roll(q[:, 0], -1) * q[:, 1])
    e = np.roll(q, -1, axis=0) - q
    n = np.stack([-e[:, 1], e[:, 0]], axis=1) * (1.0 if area2 > 0 else -1.0)  # inward for either orientation
    norm = np.linalg.norm(n, axis=1)
    # An edge a rounding error long (a vertex the clipping by three planes met at twice: the far face's
    # top corner of a door with arrises, 4e-15 apart) has a direction of rounding noise, and its half-plane
    # through that vertex cut the face across the image (the far face's band, 11 px wide, ended 4-11 px
    # early at some poses and not at others 1e-5 deg apart). Such an edge bounds nothing: the outline is
    # the same without it. Kept: edges longer than EDGE_TOLERANCE of the outline's extent, whose
    # directions are good to 1e-7 rad.
    keep = norm > EDGE_TOLERANCE * max(float(np.ptp(q[:, 0])), float(np.ptp(q[:, 1])), 1e-300)
    n = n[keep] / norm[keep, None]
    c = np.sum(n * q[keep], axis=1)
    s_const = None
    if surface.texture.exact_s:
        s_v, _, _ = _plane_coords(H, q)
        span = float(np.ptp(s_v)) or 1.0
        s_const = (np.abs(np.roll(s_v, -1) - s_v) < 1e-9 * span + 1e-12)[keep]
    return _Prepared(surface, H, n, c, label_base, s_const)


# ----------------------------------------------------------------------------------------------
# coverage
# ----------------------------------------------------------------------------------------------
def box_coverage(m: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Area of the unit pixel box ``[-1/2, 1/2]^2`` where ``m . delta <= d``.

    Parameters
    ----------
    m : ndarray, shape (..., 2)
        Unit normals (any direction) of the half-planes, in pixel units.
    d : ndarray, shape (...)
        Signed offsets, px.

    Returns
    -------
    ndarray, shape (...)
        Covered fraction in [0, 1]: the CDF at ``d`` of ``m . delta`` for ``delta`` uniform in the box,
        i.e. of the sum of two centred uniforms of widths ``|mx|`` and ``|my|``.

    Examples
    --------
    >>> float(box_coverage(np.array([1.0, 0.0]), np.array(0.25)))
    0.75
    >>> round(float(box_coverage(np.array([0.6, 0.8]), np.array(0.0))), 12)
    0.5
    """
    a = np.abs(m[..., 0])
    b = np.abs(m[..., 1])
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    t = d + 0.5 * (lo + hi)

    def r2(x):
        return np.square(np.maximum(x, 0.0))

    with np.errstate(divide="ignore", invalid="ignore"):
        general = (r2(t) - r2(t - lo) - r2(t - hi) + r2(t - lo - hi)) / (2.0 * lo * hi)
        thin = (t - 0.5 * lo) / hi  # lo ~ 0: the box seen edge-on along one axis
    out = np.where(lo > 1e-7, general, thin)
    return np.clip(out, 0.0, 1.0)


# ----------------------------------------------------------------------------------------------
# ideal coordinates of pixels
# ----------------------------------------------------------------------------------------------
def _kinv2(camera: CameraModel) -> np.ndarray:
    """d(distorted normalized)/d(u, v), shape (2, 2)."""
    fx, fy, s = camera.fx, camera.fy, camera.skew
    return np.array([[1.0 / fx, -s / (fx * fy)], [0.0, 1.0 / fy]])


def approximate_ideal_grid(camera: CameraModel) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Ideal normalized coordinates of every pixel centre: ``(x, y, finite)``, float32 arrays (H, W).

    Exact (to float32) without distortion, where ``finite`` is None (every pixel has a ray). With
    distortion: exact Newton undistortion on a grid every ``_COARSE_STEP`` px, bilinear interpolation in
    between (~1e-3 px for ordinary lenses); ``finite`` marks pixels the model can invert.
    Used only to tell which region a pixel centre lies in and for smooth shading.
    """
    import cv2

    w, h = camera.image_size
    if not np.any(camera.coeffs12):
        xv = ((np.arange(h) - camera.cy) / camera.fy).astype(np.float32)
        xu = ((np.arange(w) - camera.cx) / camera.fx).astype(np.float32)
        x = np.broadcast_to(xu[None, :], (h, w))
        if camera.skew:
            x = x - np.float32(camera.skew / camera.fx) * xv[:, None]
        return x, np.broadcast_to(xv[:, None], (h, w)), None
    st = _COARSE_STEP
    # cv2.resize by an integer factor st samples source cell i at destination st*i + (st-1)/2; put the
    # coarse samples there, with one extra row/column before the image so the border is interpolated
    # rather than clamped, and crop.
    nu = -(-(w + 2 * st) // st)
    nv = -(-(h + 2 * st) // st)
    gu = st * np.arange(nu) + (st - 1) / 2 - st
    gv = st * np.arange(nv) + (st - 1) / 2 - st
    G = np.stack(np.meshgrid(gu, gv, indexing="xy"), axis=-1)
    Q = camera.undistort(G)
    finite_c = np.all(np.isfinite(Q), axis=-1)
    Q = np.where(finite_c[..., None], Q, 0.0).astype(np.float32)
    full = cv2.resize(Q, (nu * st, nv * st), interpolation=cv2.INTER_LINEAR)[st : st + h, st : st + w]
    if finite_c.all():
        finite = None
    else:
        # a pixel is usable only if every coarse sample it interpolates from is
        bad = cv2.dilate(
            cv2.resize((~finite_c).astype(np.uint8), (nu * st, nv * st), interpolation=cv2.INTER_NEAREST),
            np.ones((2 * st + 1, 2 * st + 1), np.uint8),
        )
        finite = bad[st : st + h, st : st + w] == 0
    return np.ascontiguousarray(full[..., 0]), np.ascontiguousarray(full[..., 1]), finite


def exact_ideal_and_jacobian(camera: CameraModel, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact ideal coordinates of pixels and the Jacobian ``dq/d(u, v)``.

    Shapes ``(n, 2) -> (n, 2), (n, 2, 2)``; NaN where the distortion cannot be inverted.
    """
    kinv = _kinv2(camera)
    xd = camera.pixel_to_normalized_distorted(uv)
    if not np.any(camera.coeffs12):
        return xd, np.broadcast_to(kinv, (uv.shape[0], 2, 2)).copy()
    q = camera.undistort_normalized(xd)
    # d(distort)/dq at the solution; the inverse maps sensor steps to ideal steps.
    _, jd = camera.distort_with_jacobian(np.nan_to_num(q))
    det = jd[:, 0, 0] * jd[:, 1, 1] - jd[:, 0, 1] * jd[:, 1, 0]
    inv = np.empty_like(jd)
    inv[:, 0, 0] = jd[:, 1, 1] / det
    inv[:, 1, 1] = jd[:, 0, 0] / det
    inv[:, 0, 1] = -jd[:, 0, 1] / det
    inv[:, 1, 0] = -jd[:, 1, 0] / det
    J = inv @ kinv
    J[~np.all(np.isfinite(q), axis=1)] = np.nan
    return q, J


# ----------------------------------------------------------------------------------------------
# rendering
# ----------------------------------------------------------------------------------------------
def _plane_coords(H: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(s, t) of ideal points ``q`` (..., 2) and the homogeneous denominator."""
    x, y = q[..., 0], q[..., 1]
    w = H[2, 0] * x + H[2, 1] * y + H[2, 2]
    s = (H[0, 0] * x + H[0, 1] * y + H[0, 2]) / w
    t = (H[1, 0] * x + H[1, 1] * y + H[1, 2]) / w
    return s, t, w


def _plane_coords_xy(H: np.ndarray, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(s, t) of ideal points given as separate coordinate arrays."""
    w = H[2, 0] * x + H[2, 1] * y + H[2, 2]
    return (H[0, 0] * x + H[0, 1] * y + H[0, 2]) / w, (H[1, 0] * x + H[1, 1] * y + H[1, 2]) / w


def _pixel_bbox(camera: CameraModel, prep: _Prepared, margin: int = 3) -> tuple[int, int, int, int]:
    """Pixel bounding box (v0, v1, u0, u1) of a bounded surface's outline, clipped to the image."""
    w, h = camera.image_size
    if prep.surface.polygon_st is None:
        return 0, h, 0, w
    v = prep.surface.visible_polygon_cam()
    if len(v) < 3:
        return 0, 0, 0, 0
    q = v[:, :2] / v[:, 2:]
    # The distorted outline is curved: sample each edge densely before distorting it.
    f = np.linspace(0.0, 1.0, 257)[:, None, None]
    pts = (q[None] * (1 - f) + np.roll(q, -1, axis=0)[None] * f).reshape(-1, 2)
    uv = camera.normalized_to_pixel(camera.distort(pts))
    uv = uv[np.all(np.isfinite(uv), axis=1)]
    if uv.size == 0:
        return 0, 0, 0, 0
    u0 = int(np.clip(np.floor(uv[:, 0].min()) - margin, 0, w))
    u1 = int(np.clip(np.ceil(uv[:, 0].max()) + margin + 1, 0, w))
    v0 = int(np.clip(np.floor(uv[:, 1].min()) - margin, 0, h))
    v1 = int(np.clip(np.ceil(uv[:, 1].max()) + margin + 1, 0, h))
    return v0, v1, u0, u1


def render_radiance(
    camera: CameraModel,
    foreground: list[Surface],
    background: Surface | float,
    *,
    supersample: int = 4,
    subdivisions: int = 2,
    return_labels: bool = False,
):
    """Render the box-filtered radiance of a scene, float64 image of shape (H, W).

    Parameters
    ----------
    camera : CameraModel
        Intrinsics and distortion; the image is ``camera.image_size``.
    foreground : list of Surface
        Bounded surfaces in the camera frame whose projections are disjoint (front faces of one convex
        solid, or a board); parts behind the camera are clipped away.
    background : Surface or float
        Unbounded surface behind everything (or a constant radiance).
    supersample : int
        Point samples per side in the smallest sub-boxes where two or more boundaries meet.
    subdivisions : int
        Levels of 4 x 4 splitting of such pixels before point sampling (see :func:`_subdivide`).
    return_labels : bool
        Also return the int32 region label of each pixel centre (-1 background, else foreground
        index * 1_000_000 + colour code) and the boolean boundary-pixel mask.

    Returns
    -------
    ndarray, shape (H, W), float64
        Radiance (shade x texture x modulation) averaged over each pixel's box footprint; 0 where the
        camera model cannot tell a pixel's ray.
    """
    import cv2

    w, h = camera.image_size
    if isinstance(background, Surface):
        bg = _prepare(background, -1)
    else:
        bg = _prepare(
            Surface(
                np.array([0.0, 0.0, 1e9]),
                np.array([1.0, 0, 0]),
                np.array([0, 1.0, 0]),
                None,
                GridTexture.uniform(1.0),
                float(background),
                None,
                "background",
            ),
            -1,
        )
    preps = [_prepare(s, i) for i, s in enumerate(foreground)]

    qx, qy, finite = approximate_ideal_grid(camera)

    label = np.empty((h, w), np.int32)
    value = np.empty((h, w), np.float64)
    # background first, over the whole image
    bg_tex = bg.surface.texture
    if bg_tex.s_lines.size == 0 and bg_tex.t_lines.size == 0 and bg.surface.modulation is None:
        label[:] = -1
        value[:] = bg.surface.shade * bg_tex.values[0, 0]
    else:
        s, t = _plane_coords_xy(bg.H, qx, qy)
        i, j = bg_tex.cells(s, t)
        label[:] = -1 - bg_tex.codes[i, j]
        value[:] = bg.surface.shade * bg_tex.values[i, j]
        if bg.surface.modulation is not None:
            value *= bg.surface.modulation(s, t)
        del s, t, i, j
    for p in preps:
        v0, v1, u0, u1 = _pixel_bbox(camera, p)
        if v1 <= v0 or u1 <= u0:
            continue
        x, y = qx[v0:v1, u0:u1], qy[v0:v1, u0:u1]
        inside = np.ones(x.shape, bool)
        for n, c in zip(p.normals, p.offsets, strict=True):
            inside &= x * np.float32(n[0]) + y * np.float32(n[1]) >= np.float32(c)
        if finite is not None:
            inside &= finite[v0:v1, u0:u1]
        if not inside.any():
            continue
        s, t = _plane_coords_xy(p.H, x[inside].astype(np.float64), y[inside].astype(np.float64))
        i, j = p.surface.texture.cells(s, t)
        val = p.surface.shade * p.surface.texture.values[i, j]
        if p.surface.modulation is not None:
            val = val * p.surface.modulation(s, t)
        label[v0:v1, u0:u1][inside] = p.label_base * 1_000_000 + p.surface.texture.codes[i, j]
        value[v0:v1, u0:u1][inside] = val
    if finite is not None:
        value[~finite] = 0.0
        label[~finite] = np.iinfo(np.int32).min
    else:
        finite = np.ones((h, w), bool)

    # boundary pixels: a 4-neighbour lies in another region; dilated by two pixels, which covers diagonal
    # neighbours and the approximate ray map's error with a wide margin
    diff = np.zeros((h, w), np.uint8)
    dh = label[:, 1:] != label[:, :-1]
    dv = label[1:, :] != label[:-1, :]
    diff[:, 1:] |= dh
    diff[:, :-1] |= dh
    diff[1:, :] |= dv
    diff[:-1, :] |= dv
    boundary = cv2.dilate(diff, np.ones((5, 5), np.uint8)).astype(bool) & finite
    vv, uu = np.nonzero(boundary)
    if vv.size:
        uv = np.stack([uu, vv], axis=1).astype(float)
        q0, J = exact_ideal_and_jacobian(camera, uv)
        ok = np.all(np.isfinite(q0), axis=1) & np.all(np.isfinite(J), axis=(1, 2))
        vals = np.zeros(vv.size)
        vals[ok] = _boundary_values(q0[ok], J[ok], preps, bg, supersample, subdivisions)
        value[vv, uu] = vals
    if return_labels:
        return value, label, boundary
    return value


def _texture_state(p: _Prepared, q0: np.ndarray, J: np.ndarray):
    """Per pixel: the texture's box-filtered value where at most one texture line crosses the footprint
    (exact), and the number of lines crossing it (pixels with more are subdivided)."""
    tex = p.surface.texture
    H = p.H
    s0, t0, wden = _plane_coords(H, q0)
    # d(s, t)/dq of the homography, then through the footprint Jacobian
    ds_dq = (H[0, :2][None, :] - s0[:, None] * H[2, :2][None, :]) / wden[:, None]
    dt_dq = (H[1, :2][None, :] - t0[:, None] * H[2, :2][None, :]) / wden[:, None]
    gs = ds_dq[:, :1] * J[:, 0, :] + ds_dq[:, 1:] * J[:, 1, :]  # ds/d(u, v)
    gt = dt_dq[:, :1] * J[:, 0, :] + dt_dq[:, 1:] * J[:, 1, :]
    hs = 0.5 * (np.abs(gs[:, 0]) + np.abs(gs[:, 1]))
    ht = 0.5 * (np.abs(gt[:, 0]) + np.abs(gt[:, 1]))
    ilo = np.searchsorted(tex.s_lines, s0 - hs, side="right")
    ihi = np.searchsorted(tex.s_lines, s0 + hs, side="left")
    jlo = np.searchsorted(tex.t_lines, t0 - ht, side="right")
    jhi = np.searchsorted(tex.t_lines, t0 + ht, side="left")
    ns = np.maximum(ihi - ilo, 0)
    nt = np.maximum(jhi - jlo, 0)
    ic, jc = tex.cells(s0, t0)
    centre = tex.values[ic, jc]
    single = centre.copy()
    mod = p.surface.modulation(s0, t0) if p.surface.modulation is not None else np.ones_like(s0)
    one_s = (ns == 1) & (nt == 0)
    if np.any(one_s):
        k = ilo[one_s]
        line = tex.s_lines[np.minimum(k, tex.s_lines.size - 1)]
        g = gs[one_s]
        gn = np.linalg.norm(g, axis=1)
        cov_lo = box_coverage(g / gn[:, None], (line - s0[one_s]) / gn)  # part with s < line
        jj = jc[one_s]
        single[one_s] = cov_lo * tex.values[k, jj] + (1 - cov_lo) * tex.values[k + 1, jj]
    one_t = (nt == 1) & (ns == 0)
    if np.any(one_t):
        k = jlo[one_t]
        line = tex.t_lines[np.minimum(k, tex.t_lines.size - 1)]
        g = gt[one_t]
        gn = np.linalg.norm(g, axis=1)
        cov_lo = box_coverage(g / gn[:, None], (line - t0[one_t]) / gn)
        ii = ic[one_t]
        single[one_t] = cov_lo * tex.values[ii, k] + (1 - cov_lo) * tex.values[ii, k + 1]
    shade = p.surface.shade * mod
    return shade * single, ns + nt


def _strip_state(p: _Prepared, q0: np.ndarray, J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Box filter of a strip's piecewise-constant shading over each pixel's affine footprint (exact).

    Returns ``(value, coverage)``: the integral of the shading (0 outside the strip) over the footprint,
    and the footprint's fraction between the strip's first and last lines. The footprint maps to s
    linearly, ``s = s0 + g . delta``; the integral is the first cell's value plus, for each line crossed,
    the step times the fraction of the footprint beyond the line (:func:`box_coverage`).
    """
    tex = p.surface.texture
    H = p.H
    s0, _, wden = _plane_coords(H, q0)
    ds_dq = (H[0, :2][None, :] - s0[:, None] * H[2, :2][None, :]) / wden[:, None]
    g = ds_dq[:, :1] * J[:, 0, :] + ds_dq[:, 1:] * J[:, 1, :]
    half = 0.5 * (np.abs(g[:, 0]) + np.abs(g[:, 1]))
    lines = tex.s_lines
    vals = tex.values[:, 0]
    ilo = np.searchsorted(lines, s0 - half, side="right")
    ihi = np.searchsorted(lines, s0 + half, side="left")
    n_cross = np.maximum(ihi - ilo, 0)
    gn = np.maximum(np.linalg.norm(g, axis=1), 1e-300)
    ghat = g / gn[:, None]
    value = vals[ilo].astype(float)
    cover = ((ilo > 0) & (ilo < lines.size)).astype(float)
    for m in range(int(n_cross.max()) if n_cross.size else 0):
        k = np.minimum(ilo + m, lines.size - 1)
        beyond = 1.0 - box_coverage(ghat, (lines[k] - s0) / gn)
        live = m < n_cross
        value += np.where(live, (vals[k + 1] - vals[k]) * beyond, 0.0)
        step_in = np.where(k == 0, 1.0, np.where(k == lines.size - 1, -1.0, 0.0))
        cover += np.where(live, step_in * beyond, 0.0)
    return value, np.clip(cover, 0.0, 1.0)


def _boundary_values(q0, J, preps, bg, K, depth):
    """Exact box-filtered radiance of boundary pixels (see module docstring)."""
    n = q0.shape[0]
    fg_cov = np.zeros(n)
    fg_val = np.zeros(n)
    need_ss = np.zeros(n, bool)
    for p in preps:
        # signed distance of the pixel centre inside each outline edge, in pixel units
        nr = p.normals
        mvec = (
            nr[None, :, 0, None] * J[:, None, 0, :] + nr[None, :, 1, None] * J[:, None, 1, :]
        )  # (n, e, 2): J^T n
        mlen = np.linalg.norm(mvec, axis=-1)
        dist = (q0 @ p.normals.T - p.offsets[None, :]) / mlen
        mhat = mvec / mlen[..., None]
        half = 0.5 * (np.abs(mhat[..., 0]) + np.abs(mhat[..., 1]))
        out = np.any(dist <= -half, axis=1)
        crossing = np.abs(dist) < half
        ncross = crossing.sum(axis=1)
        if p.s_const is not None:
            # a strip: its edges along t are part of the exact box filter; any other edge crossing the
            # pixel (the strip's ends, near the door's corners) sends it to subdivision
            other = (crossing & ~p.s_const[None, :]).sum(axis=1)
            value_s, cover_s = _strip_state(p, q0, J)
            plain = ~out & (other == 0)
            fg_cov += np.where(plain, cover_s, 0.0)
            fg_val += np.where(plain, value_s, 0.0)
            need_ss |= ~out & (other >= 1)
            continue
        cov = np.ones(n)
        one = (ncross == 1) & ~out
        if np.any(one):
            e = np.argmax(crossing[one], axis=1)
            r = np.nonzero(one)[0]
            cov[one] = box_coverage(mhat[r, e], dist[r, e])
        cov[out] = 0.0
        active = ~out
        tex_val, tex_cross = _texture_state(p, q0, J)
        need_ss |= active & ((ncross >= 2) | (tex_cross >= 2) | ((tex_cross >= 1) & (ncross >= 1)))
        fg_cov += np.where(active, cov, 0.0)
        fg_val += np.where(active, cov * tex_val, 0.0)
    bg_val, bg_cross = _texture_state(bg, q0, J)
    bg_frac = np.clip(1.0 - fg_cov, 0.0, 1.0)
    need_ss |= (bg_cross >= 2) | ((bg_cross >= 1) & (bg_frac > 0) & (bg_frac < 1))
    result = fg_val + bg_frac * bg_val
    if np.any(need_ss):
        result[need_ss] = _subdivide(q0[need_ss], J[need_ss], preps, bg, K, depth)
    return result


def _apply(J: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """``J[n] @ offsets[s]`` for every pixel n and offset s: shapes (n, 2, 2), (S, 2) -> (n, S, 2)."""
    out = np.empty((J.shape[0], offsets.shape[0], 2))
    out[..., 0] = J[:, None, 0, 0] * offsets[None, :, 0] + J[:, None, 0, 1] * offsets[None, :, 1]
    out[..., 1] = J[:, None, 1, 0] * offsets[None, :, 0] + J[:, None, 1, 1] * offsets[None, :, 1]
    return out


def _subdivide(q0, J, preps, bg, K, depth):
    """Split footprints where boundaries meet into 4 x 4 sub-boxes and treat each like a pixel.

    Sub-boxes crossed by at most one boundary get the exact analytic coverage; only the few that still
    hold a vertex are split again, down to ``depth`` levels, where ``K x K`` point samples finish the job
    (their error is bounded by the area of a box ``4**-depth`` px on a side).
    """
    if depth <= 0:
        return _supersample(q0, J, preps, bg, K)
    S = 4
    d = (np.arange(S) + 0.5) / S - 0.5
    du, dv = np.meshgrid(d, d, indexing="xy")
    centres = np.stack([du.ravel(), dv.ravel()], axis=1)  # (S*S, 2)
    q = q0[:, None, :] + _apply(J, centres)
    Js = np.repeat(J / S, S * S, axis=0)
    vals = _boundary_values(q.reshape(-1, 2), Js, preps, bg, K, depth - 1)
    return vals.reshape(-1, S * S).mean(axis=1)


def _supersample(q0, J, preps, bg, K):
    """Average of K x K samples over the affine footprint ``q0 + J delta`` (pixels with corners)."""
    d = (np.arange(K) + 0.5) / K - 0.5
    du, dv = np.meshgrid(d, d, indexing="xy")
    delta = np.stack([du.ravel(), dv.ravel()], axis=1)  # (K*K, 2)
    q = q0[:, None, :] + _apply(J, delta)  # (n, S, 2)
    n, S = q.shape[:2]
    out = np.empty((n, S))
    s, t, _ = _plane_coords(bg.H, q)
    val = bg.surface.texture.lookup(s, t) * bg.surface.shade
    if bg.surface.modulation is not None:
        s0, t0, _ = _plane_coords(bg.H, q0)
        val = val * bg.surface.modulation(s0, t0)[:, None]
    out[:] = val
    for p in preps:
        inside = np.ones((n, S), bool)
        for nrm, c in zip(p.normals, p.offsets, strict=True):
            inside &= q[..., 0] * nrm[0] + q[..., 1] * nrm[1] >= c
        if not inside.any():
            continue
        s, t, _ = _plane_coords(p.H, q[inside])
        val = p.surface.texture.lookup(s, t) * p.surface.shade
        if p.surface.modulation is not None:
            s0, t0, _ = _plane_coords(p.H, q0)
            mod = np.broadcast_to(p.surface.modulation(s0, t0)[:, None], (n, S))[inside]
            val = val * mod
        out[inside] = val
    return out.mean(axis=1)
