"""Rendered "measured" sets with known hidden effects: for the tests, the benchmark and the worked examples.

A measured set with an effect is rendered with the *true* cell (the nominal cell with the effect put in,
or doors with an arris, or a camera with a non-linear response), its ``truth.csv`` carries only what a
shop would measure (SPEC section 3 columns: reference pose with a few micrometres of noise, width,
thickness), and the model check is given the *nominal* cell.
"""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from doorloc.cell import Cell, DoorSize
from doorloc.fileio import atomic_write_bytes, atomic_write_text
from doorloc.modelcheck.catalogue import EFFECT_NAMES, effect
from doorloc.pose import DoorPose
from doorloc.sim.effects import Effects

__all__ = ["MEASURED_PHOTOMETRY", "REALISTIC_RANGE", "SetSpec", "render_measured_set", "draw_hidden_effect"]

#: Photometry of a plain shop-floor image: some blur, sensor noise and a mild lighting gradient.
MEASURED_PHOTOMETRY = Effects(
    blur_sigma_px=1.0,
    read_noise_dn=1.5,
    gradient_u=0.04,
    gradient_v=-0.03,
    albedo_hinge=0.75,
    albedo_background=0.15,
)

#: Realistic magnitudes of each effect (low, high) for the hidden-effect test and the benchmark: small,
#: but well above the reference's noise of a few micrometres. A sign is drawn separately.
REALISTIC_RANGE: dict[str, tuple[tuple[float, float], ...]] = {
    "camera_roll": ((0.1, 0.3),),
    "camera_tilt": ((0.1, 0.3), (0.1, 0.3)),
    "camera_distance": ((1.0, 3.0),),
    "lateral_offset": ((0.2, 0.5), (0.2, 0.5)),
    "focal_length": ((0.4, 1.0),),
    "pixel_aspect": ((0.5, 3.0),),
    "radial_distortion": ((0.08, 0.2),),
    "arris": ((0.8, 2.0),),
    "fixture_depth": ((0.02, 0.05),),
    "response_gamma": ((1.8, 2.4),),
}
_SIGNED = {"arris": False, "response_gamma": False}


@dataclass(frozen=True)
class SetSpec:
    """What to render: doors, how many poses, the reference's noise (1 sigma) and the photometry."""

    widths_mm: tuple[float, ...] = (700.0, 900.0, 1100.0)
    thicknesses_mm: tuple[float, ...] = (40.0, 60.0)
    n_images: int = 40
    ref_noise_mm: float = 0.002
    ref_noise_deg: float = 0.0002
    photometry: Effects = MEASURED_PHOTOMETRY
    seed: int = 0


def draw_hidden_effect(
    rng: np.random.Generator, names: Sequence[str] = EFFECT_NAMES
) -> tuple[str, list[float]]:
    """One effect drawn from ``names`` with a value drawn from :data:`REALISTIC_RANGE` (random sign)."""
    name = str(rng.choice(list(names)))
    vals = []
    for lo, hi in REALISTIC_RANGE[name]:
        v = float(rng.uniform(lo, hi))
        if _SIGNED.get(name, True) and rng.random() < 0.5:
            v = -v
        vals.append(v)
    return name, vals


def render_measured_set(
    out_dir: str | os.PathLike,
    nominal: Cell,
    hidden: Mapping[str, Sequence[float]],
    spec: SetSpec = SetSpec(),
    arris_profile: str = "chamfer",
) -> Path:
    """Render a measured set with the ``hidden`` effects; returns the path of its ``truth.csv``.

    ``hidden`` maps catalogue names to values as :meth:`Effect.apply` takes them; ``arris`` gives the
    doors' arris (mm, profile ``arris_profile``), ``response_gamma`` the camera's true response. The
    nominal cell is written beside as ``cell_nominal.yaml`` (what the model check should be told) and the
    hidden truth as ``hidden.json`` (never read by the model check).
    """
    import json

    import cv2

    from doorloc.cell import save_cell
    from doorloc.sim.door import render_door

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng([spec.seed, 4242])
    true_cell = nominal
    fx = spec.photometry
    arris = 0.0
    for name, vals in hidden.items():
        if name == "arris":
            arris = float(vals[0])
            fx = replace(fx, arris_profile=arris_profile)
        elif name == "response_gamma":
            fx = replace(fx, gamma=float(vals[0]))
        else:
            true_cell = effect(name).apply(true_cell, vals)
    doors = [DoorSize(w, t, 2100.0, arris) for w in spec.widths_mm for t in spec.thicknesses_mm]
    env = nominal.envelope
    # poses spread over the envelope: a shuffled Latin hypercube, so every axis is covered evenly
    n = spec.n_images
    lh = np.stack([(rng.permutation(n) + rng.uniform(0, 1, n)) / n for _ in range(3)], 1) * 2 - 1
    lh *= 0.95
    buf = io.StringIO()
    wr = csv.writer(buf, lineterminator="\n")
    wr.writerow(["image", "x_mm", "z_mm", "yaw_deg", "width_mm", "thickness_mm"])
    for k in range(n):
        door = doors[k % len(doors)]
        pose = DoorPose(float(lh[k, 0] * env.x_mm), float(lh[k, 1] * env.z_mm), float(lh[k, 2] * env.yaw_deg))
        rd = render_door(true_cell, door, pose, effects=fx, seed=spec.seed * 1000 + k)
        ok, png = cv2.imencode(".png", rd.image, [cv2.IMWRITE_PNG_COMPRESSION, 1])
        if not ok:
            raise RuntimeError("PNG encoding failed")
        name = f"img_{k:03d}.png"
        atomic_write_bytes(out / name, png.tobytes())
        noise = rng.normal(0, 1, 4)
        vals = [
            pose.x_mm + spec.ref_noise_mm * noise[0],
            pose.z_mm + spec.ref_noise_mm * noise[1],
            pose.yaw_deg + spec.ref_noise_deg * noise[2],
            door.width_mm,
            door.thickness_mm + spec.ref_noise_mm * noise[3],
        ]
        wr.writerow([name, *(repr(float(v)) for v in vals)])
    save_cell(nominal, out / "cell_nominal.yaml")
    atomic_write_text(
        out / "hidden.json", json.dumps({k: [float(v) for v in vs] for k, vs in hidden.items()})
    )
    atomic_write_text(out / "truth.csv", buf.getvalue())
    return out / "truth.csv"
