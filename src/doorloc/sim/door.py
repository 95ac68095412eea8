"""A door in the cell, rendered exactly: the solid, its visible faces, the background, the true corner.

The door is a convex solid in the door frame (shared/SPEC.md section 1): ``X in [0, T]`` (thickness),
``Y in [0, W]`` (width, from the hinge-edge face), ``Z in [0, H]`` (height), optionally with a 45-degree
chamfer or a rounded arris of size ``DoorSize.arris_mm`` on the edges around the hinge face and the bottom
end. It is placed in the cell by :func:`doorloc.pose.door_to_cell` with its hinge face at
``face_y = cell.fixture.face_y(width)``; the reference corner is door point ``(0, 0, 0)`` (for a door
with an arris it is the virtual corner where the three nominal planes meet).

Visible faces are the ones facing the camera (back-face culling of a convex solid: they never overlap).
Behind the door a background plane at ``Y = face_y + W + BACKGROUND_GAP_MM`` can carry distractors: a
dark clamp beside the corner and a second, parallel edge.

Example
-------
>>> from doorloc.cell import DoorSize, load_cell
>>> from doorloc.pose import DoorPose
>>> cell = load_cell("fixtures/cell_thesis.yaml")                       # doctest: +SKIP
>>> rd = render_door(cell, DoorSize(900, 50, 2100), DoorPose(0, 0, 0))   # doctest: +SKIP
>>> rd.corner_px                                                         # doctest: +SKIP
array([802.56..., 708.23...])
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from doorloc.arris import ArrisSection
from doorloc.cell import Cell, DoorSize, edge_camera_cell
from doorloc.pose import DoorPose, door_to_cell, yaw_rotation_matrix
from doorloc.sim.effects import Effects, form_image, lambert_shade, wood_grain
from doorloc.sim.raster import GridTexture, Surface, paint_rectangles, render_radiance

__all__ = [
    "DoorFace",
    "door_faces",
    "RenderedDoor",
    "render_door",
    "render_hued_light",
    "true_corner_px",
    "BACKGROUND_GAP_MM",
]

#: distance of the background plane behind the door's far edge face, mm
BACKGROUND_GAP_MM = 300.0
#: sub-strips (uniform in the surface-normal angle) of the shading across a rounded arris; each is box-filtered
#: exactly; each holds its mean radiance (the only approximation: shading constant over 1/128 of the arc)
ROUND_SUBSTRIPS = 128


@dataclass(frozen=True, eq=False)
class DoorFace:
    """One planar face of the door solid, door frame.

    Attributes
    ----------
    name : str
        ``hinge_face``, ``reference_face`` (X=0), ``far_face`` (X=T), ``bottom_end`` (Z=0), ``top_end``,
        ``back_edge`` (Y=W), or ``arris:<a>/<b>[:k]`` for a chamfer or rounding facet between two faces.
    kind : str
        ``hinge``, ``side``, ``end``, ``back`` or ``arris`` (selects the albedo).
    normal : ndarray, shape (3,)
        Outward unit normal, door frame.
    polygon : ndarray, shape (m, 3)
        Convex outline, door frame, mm.
    """

    name: str
    kind: str
    normal: np.ndarray
    polygon: np.ndarray


def _halfspaces(door: DoorSize, profile: str) -> list[tuple[np.ndarray, float, str, str]]:
    T, W, H, a = door.thickness_mm, door.width_mm, door.height_mm, door.arris_mm
    base = {
        "reference_face": (np.array([-1.0, 0, 0]), 0.0, "side"),
        "far_face": (np.array([1.0, 0, 0]), T, "side"),
        "hinge_face": (np.array([0, -1.0, 0]), 0.0, "hinge"),
        "back_edge": (np.array([0, 1.0, 0]), W, "back"),
        "bottom_end": (np.array([0, 0, -1.0]), 0.0, "end"),
        "top_end": (np.array([0, 0, 1.0]), H, "end"),
    }
    out = [(n, h, name, kind) for name, (n, h, kind) in base.items()]
    if a <= 0:
        return out
    arris_edges = [
        ("hinge_face", "reference_face"),
        ("hinge_face", "far_face"),
        ("hinge_face", "bottom_end"),
        ("hinge_face", "top_end"),
        ("bottom_end", "reference_face"),
        ("bottom_end", "far_face"),
        ("bottom_end", "back_edge"),
    ]
    for f1, f2 in arris_edges:
        (n1, h1, _), (n2, h2, _) = base[f1], base[f2]
        # A chamfer is this plane; a rounding is the quarter cylinder of radius a whose centre line lies a
        # inside both faces: its tangent lines on the two faces are this plane's edges (the chord), so the
        # solid's other faces are the same, and the renderer shades the chord face as the cylinder
        # (:func:`round_arris_surface`).
        out.append(((n1 + n2) / math.sqrt(2), (h1 + h2 - a) / math.sqrt(2), f"arris:{f1}/{f2}", "arris"))
    return out


def _clip(poly: np.ndarray, n: np.ndarray, h: float) -> np.ndarray:
    """Sutherland-Hodgman: the part of a planar polygon (m, 3) where ``n . p <= h``."""
    if len(poly) == 0:
        return poly
    d = poly @ n - h
    out = []
    for k in range(len(poly)):
        p, q, dp, dq = poly[k], poly[(k + 1) % len(poly)], d[k], d[(k + 1) % len(poly)]
        if dp <= 0:
            out.append(p)
        if (dp < 0 < dq) or (dq < 0 < dp):
            out.append(p + (q - p) * (dp / (dp - dq)))
    return np.array(out).reshape(-1, 3)


def _face_polygon(
    hs: list[tuple[np.ndarray, float, str, str]], i: int, big: float, skip: tuple[str, ...] = ()
) -> np.ndarray:
    """Plane ``i`` of ``hs`` clipped by every other half-space (but those named in ``skip``), shape (m, 3)."""
    n, h = hs[i][0], hs[i][1]
    a = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    c = n * h
    poly = np.array([c + big * (sa * a + sb * b) for sa, sb in ((-1, -1), (1, -1), (1, 1), (-1, 1))])
    for j, (n2, h2, name2, _) in enumerate(hs):
        if j != i and name2 not in skip:
            poly = _clip(poly, n2, h2)
    return poly


def door_faces(door: DoorSize, profile: str = "chamfer") -> list[DoorFace]:
    """The faces of the door solid (door frame), built by clipping each bounding plane by the others.

    With a rounded arris the arris faces are the chords of the quarter cylinders (the renderer shades
    them as the cylinder; the solid's other faces end at the cylinder's tangent lines either way).

    Examples
    --------
    >>> [f.name for f in door_faces(DoorSize(900, 50, 2100))]
    ['reference_face', 'far_face', 'hinge_face', 'back_edge', 'bottom_end', 'top_end']
    >>> len(door_faces(DoorSize(900, 50, 2100, arris_mm=2)))
    13
    """
    hs = _halfspaces(door, profile)
    big = 4.0 * max(door.thickness_mm, door.width_mm, door.height_mm)
    faces = []
    for i, (n, _h, name, kind) in enumerate(hs):
        poly = _face_polygon(hs, i, big)
        if len(poly) >= 3:
            area = 0.5 * np.linalg.norm(np.sum(np.cross(poly, np.roll(poly, -1, axis=0)), axis=0))
            if area > 1e-9:
                faces.append(DoorFace(name, kind, n, poly))
    return faces


def true_corner_px(cell: Cell, door: DoorSize, pose: DoorPose) -> np.ndarray:
    """Pixel of the reference corner (door point (0, 0, 0)), distorted image, shape (2,)."""
    corner_cell = door_to_cell(np.zeros((1, 3)), pose, cell.face_y(door))
    return cell.posed_camera.project_cell(corner_cell)[0]


@dataclass(frozen=True, eq=False)
class RenderedDoor:
    """A rendered door image and its truth.

    Attributes
    ----------
    image : ndarray
        uint8 (H, W) grey (or uint16, or (H, W, 3) BGR, as the effects ask).
    corner_px : ndarray, shape (2,)
        True pixel of the reference corner.
    truth : dict
        Pose, door, ``face_y_mm``, ``corner_u``/``corner_v``, ``scale_mm_per_px``, ``visible_faces`` and
        ``effects`` (the :meth:`Effects.to_dict` mapping).
    radiance : ndarray, shape (H, W), float64
        Box-filtered scene radiance before optics and sensor effects.
    """

    image: np.ndarray
    corner_px: np.ndarray
    truth: dict
    radiance: np.ndarray


def _albedo(effects: Effects, kind: str) -> float:
    return {
        "hinge": effects.albedo_hinge,
        "side": effects.albedo_side,
        "end": effects.albedo_end,
        "back": effects.albedo_back,
        "arris": effects.albedo_chamfer,
    }[kind]


def _face_axes(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """In-plane (s, t) axes of a face, door frame: s along door X where possible, t = n x s."""
    for axis in (np.array([1.0, 0, 0]), np.array([0, 0, 1.0]), np.array([0, 1.0, 0])):
        s = axis - normal * (axis @ normal)
        if np.linalg.norm(s) > 0.3:
            s = s / np.linalg.norm(s)
            return s, np.cross(normal, s)
    raise AssertionError("unreachable")


def scene_surfaces(cell: Cell, door: DoorSize, pose: DoorPose, effects: Effects, seed: int = 0):
    """The visible door faces and the background as :class:`~doorloc.sim.raster.Surface` (camera frame).

    Returns ``(foreground, background, visible_face_names)``.
    """
    face_y = cell.face_y(door)
    ext = cell.extrinsics
    R = ext.rotation
    Ryaw = yaw_rotation_matrix(pose.yaw_deg)
    centre = ext.camera_centre_cell
    origin_door = np.zeros(3)
    foreground, names = [], []
    eye_door = Ryaw.T @ (centre - np.array([pose.x_mm, face_y, pose.z_mm]))
    hs = _halfspaces(door, effects.arris_profile)
    for f in door_faces(door, effects.arris_profile):
        if f.kind == "arris" and effects.arris_profile == "round":
            surf = _round_arris_surface(cell, door, pose, effects, hs, f, eye_door)
            if surf is not None:
                foreground.append(surf)
                names.append(f.name)
            continue
        poly_cell = door_to_cell(f.polygon, pose, face_y)
        n_cell = Ryaw @ f.normal
        if float(n_cell @ (poly_cell[0] - centre)) >= 0:  # back-facing (or edge-on)
            continue
        s_door, t_door = _face_axes(f.normal)
        # the face's (s, t) origin: the door origin projected onto the face plane
        o_door = origin_door - f.normal * ((origin_door - f.polygon[0]) @ f.normal)
        rel = f.polygon - o_door
        poly_st = np.stack([rel @ s_door, rel @ t_door], axis=1)
        o_cell = door_to_cell(o_door[None], pose, face_y)[0]
        texture = GridTexture.uniform(1.0)
        modulation = None
        if f.name == "hinge_face":
            modulation = wood_grain(effects, seed)
            if effects.shadow_strength > 0:
                z0 = effects.shadow_z_mm
                texture = paint_rectangles(
                    1.0, [(-np.inf, np.inf, z0, z0 + effects.shadow_height_mm, 1.0 - effects.shadow_strength)]
                )
        foreground.append(
            Surface(
                origin=ext.cell_to_camera(o_cell),
                s_axis=R @ (Ryaw @ s_door),
                t_axis=R @ (Ryaw @ t_door),
                polygon_st=poly_st,
                texture=texture,
                shade=lambert_shade(effects, _albedo(effects, f.kind), n_cell),
                modulation=modulation,
                name=f.name,
            )
        )
        names.append(f.name)
    background = _background(cell, door, face_y, effects)
    return foreground, background, names


def _round_arris_surface(
    cell: Cell,
    door: DoorSize,
    pose: DoorPose,
    effects: Effects,
    hs: list[tuple[np.ndarray, float, str, str]],
    face: DoorFace,
    eye_door: np.ndarray,
) -> Surface | None:
    """A rounded arris as one surface: its chord plane, shaded across as the cylinder the camera sees.

    Every camera ray through a ruling of the cylinder (a line along the edge) meets the chord plane on a
    line along the edge too, so the cylinder's image is the chord plane's image with a shading that
    varies across the chord only: the view ray through chord coordinate ``s`` hits the cylinder where its
    normal makes the angle ``theta(s)`` (:class:`doorloc.arris.ArrisSection`). The strip reaches from
    the tangent line on the hinge face to the other tangent line, or to the silhouette where the
    neighbouring face is turned away (then beyond the chord's end). The shading is Lambert under the
    cell's light, piecewise constant over ``ROUND_SUBSTRIPS`` sub-strips that the rasteriser box-filters
    exactly (:attr:`doorloc.sim.raster.GridTexture.exact_s`). Returns None when no part faces the camera.
    """
    i = next(k for k, h in enumerate(hs) if h[2] == face.name)
    f1, f2 = face.name.split(":", 1)[1].split("/")
    (n1, h1, _, _), (n2, h2, _, _) = (next(h for h in hs if h[2] == nm) for nm in (f1, f2))
    a = door.arris_mm
    sec = ArrisSection(a, "round", eye_w=float(h2 - n2 @ eye_door), eye_y=float(h1 - n1 @ eye_door))
    th_a, th_b = sec.visible_arc()
    if not np.isfinite(th_a):
        return None
    eye = np.array([sec.eye_w, sec.eye_y])
    t0, e = np.array([a, 0.0]), np.array([-1.0, 1.0]) / math.sqrt(2.0)

    def chord(theta: np.ndarray) -> np.ndarray:
        # chord coordinate of the view ray through the ruling at theta: eye + lam * d = t0 + sig * e
        d = sec.point(theta) - eye
        rel = eye - t0
        return (rel[0] * d[..., 1] - rel[1] * d[..., 0]) / (e[0] * d[..., 1] - e[1] * d[..., 0])

    th = np.linspace(th_a, th_b, ROUND_SUBSTRIPS + 1)
    sig = chord(th)
    s_axis = (n2 - n1) / math.sqrt(2.0)
    normal = (n1 + n2) / math.sqrt(2.0)
    t_axis = np.cross(normal, s_axis)
    origin = h1 * n1 + (h2 - a) * n2  # (w, y) = (a, 0), the tangent line on face 1
    big = 4.0 * max(door.thickness_mm, door.width_mm, door.height_mm)
    poly = _face_polygon(hs, i, big, skip=(f1, f2))
    lo, hi = float(min(sig[0], sig[-1])), float(max(sig[0], sig[-1]))
    so = float(s_axis @ origin)
    poly = _clip(_clip(poly, -s_axis, -(lo + so)), s_axis, hi + so)
    if len(poly) < 3:
        return None
    Ryaw = yaw_rotation_matrix(pose.yaw_deg)
    # each sub-strip's mean radiance over its image width (Gauss-Legendre in theta, weighted by d sig/d theta)
    xg, wg = np.polynomial.legendre.leggauss(4)
    th_q = 0.5 * (th[1:] + th[:-1])[:, None] + 0.5 * np.diff(th)[:, None] * xg[None, :]
    dth = 1e-6
    jac = np.abs(chord(th_q + dth) - chord(th_q - dth)) / (2 * dth)
    n_q = np.cos(th_q)[..., None] * n1 + np.sin(th_q)[..., None] * n2
    light = effects.light_direction_cell()
    cos_l = np.maximum(0.0, (n_q @ Ryaw.T) @ light)
    radiance = _albedo(effects, "arris") * (
        effects.light_ambient + effects.light_directional * effects.finish_term(cos_l)
    )
    shade = np.sum(radiance * jac * wg, axis=1) / np.sum(jac * wg, axis=1)
    if sig[-1] < sig[0]:
        sig, shade = sig[::-1], shade[::-1]
    # the strip's texture: 0 outside its two bounding lines (its outline's edges along the arris)
    texture = GridTexture(sig, np.empty(0), np.concatenate([[0.0], shade, [0.0]])[:, None], exact_s=True)
    ext = cell.extrinsics
    R = ext.rotation
    face_y = cell.face_y(door)
    rel_poly = poly - origin
    poly_st = np.stack([rel_poly @ s_axis, rel_poly @ t_axis], axis=1)
    o_cell = door_to_cell(origin[None], pose, face_y)[0]
    return Surface(
        origin=ext.cell_to_camera(o_cell),
        s_axis=R @ (Ryaw @ s_axis),
        t_axis=R @ (Ryaw @ t_axis),
        polygon_st=poly_st,
        texture=texture,
        shade=1.0,
        modulation=None,
        name=face.name,
    )


def _background(cell: Cell, door: DoorSize, face_y: float, effects: Effects) -> Surface:
    """Background plane ``Y = face_y + W + gap`` with (s, t) = cell (X, Z), and its distractors."""
    ext = cell.extrinsics
    R = ext.rotation
    y_bg = face_y + door.width_mm + BACKGROUND_GAP_MM
    c = ext.camera_centre_cell
    # Distractors are specified as seen at the hinge-face depth; scale them onto the background plane
    # through the camera centre so they appear where asked.
    k = (y_bg - c[1]) / (face_y - c[1])

    def to_bg_x(x):
        return c[0] + (x - c[0]) * k

    def to_bg_z(z):
        return c[2] + (z - c[2]) * k

    base = effects.albedo_background
    rects = []
    if effects.second_edge_offset_mm:
        rects.append(
            (
                -np.inf,
                to_bg_x(-abs(effects.second_edge_offset_mm)),
                -np.inf,
                np.inf,
                effects.second_edge_albedo / base,
            )
        )
    if effects.clamp_albedo >= 0:
        rects.append(
            (to_bg_x(-45.0), to_bg_x(-2.0), to_bg_z(-30.0), to_bg_z(40.0), effects.clamp_albedo / base)
        )
    texture = paint_rectangles(1.0, rects) if rects else GridTexture.uniform(1.0)
    origin = ext.cell_to_camera(np.array([0.0, y_bg, 0.0]))
    return Surface(origin, R[:, 0].copy(), R[:, 2].copy(), None, texture, base, None, "background")


def render_door(
    cell: Cell,
    door: DoorSize,
    pose: DoorPose,
    *,
    effects: Effects | None = None,
    seed: int = 0,
) -> RenderedDoor:
    """Render the door seen by the cell's camera.

    Parameters
    ----------
    cell : Cell
        Camera (intrinsics, distortion, extrinsics) and fixture (hinge-face depth for the door width); its
        ``camera_photometry`` where it has one (the response beyond a power law, the edges' shift).
    door : DoorSize
        Door dimensions (mm) and arris size.
    pose : DoorPose
        True door pose (x_mm, z_mm, yaw_deg).
    effects : Effects or None
        Photometry, optics and sensor effects; None = plain (uniform faces, noise-free 8-bit).
    seed : int
        Seeds the wood grain and the noise: the same inputs and seed give the same bytes.

    Returns
    -------
    RenderedDoor
    """
    effects = effects or Effects()
    fg, bg, names = scene_surfaces(cell, door, pose, effects, seed)
    # a camera whose point spread moves every edge draws them through its moved principal point, and its
    # response beyond a power law stores the levels (the cell's camera_photometry, as locate reads them)
    seen = edge_camera_cell(cell)
    radiance = render_radiance(seen.camera, fg, bg)
    image = form_image(
        radiance,
        effects,
        seed,
        principal_point=(cell.camera.cx, cell.camera.cy),
        response=cell.camera_photometry,
    )
    corner = true_corner_px(cell, door, pose)
    face_y = cell.face_y(door)
    corner_cell = door_to_cell(np.zeros((1, 3)), pose, face_y)[0]
    truth = {
        "x_mm": pose.x_mm,
        "z_mm": pose.z_mm,
        "yaw_deg": pose.yaw_deg,
        "width_mm": door.width_mm,
        "thickness_mm": door.thickness_mm,
        "height_mm": door.height_mm,
        "arris_mm": door.arris_mm,
        "face_y_mm": face_y,
        "corner_u": float(corner[0]),
        "corner_v": float(corner[1]),
        "scale_mm_per_px": cell.posed_camera.scale_mm_per_px(corner_cell),
        "visible_faces": names,
        "seed": seed,
        "effects": effects.to_dict(),
    }
    return RenderedDoor(image, corner, truth, radiance)


def render_hued_light(
    cell: Cell,
    door: DoorSize,
    pose: DoorPose,
    door_bgr: np.ndarray,
    background_bgr: np.ndarray,
    effects: Effects | None = None,
) -> np.ndarray:
    """The linear light (H, W, 3: BGR, float64, full scale 1) through the lens of a door of one hue on a
    background of another: the door alone (its background black) and the background alone (the door's
    faces black), each rendered by :func:`render_door` linear, noise-free and at 16 bits, times its colour
    (``door_bgr``, ``background_bgr``: each channel's share of the light). Light adds, so the two renders
    sum per channel; the renderer's own scenes have one grey level per face. ``effects``: the faces'
    albedos, the lighting and the lens (its response, noise, output and camera settings are not used).

    A colour camera's response, noise, colour filter and file are the caller's to add
    (:func:`doorloc.sim.effects.bayer_samples`, :func:`doorloc.sim.effects.demosaiced`)."""
    linear = replace(
        effects or Effects(),
        gamma=1.0,
        response_curve="power",
        full_well_e=0.0,
        read_noise_dn=0.0,
        sharpen_amount=0.0,
        bit_depth=16,
        jpeg_quality=0,
        color=False,
        demosaic="none",
    )
    plain = replace(cell, camera_photometry=None)
    behind_only = replace(
        linear,
        albedo_background=1.0,
        albedo_hinge=0.0,
        albedo_side=0.0,
        albedo_end=0.0,
        albedo_chamfer=0.0,
        albedo_back=0.0,
    )
    alone = render_door(plain, door, pose, effects=replace(linear, albedo_background=0.0)).image
    behind = render_door(plain, door, pose, effects=behind_only).image
    return alone[..., None] / 65535.0 * np.asarray(door_bgr) + behind[..., None] / 65535.0 * np.asarray(
        background_bgr
    )
