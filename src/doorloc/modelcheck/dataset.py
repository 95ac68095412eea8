"""A DATASET folder for the model check: images and ``truth.csv`` (shared/SPEC.md section 3).

``truth.csv`` holds one row per image with at least ``image,x_mm,z_mm,yaw_deg,width_mm,thickness_mm``:
the reference pose measured independently (jig, dial gauges) and the door's measured size. Optional
columns ``height_mm`` and ``arris_mm`` give the door's height and arris where they were measured;
otherwise the cell's default door says them. Rendered sets carry more columns; they are ignored here
(a model check must not peek at the effects the renderer used).
"""

from __future__ import annotations

import csv
import os
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from doorloc.cell import Cell, DoorSize
from doorloc.pose import DoorPose

__all__ = [
    "DatasetError",
    "MeasuredImage",
    "Dataset",
    "read_dataset",
    "too_few_located",
    "REQUIRED_COLUMNS",
    "MIN_IMAGES",
    "IMAGE_REFUSALS",
]

REQUIRED_COLUMNS = ("image", "x_mm", "z_mm", "yaw_deg", "width_mm", "thickness_mm")
#: Fewest images a model check accepts: a held-out third and a cross-validated training set need this many.
MIN_IMAGES = 15


#: locate's refusal codes that fault the image itself (exposure, contrast, format, the camera's
#: sharpening), whatever the cell
IMAGE_REFUSALS = frozenset(
    {
        "bad_image",
        "wrong_image_size",
        "black_image",
        "saturated_image",
        "low_contrast",
        "overexposed",
        "sharpened",
    }
)


class DatasetError(ValueError):
    """A data set the model check cannot use; the message names the file and what is wrong."""


@dataclass(frozen=True)
class MeasuredImage:
    """One image of the data set with its reference pose and door (mm, degrees, cell frame)."""

    image: str
    path: Path
    door: DoorSize
    reference: DoorPose


@dataclass(frozen=True)
class Dataset:
    """The images of one data set, in ``truth.csv`` order."""

    folder: Path
    images: tuple[MeasuredImage, ...]

    def __len__(self) -> int:
        return len(self.images)


def _door(row: dict[str, str], cell: Cell) -> DoorSize:
    d = cell.default_door
    thickness = float(row["thickness_mm"])
    arris_txt = (row.get("arris_mm") or "").strip()
    # No measured arris: the cell's typical one applies where it fits this door (as in locate's requests).
    arris = float(arris_txt) if arris_txt else (d.arris_mm if d.arris_mm < thickness / 2 else 0.0)
    height_txt = (row.get("height_mm") or "").strip()
    return DoorSize(
        float(row["width_mm"]),
        thickness,
        float(height_txt) if height_txt else d.height_mm,
        arris,
        d.arris_profile,
    )


def read_dataset(folder: str | os.PathLike, cell: Cell, min_images: int = MIN_IMAGES) -> Dataset:
    """Read ``folder/truth.csv`` and check that every image it names is there.

    Raises
    ------
    DatasetError
        No folder, no ``truth.csv``, a missing column, a bad value (file and line named), a missing image,
        or fewer than ``min_images`` rows.
    """
    root = Path(folder)
    if not root.is_dir():
        raise DatasetError(f"{root} is not a folder; give the folder that holds the images and truth.csv")
    truth = root / "truth.csv"
    if not truth.is_file():
        raise DatasetError(
            f"{root} has no truth.csv; a model check needs the reference pose of every image "
            f"(columns {','.join(REQUIRED_COLUMNS)}, shared/SPEC.md section 3)"
        )
    items = []
    try:
        with truth.open(newline="", encoding="utf-8") as f:
            rd = csv.DictReader(f)
            missing = [c for c in REQUIRED_COLUMNS if c not in (rd.fieldnames or [])]
            if missing:
                raise DatasetError(
                    f"{truth}: lacks column(s) {', '.join(missing)} (needs {','.join(REQUIRED_COLUMNS)})"
                )
            for line, row in enumerate(rd, start=2):
                try:
                    door = _door(row, cell)
                    ref = DoorPose(float(row["x_mm"]), float(row["z_mm"]), float(row["yaw_deg"]))
                except (ValueError, TypeError) as e:
                    raise DatasetError(f"{truth}, line {line}: {e}") from None
                items.append(MeasuredImage(row["image"], root / row["image"], door, ref))
    except UnicodeDecodeError:
        raise DatasetError(f"{truth}: not a text file") from None
    absent = [m.image for m in items if not m.path.is_file()]
    if absent:
        more = f" and {len(absent) - 3} more" if len(absent) > 3 else ""
        raise DatasetError(f"{truth} names images that are not in {root}: {', '.join(absent[:3])}{more}")
    if len(items) < min_images:
        raise DatasetError(
            f"{truth} lists {len(items)} images; a model check needs at least {min_images} "
            "(30-60 recommended, several door widths and thicknesses, poses over the envelope)"
        )
    return Dataset(root, tuple(items))


def read_measured_image(item: MeasuredImage) -> tuple[np.ndarray, int]:
    """The image's grey levels and the JPEG quality its file was stored at (0 where it is no JPEG), which
    locate is told as the service tells it: a JPEG data set's edges are doubted at its quality's grey levels.

    Raises
    ------
    DatasetError
        The file cannot be read or is not an image.
    """
    from doorloc.vision.imageio import ImageDecodeError, read_stored_image

    try:
        return read_stored_image(item.path)
    except ImageDecodeError as e:
        raise DatasetError(f"{item.image}: {e}") from None


def too_few_located(answered: int, total: int, refusals: list[str]) -> DatasetError:
    """The error for a data set that locate answered on too few images with the given cell.

    ``refusals``: each refused image's ``error_code: message``. The most frequent refusal decides the
    advice: one that faults the images (:data:`IMAGE_REFUSALS`: lighting that clips the hinge face on
    every image is refused ``overexposed`` whatever the cell) asks for new images; any other points at
    the cell (camera, extrinsics), which the images then disagree with too far for a model check.
    """
    codes = Counter(r.split(":", 1)[0].strip() for r in refusals)
    if not codes:
        return DatasetError(f"locate answered on only {answered} of {total} images with this cell")
    code, n = codes.most_common(1)[0]
    example = next(r for r in refusals if r.split(":", 1)[0].strip() == code)
    tally = ", ".join(f"{c} {k}" for c, k in codes.most_common())
    head = (
        f"locate answered on only {answered} of {total} images with this cell (refused: {tally}; {example})"
    )
    if code in IMAGE_REFUSALS:
        return DatasetError(
            f"{head}: {n} of {total} images cannot be measured as taken, whatever the cell; retake the "
            "data set with the lighting or exposure fixed"
        )
    return DatasetError(
        f"{head}: the cell is too far from the images for a model check; check the camera and extrinsics first"
    )
