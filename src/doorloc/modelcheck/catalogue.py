"""The catalogue of effects a cell can have that its model lacks (shared/SPEC.md section 8).

Each :class:`Effect` says its parameters (units, bounds), where it lives in the cell model (camera
matrix, distortion, extrinsics, fixture, door arris, ``response_gamma``) and how to apply parameter
values to a :class:`~doorloc.cell.Cell`. The same ``apply`` makes the perturbed "true" cell of the
analytic forward model and the extended cell file the model check writes.

Geometric effects move the camera about its own centre (roll, tilt) or move the centre (distance,
lateral offset), so one parameter means one physical change.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Literal, get_args

import numpy as np
from scipy.spatial.transform import Rotation

from doorloc.calib.camera import CameraModel, Extrinsics
from doorloc.cell import ArrisProfile, Cell, DoorSize

__all__ = ["Values", "Effect", "CATALOGUE", "EFFECT_NAMES", "effect", "apply_effects", "arris_variants"]

ForwardKind = Literal["analytic", "relocate"]
#: Parameter values of one effect, in the order of its ``params``.
Values = Sequence[float] | np.ndarray


@dataclass(frozen=True)
class Effect:
    """One catalogue entry.

    Attributes
    ----------
    name : str
        Catalogue name (SPEC section 8).
    params : tuple of str
        Parameter names, each with its unit in the name (``_deg``, ``_mm``, ``_pct``...).
    lives_in : str
        Where the fitted values go in the cell file.
    lower, upper : tuple of float
        Bounds of the parameters (offsets from the nominal cell, except ``response_gamma``'s value).
    step : tuple of float
        Typical size of each parameter (the optimizer's scale).
    forward : {"analytic", "relocate"}
        ``analytic``: predicted through the camera model; ``relocate``: by locating the images again
        with candidate values (the effect acts on the grey levels, not on the geometry).
    looks_like : str
        What the data cannot tell this effect from, or "".
    variant : str
        A discrete choice within the effect (the arris's profile, ``chamfer`` or ``round``), "" for none.
    """

    name: str
    params: tuple[str, ...]
    lives_in: str
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    step: tuple[float, ...]
    forward: ForwardKind
    apply_fn: Callable[[Cell, Sequence[float]], Cell]
    looks_like: str = ""
    variant: str = ""

    @property
    def key(self) -> str:
        """The name, with the variant where there is one (``arris:round``): one forward model each."""
        return f"{self.name}:{self.variant}" if self.variant else self.name

    def apply(self, cell: Cell, values: Values) -> Cell:
        """The cell with this effect's parameter ``values`` (offsets from the cell's own) put in."""
        return self.apply_fn(cell, [float(v) for v in values])

    def nominal(self, cell: Cell) -> np.ndarray:
        """The parameter values that leave ``cell`` unchanged."""
        if self.name == "response_gamma":
            return np.array([cell.response_gamma])
        return np.zeros(len(self.params))


def _rotate_about_centre(cell: Cell, rot_cam: np.ndarray) -> Cell:
    """Turn the camera about its own centre by ``rot_cam`` (a rotation in the camera frame)."""
    R, t = cell.extrinsics.rotation, cell.extrinsics.tvec_mm
    return cell.with_extrinsics(Extrinsics.from_rotation(rot_cam @ R, rot_cam @ t))


def _roll(cell: Cell, v: Sequence[float]) -> Cell:
    return _rotate_about_centre(cell, Rotation.from_euler("z", v[0], degrees=True).as_matrix())


def _tilt(cell: Cell, v: Sequence[float]) -> Cell:
    # tilt about the camera's x axis (image rows move), pan about its y axis (image columns move)
    return _rotate_about_centre(cell, Rotation.from_euler("xy", [v[0], v[1]], degrees=True).as_matrix())


def _distance(cell: Cell, v: Sequence[float]) -> Cell:
    # the camera backs away along its optical axis: every point's depth grows by v[0]
    e = cell.extrinsics
    return cell.with_extrinsics(Extrinsics(e.rvec, e.tvec_mm + np.array([0.0, 0.0, v[0]])))


def _lateral(cell: Cell, v: Sequence[float]) -> Cell:
    # the camera centre moves by (dX, 0, dZ) in the cell frame: t' = -R (C + d) = t - R d
    e = cell.extrinsics
    return cell.with_extrinsics(Extrinsics(e.rvec, e.tvec_mm - e.rotation @ np.array([v[0], 0.0, v[1]])))


def _camera(cell: Cell, K: np.ndarray | None = None, dist: np.ndarray | None = None) -> Cell:
    c = cell.camera
    cam = CameraModel(
        c.camera_matrix.copy() if K is None else K,
        c.dist_coeffs.copy() if dist is None else dist,
        c.image_size,
        c.observed_radius_px,
    )
    return replace(cell, camera=cam)


def _focal(cell: Cell, v: Sequence[float]) -> Cell:
    K = cell.camera.camera_matrix.copy()
    K[0, 0] *= 1 + v[0] / 100
    K[1, 1] *= 1 + v[0] / 100
    return _camera(cell, K=K)


def _aspect(cell: Cell, v: Sequence[float]) -> Cell:
    # fy/fx grows by v[0] % with the mean focal length kept (not a focal-length change)
    K = cell.camera.camera_matrix.copy()
    K[0, 0] *= 1 - v[0] / 200
    K[1, 1] *= 1 + v[0] / 200
    return _camera(cell, K=K)


def _k1(cell: Cell, v: Sequence[float]) -> Cell:
    d = np.array(cell.camera.dist_coeffs, float)
    if d.size == 0:
        d = np.zeros(5)
    d[0] += v[0]
    return _camera(cell, dist=d)


def _fixture_depth(cell: Cell, v: Sequence[float]) -> Cell:
    f = cell.fixture
    return replace(cell, fixture=replace(f, face_shift_per_width=f.face_shift_per_width + v[0]))


def _arris(cell: Cell, v: Sequence[float]) -> Cell:
    d = cell.default_door
    a = max(d.arris_mm + v[0], 0.0)
    return replace(cell, default_door=DoorSize(d.width_mm, d.thickness_mm, d.height_mm, a, d.arris_profile))


def _arris_profiled(profile: ArrisProfile) -> Callable[[Cell, Sequence[float]], Cell]:
    def apply(cell: Cell, v: Sequence[float]) -> Cell:
        out = _arris(cell, v)
        d = out.default_door
        # sharp edges have no profile: the cell stays the nominal one
        return replace(out, default_door=replace(d, arris_profile=profile)) if d.arris_mm > 0 else out

    return apply


def arris_variants(cell: Cell) -> tuple[Effect, ...]:
    """The arris with each profile (the cell's own first): a rounded arris shifts the edges otherwise
    than a chamfer of the same size, and a forward model with the wrong profile leaves a residual that a
    geometric effect fits better (hidden rounded 0.79 mm arris answered as focal length -0.69 %)."""
    base = effect("arris")
    own = cell.default_door.arris_profile
    order = [own, *(p for p in get_args(ArrisProfile) if p != own)]
    return tuple(replace(base, apply_fn=_arris_profiled(p), variant=p) for p in order)


def _gamma(cell: Cell, v: Sequence[float]) -> Cell:
    return replace(cell, response_gamma=float(v[0]))


CATALOGUE: tuple[Effect, ...] = (
    Effect(
        "camera_roll",
        ("roll_deg",),
        "camera.extrinsics (rotation about the optical axis)",
        (-3.0,),
        (3.0,),
        (0.05,),
        "analytic",
        _roll,
    ),
    Effect(
        "camera_tilt",
        ("tilt_deg", "pan_deg"),
        "camera.extrinsics (rotation about the camera's x and y axes)",
        (-3.0, -3.0),
        (3.0, 3.0),
        (0.05, 0.05),
        "analytic",
        _tilt,
        looks_like="a principal-point error (cx, cy) moves the image the same way",
    ),
    Effect(
        "camera_distance",
        ("distance_mm",),
        "camera.extrinsics (tvec along the optical axis)",
        (-50.0,),
        (50.0,),
        (0.5,),
        "analytic",
        _distance,
    ),
    Effect(
        "lateral_offset",
        ("dx_mm", "dz_mm"),
        "camera.extrinsics (camera centre moved along cell X and Z)",
        (-20.0, -20.0),
        (20.0, 20.0),
        (0.1, 0.1),
        "analytic",
        _lateral,
    ),
    Effect(
        "focal_length",
        ("focal_pct",),
        "camera.camera_matrix (fx and fy scaled together)",
        (-10.0,),
        (10.0,),
        (0.1,),
        "analytic",
        _focal,
    ),
    Effect(
        "pixel_aspect",
        ("aspect_pct",),
        "camera.camera_matrix (fy/fx, mean focal length kept)",
        (-10.0,),
        (10.0,),
        (0.1,),
        "analytic",
        _aspect,
    ),
    Effect("radial_distortion", ("k1",), "camera.dist_coeffs[0]", (-0.5,), (0.5,), (0.01,), "analytic", _k1),
    Effect(
        "arris",
        ("arris_mm",),
        "door.arris_mm (the default door's arris; a request naming its own arris overrides)",
        (0.0,),
        (4.0,),
        (0.2,),
        "relocate",
        _arris,
    ),
    Effect(
        "fixture_depth",
        ("face_shift_per_width",),
        "fixture.face_shift_per_width (dY/dW)",
        (-0.5,),
        (0.5,),
        (0.005,),
        "analytic",
        _fixture_depth,
    ),
    Effect(
        "response_gamma",
        ("response_gamma",),
        "camera.response_gamma",
        (0.5,),
        (3.2,),
        (0.1,),
        "relocate",
        _gamma,
    ),
)

EFFECT_NAMES: tuple[str, ...] = tuple(e.name for e in CATALOGUE)


def effect(name: str) -> Effect:
    """The catalogue entry called ``name``; ValueError naming the catalogue otherwise."""
    for e in CATALOGUE:
        if e.name == name:
            return e
    raise ValueError(f"no effect {name!r} in the catalogue ({', '.join(EFFECT_NAMES)})")


def apply_effects(cell: Cell, values: dict[str, Values]) -> Cell:
    """``cell`` with every named effect's values put in (in catalogue order)."""
    for e in CATALOGUE:
        if e.name in values:
            cell = e.apply(cell, values[e.name])
    return cell
