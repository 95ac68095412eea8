"""Rendered data sets: pose lists, rows of ``truth.csv`` and writing a set to a folder.

``truth.csv`` (shared/SPEC.md section 3, "Datasets with reference poses"): one row per image with
``image,x_mm,z_mm,yaw_deg,width_mm,thickness_mm`` (reference pose and door), then ``height_mm``,
``arris_mm``, ``face_y_mm``, ``corner_u,corner_v`` (true reference-corner pixel), ``scale_mm_per_px``,
``seed`` and one column per :class:`~doorloc.sim.effects.Effects` field (the effects used). Floats are
written with ``repr`` so that they read back exactly.
"""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Iterable
from dataclasses import dataclass, fields, replace
from pathlib import Path

import numpy as np

from doorloc.cell import Cell, DoorSize, Envelope, save_cell
from doorloc.pose import DoorPose
from doorloc.sim.effects import Effects

__all__ = [
    "grid_poses",
    "random_poses",
    "DatasetItem",
    "dataset_items",
    "TRUTH_COLUMNS",
    "truth_csv_text",
    "write_dataset",
    "TruthRow",
    "read_truth_csv",
]

TRUTH_COLUMNS = [
    "image",
    "x_mm",
    "z_mm",
    "yaw_deg",
    "width_mm",
    "thickness_mm",
    "height_mm",
    "arris_mm",
    "face_y_mm",
    "corner_u",
    "corner_v",
    "scale_mm_per_px",
    "seed",
] + [f.name for f in fields(Effects)]


def grid_poses(envelope: Envelope, steps: int = 3) -> list[DoorPose]:
    """The full ``steps x steps x steps`` grid over the placement envelope (x, z, yaw), corners included.

    Examples
    --------
    >>> ps = grid_poses(Envelope(10, 10, 2), 3)
    >>> len(ps), ps[0], ps[13]
    (27, DoorPose(x_mm=-10.0, z_mm=-10.0, yaw_deg=-2.0), DoorPose(x_mm=0.0, z_mm=0.0, yaw_deg=0.0))
    """
    if steps < 1:
        raise ValueError("the pose grid needs at least 1 step per axis")

    def axis(e):
        return [0.0] if steps == 1 else [float(v) for v in np.linspace(-e, e, steps)]

    return [
        DoorPose(x, z, y)
        for x in axis(envelope.x_mm)
        for z in axis(envelope.z_mm)
        for y in axis(envelope.yaw_deg)
    ]


def random_poses(envelope: Envelope, count: int, seed: int = 0) -> list[DoorPose]:
    """``count`` poses drawn uniformly inside the envelope, reproducible from ``seed``."""
    if count < 1:
        raise ValueError("--count must be at least 1")
    rng = np.random.default_rng([seed, 31337])
    u = rng.uniform(-1.0, 1.0, (count, 3))
    return [
        DoorPose(float(a * envelope.x_mm), float(b * envelope.z_mm), float(c * envelope.yaw_deg))
        for a, b, c in u
    ]


@dataclass(frozen=True)
class DatasetItem:
    """One image to render: its file name, door, pose and noise/grain seed."""

    image: str
    door: DoorSize
    pose: DoorPose
    seed: int


def dataset_items(doors: Iterable[DoorSize], poses: list[DoorPose], seed: int = 0) -> list[DatasetItem]:
    """Every door at every pose, named ``img_0000.png``...; per-image seeds derived from ``seed``."""
    items: list[DatasetItem] = []
    for door in doors:
        for pose in poses:
            k = len(items)
            items.append(DatasetItem(f"img_{k:04d}.png", door, pose, int(seed) * 100_003 + k))
    return items


def _fmt(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)
    return str(v)


def truth_csv_text(rows: list[dict]) -> str:
    """CSV text with :data:`TRUTH_COLUMNS` for rows built from :attr:`RenderedDoor.truth` + ``image``."""
    buf = io.StringIO()
    wr = csv.writer(buf, lineterminator="\n")
    wr.writerow(TRUTH_COLUMNS)
    for r in rows:
        flat = {**{k: v for k, v in r.items() if k != "effects"}, **r["effects"]}
        wr.writerow([_fmt(flat[c]) for c in TRUTH_COLUMNS])
    return buf.getvalue()


def write_dataset(
    out_dir: str | os.PathLike, cell: Cell, items: list[DatasetItem], effects: Effects, progress=None
) -> Path:
    """Render ``items`` into ``out_dir``: PNG images, ``truth.csv`` and ``cell.yaml``.

    Every file is written through a temporary file and a rename; ``truth.csv`` comes last, so a set with
    a ``truth.csv`` is complete. ``cell.yaml`` is the cell the pipeline should be told (camera inline,
    its ``response_gamma`` the rendered camera's; its default door is the rendered door when there is
    only one). Returns the path of ``truth.csv``.
    """
    import cv2

    from doorloc.fileio import atomic_write_bytes, atomic_write_text
    from doorloc.sim.door import render_door

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for n, it in enumerate(items):
        rd = render_door(cell, it.door, it.pose, effects=effects, seed=it.seed)
        ok, buf = cv2.imencode(".png", rd.image, [cv2.IMWRITE_PNG_COMPRESSION, 9])
        if not ok:
            raise RuntimeError(f"PNG encoding failed for {it.image}")
        atomic_write_bytes(out / it.image, buf.tobytes())
        rows.append({"image": it.image, **rd.truth})
        if progress is not None:
            progress(n + 1, len(items))
    doors = {it.door for it in items}
    told = replace(cell, default_door=next(iter(doors))) if len(doors) == 1 else cell
    # the camera's response is the rendered one (a cell that says otherwise describes another camera)
    told = replace(told, response_gamma=effects.stated_gamma)
    if 8 < effects.bit_depth < 16:  # and so are its stored levels' bits (a 12-bit camera's 0-4095)
        told = replace(told, stored_bits=effects.bit_depth)
    save_cell(told, out / "cell.yaml")
    atomic_write_text(out / "truth.csv", truth_csv_text(rows))
    for name in ("cell.yaml", "truth.csv"):
        os.chmod(out / name, 0o644)
    return out / "truth.csv"


@dataclass(frozen=True)
class TruthRow:
    """One row of a rendered set's ``truth.csv``, typed."""

    image: str
    door: DoorSize
    pose: DoorPose
    corner_px: tuple[float, float]
    seed: int
    effects: Effects


def read_truth_csv(path: str | os.PathLike) -> list[TruthRow]:
    """Read a rendered set's ``truth.csv`` (the layout :func:`truth_csv_text` writes).

    Raises ValueError naming the file and line for a missing column or a bad value.
    """
    p = Path(path)
    effect_names = {f.name for f in fields(Effects)}
    rows = []
    with p.open(newline="", encoding="utf-8") as f:
        rd = csv.DictReader(f)
        missing = [
            c
            for c in ("image", "x_mm", "z_mm", "yaw_deg", "width_mm", "thickness_mm")
            if c not in (rd.fieldnames or [])
        ]
        if missing:
            raise ValueError(f"{p}: truth.csv lacks column(s) {', '.join(missing)}")
        for line, r in enumerate(rd, start=2):
            try:
                door = DoorSize(
                    float(r["width_mm"]),
                    float(r["thickness_mm"]),
                    float(r.get("height_mm") or 2100.0),
                    float(r.get("arris_mm") or 0.0),
                )
                pose = DoorPose(float(r["x_mm"]), float(r["z_mm"]), float(r["yaw_deg"]))
                corner = (float(r.get("corner_u") or "nan"), float(r.get("corner_v") or "nan"))
                fx = Effects.from_dict(
                    {k: v for k, v in r.items() if k in effect_names and v not in (None, "")}
                )
                rows.append(TruthRow(r["image"], door, pose, corner, int(float(r.get("seed") or 0)), fx))
            except (ValueError, TypeError) as e:
                raise ValueError(f"{p}, line {line}: {e}") from None
    return rows
