"""Offline batch: every image under a folder located, one JSON line per image (SPEC section 3 + targets).

Flow: plan (walk the folder or read the manifest; images recognised by content) -> skip what the
results file already holds (``--resume``) -> locate in parallel worker processes (or on Ray Data) ->
append each record to the results file as it arrives -> summary.

Every file under the folder gets a record: an image is ``answered`` or ``refused``; anything else is
``failed`` with the reason (``unreadable``, ``empty_file``, ``not_an_image``, ``too_large``,
``not_a_regular_file``, ``undecodable_image``). Special files (FIFOs, sockets, devices) are recognised
without being read, so nothing blocks on them; an image's declared size is checked against the pixel
and decoded-byte limits before it is decoded. Worker processes die with the batch process (Linux
parent-death signal plus a watchdog thread), so a ``kill -9`` of the job leaves no workers behind.

Every record carries ``provenance`` (software version, cell and calibration hashes, recipe version);
``--resume`` refuses to continue a results file whose records were made with a different one.

The results file is the job's only state. Each record is appended with one ``os.write`` of the whole
line on an ``O_APPEND`` descriptor and fsynced, so a run killed at any moment (``kill -9``) leaves
complete lines plus at most one torn last line; ``--resume`` drops that torn tail and runs only the
images without a record. A failure on one image (unreadable file, a bug) is a record with
``status: "failed"``, never the end of the run.

Records carry ``status``: ``answered`` (ok), ``refused`` (locate said ok=false, ``error_code`` says
why) or ``failed``.
"""

from __future__ import annotations

import csv
import json
import os
import pickle
import stat
import threading
from collections import Counter
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from multiprocessing import get_context
from pathlib import Path
from typing import TYPE_CHECKING, Any

from doorloc.app.answer import DoorChoice, DoorOut, LocateFn, provenance_of
from doorloc.app.imagesniff import (
    HEADER_BYTES_NEEDED,
    MAGIC_BYTES_NEEDED,
    decode_limit_problem,
    sniff_image,
    sniff_kind,
)
from doorloc.app.services import DoorChoiceError, RecipeLookup, answer_image, resolve_door
from doorloc.app.settings import DEFAULT_MAX_DECODED_BYTES, DEFAULT_MAX_PIXELS
from doorloc.cell import Cell, DoorSize

if TYPE_CHECKING:  # torch is the optional extra; only run_batched's workers import it
    import numpy as np
    import torch

    from doorloc.vision.cell_light import LightMeasurement
    from doorloc.vision.cell_response import ResponseMeasurement

__all__ = [
    "BatchItem",
    "BatchJob",
    "BatchOptions",
    "claims_an_image",
    "not_images_sentence",
    "open_job",
    "plan_folder",
    "BatchSummary",
    "BatchSetupError",
    "FileLimits",
    "ResultsLog",
    "check_resume",
    "list_files",
    "find_images",
    "plan_batch",
    "measure_light_in_folder",
    "measure_response_in_folder",
    "BatchResponse",
    "batch_response",
    "BATCH_RESPONSE_DOORS",
    "BATCH_RESPONSE_MIN_DOORS",
    "BATCH_RESPONSE_FACTOR_MAX",
    "locate_item",
    "run_local",
    "run_ray",
    "run_batched",
    "run_job",
    "summarize",
]

#: statuses of a record
ANSWERED, REFUSED, FAILED = "answered", "refused", "failed"


class BatchSetupError(ValueError):
    """The job cannot start (bad folder, manifest or results file); the message says what to fix."""


@dataclass(frozen=True)
class FileLimits:
    """What a batch worker agrees to read and decode (the service's defaults)."""

    max_pixels: int = DEFAULT_MAX_PIXELS
    max_decoded_bytes: int = DEFAULT_MAX_DECODED_BYTES
    #: encoded file size; a camera frame is a few MB, and a larger file is read into memory whole
    max_file_bytes: int = 200_000_000


@dataclass(frozen=True)
class BatchItem:
    """One image to locate: its name in the records (relative to the folder, '/'-separated), its path, its door."""

    image: str
    path: str
    choice: DoorChoice
    problem: str | None = None  # set when the item cannot be processed at all (e.g. unknown door_id)


@dataclass
class BatchSummary:
    """Counts of one run's records (including those found when resuming)."""

    answered: int = 0
    refused: dict[str, int] = field(default_factory=dict)
    failed: int = 0
    skipped: int = 0  # already in the results file before this run
    failed_reasons: dict[str, int] = field(default_factory=dict)

    @property
    def total(self) -> int:
        return self.answered + sum(self.refused.values()) + self.failed

    def text(self) -> str:
        refused = sum(self.refused.values())
        reasons = ", ".join(f"{k}: {v}" for k, v in sorted(self.refused.items())) or "none"
        failures = ", ".join(f"{k}: {v}" for k, v in sorted(self.failed_reasons.items()))
        return (
            f"{self.total} images: {self.answered} answered, {refused} refused ({reasons}), {self.failed} failed"
            + (f" ({failures})" if failures else "")
            + (f"; {self.skipped} were already done" if self.skipped else "")
        )


# ---------------------------------------------------------------------------------------------- planning


def find_images(root: str | os.PathLike) -> list[Path]:
    """Image files under ``root`` (recursive, sorted), recognised by their first bytes, not their names."""
    root = Path(root)
    found = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames.sort()
        for name in sorted(filenames):
            p = Path(dirpath) / name
            try:
                with open(p, "rb") as f:
                    head = f.read(MAGIC_BYTES_NEEDED)
            except OSError:
                continue
            if sniff_kind(head) is not None:
                found.append(p)
    return found


def list_files(root: str | os.PathLike, exclude: Iterable[str | os.PathLike] = ()) -> list[Path]:
    """Every file under ``root`` that is not a folder (recursive, sorted), special files included.

    Nothing is opened: a FIFO or socket is listed like any file and gets a ``not_a_regular_file`` record
    later. ``exclude`` names files to leave out (the job's own results file and manifest).
    """
    root = Path(root)
    skip = {os.path.realpath(p) for p in exclude}
    found = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames.sort()
        found += [p for name in sorted(filenames) if os.path.realpath(p := Path(dirpath) / name) not in skip]
    return found


#: names that claim an image: such a file gets a record whatever it holds (``not_an_image`` when it is none)
IMAGE_NAME_SUFFIXES = frozenset({".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp"})


def claims_an_image(path: str | os.PathLike) -> bool:
    """True for a file the job must account for: a name that claims an image, first bytes that are one, or a
    file that cannot be looked into without risk (a FIFO, socket or device, never opened here; an unreadable
    one). A plain file that neither is nor claims to be an image (``truth.csv``, ``notes.md``) is False."""
    if Path(path).suffix.lower() in IMAGE_NAME_SUFFIXES:
        return True
    try:
        if not stat.S_ISREG(os.stat(path).st_mode):
            return True
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0))
    except OSError:
        return True
    try:
        head = os.read(fd, MAGIC_BYTES_NEEDED)
    except OSError:
        return True
    finally:
        os.close(fd)
    return sniff_kind(head) is not None


def plan_folder(
    root: str | os.PathLike, cell: Cell, exclude: Iterable[str | os.PathLike] = ()
) -> tuple[list[BatchItem], list[str]]:
    """Every image under ``root`` as the cell's default door, and the files left out as no images (paths
    relative to ``root``). A file whose name claims an image stays in (it gets a ``failed`` record saying
    what it is) and so do special files (:func:`claims_an_image`)."""
    root = Path(root)
    items, not_images = [], []
    for p in list_files(root, [*exclude]):
        name = p.relative_to(root).as_posix()
        if claims_an_image(p):
            items.append(BatchItem(name, str(p), DoorChoice(cell.default_door)))
        else:
            not_images.append(name)
    return items, not_images


def _float_or_none(row: dict[str, str], key: str, where: str) -> float | None:
    v = (row.get(key) or "").strip()
    if not v:
        return None
    try:
        return float(v)
    except ValueError:
        raise BatchSetupError(f"{where}: {key} '{v}' is not a number of millimetres") from None


def plan_batch(
    root: str | os.PathLike,
    cell: Cell,
    manifest: str | os.PathLike | None = None,
    recipe_lookup: Callable[[str], Any] | None = None,
    exclude: Iterable[str | os.PathLike] = (),
) -> list[BatchItem]:
    """The job: each file with its door.

    Without a manifest: every image under ``root`` (:func:`plan_folder`), as the cell's default door;
    ``exclude`` leaves out the job's own files. With one (CSV with ``image`` and ``door_id`` or ``width_mm,thickness_mm[,height_mm]``,
    optional ``arris_mm``): exactly its rows, image paths relative to ``root``. ``recipe_lookup(door_id)``
    returns a recipe, a ``(recipe, version)`` pair, or None.
    """
    root = Path(root)
    if not root.is_dir():
        raise BatchSetupError(f"{root} is not a folder; give the folder that holds the images")
    if manifest is None:
        return plan_folder(root, cell, exclude)[0]
    try:
        text = Path(manifest).read_text(encoding="utf-8-sig")
    except OSError as e:
        raise BatchSetupError(f"cannot read manifest {manifest}: {e.strerror or e}") from None
    reader = csv.DictReader(text.splitlines())
    if not reader.fieldnames or "image" not in reader.fieldnames:
        raise BatchSetupError(f"{manifest}: the first line must name the columns, with at least 'image'")
    items: list[BatchItem] = []
    seen: set[str] = set()
    lookup = _cached(recipe_lookup)
    for line_no, row in enumerate(reader, start=2):
        item = _manifest_item(row, f"{manifest} line {line_no}", root, cell, lookup)
        if item.image in seen:
            raise BatchSetupError(f"{manifest} line {line_no}: image '{item.image}' is listed twice")
        seen.add(item.image)
        items.append(item)
    return items


def measure_light_in_folder(
    root: str | os.PathLike,
    cell_path: str | os.PathLike,
    manifest: str | os.PathLike | None = None,
    progress: Callable[[str], None] | None = None,
) -> LightMeasurement:
    """The cell's light measured from the door images under ``root``, their doors from ``manifest`` (as
    :func:`plan_batch` reads it, ``door_id`` rows excepted: no recipe database here) or else the cell's
    default door: :func:`doorloc.vision.cell_light.measure_cell_light` (``progress`` its).

    Raises :class:`doorloc.cell.CellFileError`, :class:`BatchSetupError`,
    :class:`doorloc.vision.imageio.ImageDecodeError` (unusable files) and
    :class:`doorloc.vision.cell_light.LightNotMeasurable` (the images cannot tell the light).
    """
    from doorloc.vision.cell_light import measure_cell_light

    cell, frames = _door_frames(root, cell_path, manifest)
    return measure_cell_light(frames, cell, progress=progress)


def measure_response_in_folder(
    root: str | os.PathLike,
    cell_path: str | os.PathLike,
    manifest: str | os.PathLike | None = None,
    progress: Callable[[str], None] | None = None,
) -> ResponseMeasurement:
    """The camera's response (and the cell's light) measured from the door images under ``root``, their
    doors as :func:`measure_light_in_folder` reads them: :func:`doorloc.vision.cell_response.
    measure_cell_response` (``progress`` its).

    Raises as :func:`measure_light_in_folder`, and :class:`doorloc.vision.cell_response.
    ResponseNotMeasurable` where the images cannot tell the response.
    """
    from doorloc.vision.cell_response import measure_cell_response

    cell, frames = _door_frames(root, cell_path, manifest)
    return measure_cell_response(frames, cell, progress=progress)


#: the most doors with rounded arrises a batch measures its camera's response from (spread over its rounded
#: doors; ``doorloc measure-light --response`` is measured on eight), and the fewest it tries with (five
#: doors, each under its own lamp, found a camera of 1.8 within a factor 1.4: tests/vision/test_cell_response.py)
BATCH_RESPONSE_DOORS, BATCH_RESPONSE_MIN_DOORS = 8, 5
#: the widest range (a factor about the exponent found) a batch takes in place of the cell's stated exponent:
#: a wider one narrows the stated doubt little and moves the answers off a stated exponent that may be right
#: (two rendered jobs of 16 doors, their cameras stated right, each door its own lamp: measured 1.18 and 1.23
#: times the cameras' exponents within factors 2.08 and 2.01; located with them, x RMS 0.0023 -> 0.0223 mm
#: and 24 -> 23 doors answered: bench/bench_batch_response.py --jobs 2, before this bound)
BATCH_RESPONSE_FACTOR_MAX = 1.5


@dataclass(frozen=True)
class BatchResponse:
    """The cell a job's doors are located with, and what :func:`batch_response` did to its camera's response:
    ``measurement`` (None where nothing was measured; where its range is wider than
    ``BATCH_RESPONSE_FACTOR_MAX``, ``cell`` is the job's own) and ``sentence``, what the operator is told
    (None where the cell's response was measured already or the job has too few rounded doors to tell)."""

    cell: Cell
    measurement: ResponseMeasurement | None = None
    sentence: str | None = None


def batch_response(
    items: list[BatchItem],
    cell: Cell,
    limits: FileLimits | None = None,
    progress: Callable[[str], None] | None = None,
) -> BatchResponse:
    """The cell with its camera's response measured from the job's own doors, where the cell only states it.

    A stated exponent is taken as known within ``locate.response_unmeasured_factor`` (2.2 unless set), and
    that doubt refuses many rounded and chamfered doors as uncertain; one door's strips seldom narrow it, but
    many doors of one camera together do (:func:`doorloc.vision.cell_response.measure_cell_response`: under a
    lamp common to the doors, or each door's own). So where the cell's camera has no measured response (no
    ``camera.response_gamma_sigma``, no photometric model) and a factor above the measurement's floor, and
    at least ``BATCH_RESPONSE_MIN_DOORS`` of the job's doors have rounded arrises, up to
    ``BATCH_RESPONSE_DOORS`` of them, spread over the job, are read with trial exponents (a minute or two
    on one core), and every door is located with the exponent found and its range; where the doors cannot
    tell it, or only within more than ``BATCH_RESPONSE_FACTOR_MAX``, the cell stays as it is and the
    sentence says why. Where the doors' strips rule out a shoulder in the response
    (:class:`doorloc.vision.cell_response.ShoulderReading`), the doors are located with the shoulder doubted
    only above the brightest level the measured doors reached (``locate.response_shoulder_knee``).
    ``progress`` hears the measurement's lines.
    Deterministic: a resumed job measures the same.
    """
    from doorloc.vision.cell_response import (
        RESPONSE_FACTOR_FLOOR,
        ResponseNotMeasurable,
        measure_cell_response,
    )

    if (
        cell.response_gamma_sigma is not None
        or cell.camera_photometry is not None
        or cell.locate.response_unmeasured_factor <= RESPONSE_FACTOR_FLOOR
    ):
        return BatchResponse(cell)
    picked = _rounded_doors_spread(items)
    if picked is None:
        return BatchResponse(cell)
    frames = []
    for it in picked:
        decoded = _decode(it, cell, limits or FileLimits())
        if isinstance(decoded, tuple):  # (a record where the file cannot be read: the job will say why)
            frames.append((decoded[0], it.choice.door))
    stated = (
        f"the cell's stated exponent {cell.response_gamma:g} used, known within a factor "
        f"{cell.locate.response_unmeasured_factor:g}"
    )
    try:
        m = measure_cell_response(frames, cell, progress=progress)
    except ResponseNotMeasurable as e:
        return BatchResponse(
            cell, None, f"the camera's response was not measured from the doors ({e}): {stated}"
        )
    except Exception as e:  # noqa: BLE001 - the job goes on with the cell as stated; each door's record says more
        return BatchResponse(
            cell,
            None,
            f"the camera's response could not be measured from the doors ({type(e).__name__}: {e}; please report "
            f"it): {stated}",
        )
    if m.factor > BATCH_RESPONSE_FACTOR_MAX:
        return BatchResponse(
            cell,
            m,
            f"the doors tell the camera's response only within exponents {m.gamma / m.factor:.2f}-"
            f"{m.gamma * m.factor:.2f} (a factor {m.factor:.2f}, more than {BATCH_RESPONSE_FACTOR_MAX:g}): {stated}",
        )
    return BatchResponse(m.applied_to(cell), m, _measured_sentence(m))


def _rounded_doors_spread(items: list[BatchItem]) -> list[BatchItem] | None:
    """Up to ``BATCH_RESPONSE_DOORS`` of the job's doors with rounded arrises, spread evenly over them in the
    job's order; None where there are fewer than ``BATCH_RESPONSE_MIN_DOORS``."""
    rounded = [
        it
        for it in items
        if it.problem is None and it.choice.door.arris_mm > 0 and it.choice.door.arris_profile == "round"
    ]
    n = len(rounded)
    if n < BATCH_RESPONSE_MIN_DOORS:
        return None
    spread = {round(j * (n - 1) / (BATCH_RESPONSE_DOORS - 1)) for j in range(BATCH_RESPONSE_DOORS)}
    return [rounded[k] for k in sorted(spread)]


def _measured_sentence(m: ResponseMeasurement) -> str:
    """What the operator is told of a response the batch measured and located every door with."""
    sentence = (
        f"the camera's response measured from {m.doors} of the batch's doors with rounded arrises: gamma "
        f"{m.gamma:.3f} +- {m.sigma:.3f} (exponents {m.gamma / m.factor:.2f}-{m.gamma * m.factor:.2f}; the "
        f"cell states {m.cell_gamma:g}); every door located with it (to skip this measurement, state it in "
        f"the cell: camera.response_gamma: {m.gamma:.3f}, response_gamma_sigma: {m.sigma:.3f})"
    )
    if m.shoulder is not None and m.shoulder.ruled_out:
        sentence += (
            f"; their roundings rule out a shoulder in the response from {m.shoulder.knee:g} of full scale up "
            f"to {m.shoulder.reached:.2f}, the brightest level they reach, and a shoulder is doubted only above "
            "it"
        )
    if m.cell_ruled_out:
        sentence += (
            f"; warning: the cell's camera.response_gamma {m.cell_gamma:g} lies outside what the doors "
            "allow: check the camera's gamma setting"
        )
    return sentence


def _door_frames(
    root: str | os.PathLike, cell_path: str | os.PathLike, manifest: str | os.PathLike | None
) -> tuple[Cell, list[tuple[np.ndarray, DoorSize]]]:
    """The cell and its door images under ``root`` with their doors (``manifest`` or the cell's door)."""
    from doorloc.cell import load_cell
    from doorloc.vision.imageio import read_image

    cell = load_cell(cell_path)
    items = plan_batch(root, cell, manifest)
    if problems := [f"{it.image}: {it.problem}" for it in items if it.problem]:
        raise BatchSetupError("; ".join(problems[:5]) + ("; ..." if len(problems) > 5 else ""))
    if not items:
        raise BatchSetupError(f"no images under {root}")
    return cell, [(read_image(it.path), it.choice.door) for it in items]


def _cached(lookup: RecipeLookup | None) -> RecipeLookup:
    """``lookup`` asked once per door id (a manifest names the same door on many rows); None finds nothing.

    A lookup may return a bare recipe (no version) as well as a ``(recipe, version)`` pair."""
    known: dict[str, Any] = {}

    def cached(door_id: str) -> Any:
        if door_id not in known:
            try:
                found = lookup(door_id) if lookup is not None else None
                known[door_id] = found if found is None or isinstance(found, tuple) else (found, None)
            except ValueError as e:  # a stored recipe that today's rules refuse: asked again, refused again
                known[door_id] = e
        if isinstance(known[door_id], ValueError):
            raise known[door_id]
        return known[door_id]

    return cached


def _manifest_item(
    row: dict[str, str], where: str, root: Path, cell: Cell, lookup: RecipeLookup
) -> BatchItem:
    """One manifest row as a job item. A door id without a usable recipe is a row that fails (a record
    saying why); a size outside the accepted ranges stops the job before it starts (BatchSetupError)."""
    image = (row.get("image") or "").strip()
    if not image:
        raise BatchSetupError(f"{where}: 'image' is empty")
    path = str(root / image)
    door_id = (row.get("door_id") or "").strip() or None
    # with a door id the recipe gives the size and the size columns are not read
    w, t, h = (
        None if door_id else _float_or_none(row, k, where) for k in ("width_mm", "thickness_mm", "height_mm")
    )
    try:
        arris = _float_or_none(row, "arris_mm", where)
        choice = resolve_door(
            cell, lookup, door_id=door_id, width_mm=w, thickness_mm=t, height_mm=h, arris_mm=arris
        )
    except DoorChoiceError as e:
        if door_id is not None and e.code in ("unknown_door", "unusable_recipe"):
            return BatchItem(image, path, DoorChoice(cell.default_door, door_id), str(e))
        raise BatchSetupError(f"{where}: {e}") from None
    return BatchItem(image, path, choice)


# ---------------------------------------------------------------------------------------------- one image


def _failed(item: BatchItem, code: str, error: str, cell: Cell | None = None) -> dict[str, Any]:
    from doorloc.vision.result import LocateResult

    record = LocateResult.refusal(item.image, code, error).model_dump(mode="json")
    record.update(
        door_id=item.choice.door_id,
        door=DoorOut.of(item.choice.door).model_dump(),
        targets=[],
        targets_note=None,
        status=FAILED,
    )
    if cell is not None:
        record["provenance"] = provenance_of(cell, item.choice).model_dump(mode="json")
    return record


def read_file_checked(path: str, limits: FileLimits) -> tuple[bytes | None, str, str]:
    """The file's bytes, or None with ``(code, sentence)`` saying why it is not an image this job decodes.

    Opened with O_NONBLOCK and checked with fstat on the open descriptor, so a FIFO, socket or device
    (or a file swapped for one after listing) is named, never waited on.
    """
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0))
    except OSError as e:
        return None, "unreadable", f"cannot open {path}: {e.strerror or e}"
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            kind = (
                "a FIFO"
                if stat.S_ISFIFO(st.st_mode)
                else "a socket"
                if stat.S_ISSOCK(st.st_mode)
                else "a device"
                if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode)
                else "not a file"
            )
            return None, "not_a_regular_file", f"{path} is {kind}, not a regular file; it was not read"
        if st.st_size == 0:
            return None, "empty_file", f"{path} is empty (0 bytes); copy the camera image again"
        if st.st_size > limits.max_file_bytes:
            return (
                None,
                "too_large",
                (
                    f"{path} is {st.st_size / 1e6:.0f} MB, more than the "
                    f"{limits.max_file_bytes / 1e6:.0f} MB a camera image may take"
                ),
            )
        with os.fdopen(os.dup(fd), "rb") as f:
            data = f.read(limits.max_file_bytes + 1)
    except OSError as e:
        return None, "unreadable", f"cannot read {path}: {e.strerror or e}"
    finally:
        os.close(fd)
    header = sniff_image(data[:HEADER_BYTES_NEEDED])
    if header is None:
        return (
            None,
            "not_an_image",
            f"{path} is not a PNG, JPEG, TIFF or BMP image (judged by its first bytes)",
        )
    problem = decode_limit_problem(header, path, limits.max_pixels, limits.max_decoded_bytes)
    if problem is not None:
        return None, "too_large", problem
    return data, "", ""


def locate_item(
    item: BatchItem, cell: Cell, locate_fn: LocateFn | None = None, limits: FileLimits | None = None
) -> dict[str, Any]:
    """The record of one file; never raises (a failure is a record with ``status: "failed"`` and a reason)."""
    from doorloc.vision.imageio import ImageDecodeError, decode_image, stored_jpeg_quality

    if item.problem is not None:
        return _failed(item, "bad_job_row", item.problem, cell)
    data, code, why = read_file_checked(item.path, limits or FileLimits())
    if data is None:
        return _failed(item, code, why, cell)
    try:
        image = decode_image(data, name=item.path)
    except ImageDecodeError as e:
        return _failed(item, "unreadable_image", str(e), cell)
    quality = stored_jpeg_quality(data)
    del data
    try:
        fields = answer_image(
            image, cell, item.choice, image_name=item.image, locate_fn=locate_fn, jpeg_quality=quality
        ).fields
    except Exception as e:  # noqa: BLE001 - one bad image must not end a run of thousands
        return _failed(
            item,
            "internal_error",
            f"locate failed on this image ({type(e).__name__}: {e}); please report it",
            cell,
        )
    fields["status"] = ANSWERED if fields["ok"] else REFUSED
    return fields


def _die_with_parent(parent_pid: int) -> None:
    """Make this worker process end when the batch process does, however it ends (``kill -9`` included).

    Linux's parent-death signal acts at once; the watchdog thread covers other systems and the moment
    between the fork and the prctl call.
    """
    import signal
    import sys
    import time

    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            pr_set_pdeathsig = 1
            libc.prctl(pr_set_pdeathsig, signal.SIGKILL, 0, 0, 0)
        except (OSError, AttributeError):  # no libc prctl: the watchdog alone
            pass
    if os.getppid() != parent_pid:
        os._exit(1)

    def watchdog() -> None:
        while True:  # ends with the process (daemon thread)
            if os.getppid() != parent_pid:
                os._exit(1)
            time.sleep(0.5)

    threading.Thread(target=watchdog, name="doorloc-parent-watchdog", daemon=True).start()


def _worker_init(parent_pid: int) -> None:
    _die_with_parent(parent_pid)
    _configure_opencv()


def _configure_opencv() -> None:
    import cv2

    # One image per worker process at a time; the processes already fill the cores.
    cv2.setNumThreads(1)
    # A damaged file becomes a record saying so; OpenCV's own warnings would only garble the progress bar.
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)


# ---------------------------------------------------------------------------------------------- results file


class ResultsLog:
    """The append-only JSONL results file of a batch job.

    Parameters
    ----------
    path : path-like
        ``results.jsonl``.
    resume : bool
        Keep what is there (dropping a torn last line) and report the images already done. Without it
        an existing non-empty file is an error, so a finished job is never overwritten by accident.
    """

    def __init__(self, path: str | os.PathLike, resume: bool) -> None:
        self.path = Path(path)
        self.done: dict[str, dict[str, Any]] = {}
        exists = self.path.exists() and self.path.stat().st_size > 0
        if exists and not resume:
            raise BatchSetupError(
                f"{self.path} already holds results; pass --resume to continue that job, or choose another --out"
            )
        if exists:
            self._recover()
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)

    def _recover(self) -> None:
        data = self.path.read_bytes()
        complete_end = data.rfind(b"\n") + 1  # bytes up to and including the last newline
        if complete_end < len(data):
            # The run was killed in the middle of a write: drop the torn tail, its image runs again.
            with open(self.path, "r+b") as f:
                f.truncate(complete_end)
                f.flush()
                os.fsync(f.fileno())
        for n, line in enumerate(data[:complete_end].splitlines(), start=1):
            if not line.strip():
                continue
            try:
                record = json.loads(line)
                image = record["image"]
            except (ValueError, KeyError, TypeError):
                raise BatchSetupError(
                    f"{self.path} line {n} is not a doorloc result record; it is not a results file this job wrote"
                ) from None
            self.done[image] = record

    def append(self, record: dict[str, Any]) -> None:
        """Append one record as one line: a single write of the whole line, then fsync."""
        line = (json.dumps(record, separators=(",", ":"), allow_nan=False) + "\n").encode()
        written = os.write(self._fd, line)
        if written != len(line):  # pragma: no cover - regular files take whole writes; a full disk raises
            raise OSError(f"short write to {self.path} ({written} of {len(line)} bytes)")
        os.fsync(self._fd)
        self.done[record["image"]] = record

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1

    def __enter__(self) -> ResultsLog:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# ---------------------------------------------------------------------------------------------- backends


def run_local(
    items: list[BatchItem],
    cell: Cell,
    *,
    workers: int,
    locate_fn: LocateFn | None = None,
    limits: FileLimits | None = None,
) -> Iterator[dict[str, Any]]:
    """Locate ``items`` in ``workers`` processes; yield each record as soon as it is ready (any order).

    ``workers <= 1`` runs in this process. ``locate_fn`` must be a module-level function (it is pickled).
    At most ``2 * workers`` images are in flight, so memory stays bounded on archives of any size.
    """
    if workers <= 1:
        _configure_opencv()
        for it in items:
            yield locate_item(it, cell, locate_fn, limits)
        return
    # "spawn": the parent runs a progress thread, and fork with threads is unsafe.
    with ProcessPoolExecutor(
        workers, mp_context=get_context("spawn"), initializer=_worker_init, initargs=(os.getpid(),)
    ) as pool:
        yield from _in_flight(pool, items, 2 * workers, lambda it: (locate_item, it, cell, locate_fn, limits))


def _in_flight(pool: ProcessPoolExecutor, jobs: Iterable[Any], limit: int, call: Callable) -> Iterator[Any]:
    """Each job's result from ``pool`` as soon as it is ready, at most ``limit`` jobs submitted at a time.

    ``call(job)`` gives ``(function, *args)``; bounding what is in flight keeps memory flat on archives of
    any size (``pool.map`` would submit them all).
    """
    pending: set = set()
    queue = iter(jobs)
    exhausted = False
    while True:
        while not exhausted and len(pending) < limit:
            nxt = next(queue, None)
            if nxt is None:
                exhausted = True
                break
            pending.add(pool.submit(*call(nxt)))
        if not pending:
            return
        finished, pending = wait(pending, return_when=FIRST_COMPLETED)
        for fut in finished:
            yield fut.result()


def run_ray(
    items: list[BatchItem],
    cell: Cell,
    *,
    workers: int,
    locate_fn: LocateFn | None = None,
    ray_address: str | None = None,
    limits: FileLimits | None = None,
) -> Iterator[dict[str, Any]]:
    """The same job on Ray Data: items become a dataset, each mapped by :func:`locate_item` on a Ray worker.

    Records stream back to this process as Ray finishes them, so the results file grows the same way as
    with the local backend (and resumes the same way). Starts a local Ray instance with ``workers`` CPUs
    unless ``ray_address`` names a cluster.
    """
    try:
        import ray
    except ImportError:
        raise BatchSetupError("the ray backend needs Ray: pip install 'doorloc[ray]'") from None
    if not items:
        return
    started_here = False
    if not ray.is_initialized():
        kwargs: dict[str, Any] = {
            "include_dashboard": False,
            "log_to_driver": False,
            "configure_logging": False,
        }
        if ray_address:
            ray.init(address=ray_address, **kwargs)
        else:
            ray.init(num_cpus=max(1, workers), **kwargs)
        started_here = True
    try:
        ctx = ray.data.DataContext.get_current()
        ctx.enable_progress_bars = False
        # Rows carry the pickled item: a DoorChoice holds a pydantic recipe, which Arrow cannot store as columns.
        rows = [{"item": pickle.dumps(it)} for it in items]
        ds = ray.data.from_items(rows, override_num_blocks=min(len(rows), max(1, workers) * 4))

        def _locate_batch(batch: dict[str, Any]) -> dict[str, Any]:
            _configure_opencv()
            records = [locate_item(pickle.loads(b), cell, locate_fn, limits) for b in batch["item"]]
            return {"record": [json.dumps(r, allow_nan=False) for r in records]}

        out = ds.map_batches(_locate_batch, batch_size=1, concurrency=max(1, workers))
        for row in out.iter_rows():
            yield json.loads(row["record"])
    finally:
        if started_here:
            ray.shutdown()


def _decode(item: BatchItem, cell: Cell, limits: FileLimits) -> Any:
    """The item's image and its file's JPEG quality (0: not a JPEG), or the record saying why there is none
    (runs in a worker process).

    The same file checks as :func:`locate_item` (no waiting on special files, no decoding past the limits).
    """
    from doorloc.vision.imageio import ImageDecodeError, decode_image, stored_jpeg_quality

    if item.problem is not None:
        return _failed(item, "bad_job_row", item.problem, cell)
    data, code, why = read_file_checked(item.path, limits)
    if data is None:
        return _failed(item, code, why, cell)
    try:
        return decode_image(data, name=item.path), stored_jpeg_quality(data)
    except ImageDecodeError as e:
        return _failed(item, "unreadable_image", str(e), cell)


def run_batched(
    items: list[BatchItem],
    cell: Cell,
    *,
    device: str,
    batch_size: int,
    workers: int,
    limits: FileLimits | None = None,
) -> Iterator[dict[str, Any]]:
    """The local job with locate batched on torch (:mod:`doorloc.vision.batched`, the doorloc torch extra).

    The items are cut into batches of ``batch_size`` frames. Each of ``workers`` processes takes a whole
    batch: it decodes the frames and locates them together on ``device`` (cpu, cuda or auto; on CUDA every
    worker holds its own context on the one GPU). The workers, not this process, do the sub-pixel stage:
    that stage runs frame by frame on the CPU (see :mod:`doorloc.vision.batched`), so one locating process
    would cap the job at one core's rate however fast the device is. At most ``2 * workers`` batches are in
    flight. The records are those of :func:`run_local` (any order); a frame the batched path could not take
    carries ``diagnostics.batched_fallback``.
    """
    from doorloc.vision.batched import resolve_device

    resolve_device(device)  # a clear error here, not in every worker
    limits = limits or FileLimits()
    chunks = [items[i : i + batch_size] for i in range(0, len(items), max(1, batch_size))]
    if workers <= 1:
        _configure_worker_torch()
        for chunk in chunks:
            yield from locate_chunk(chunk, cell, device, limits)
        return
    # workers die with the batch process, as run_local's do (_worker_init)
    with ProcessPoolExecutor(
        workers, mp_context=get_context("spawn"), initializer=_batched_worker_init, initargs=(os.getpid(),)
    ) as pool:
        for records in _in_flight(
            pool, chunks, 2 * workers, lambda c: (locate_chunk, c, cell, device, limits)
        ):
            yield from records


def _batched_worker_init(parent_pid: int) -> None:
    _worker_init(parent_pid)
    _configure_worker_torch()


def _configure_worker_torch() -> None:
    _configure_opencv()
    import torch

    # as OpenCV's: the processes fill the cores, and torch's own threads would only contend with them
    torch.set_num_threads(1)


def locate_chunk(chunk: list[BatchItem], cell: Cell, device: str, limits: FileLimits) -> list[dict[str, Any]]:
    """Decode one batch of items and locate its frames together on ``device``; one record per item.

    On CPU the frames' step searches are answered frame by frame anyway (:func:`locate_batch`'s ``auto``
    finder), so each frame is decoded just before it is located: decoding the whole batch first only
    pushed each frame out of the caches before its turn came.
    """
    from doorloc.vision.batched import resolve_device

    dev = resolve_device(device)
    if dev.type == "cpu":
        return [rec for it in chunk for rec in _locate_together([it], cell, dev, limits)]
    return _locate_together(chunk, cell, dev, limits)


def _locate_together(
    chunk: list[BatchItem], cell: Cell, dev: torch.device, limits: FileLimits
) -> list[dict[str, Any]]:
    """Decode ``chunk`` and locate its frames in one :func:`locate_batch` call on ``dev``."""
    from doorloc.vision.batched import locate_batch

    decoded = [_decode(it, cell, limits) for it in chunk]
    records = [rec for rec in decoded if isinstance(rec, dict)]
    ok = [(it, *got) for it, got in zip(chunk, decoded, strict=True) if not isinstance(got, dict)]
    answers = locate_batch(
        [img for _, img, _ in ok],
        cell,
        [it.choice.door for it, _, _ in ok],
        names=[it.image for it, _, _ in ok],
        device=dev,
        jpeg_qualities=[quality for _, _, quality in ok],
    )
    for (it, img, _), a in zip(ok, answers, strict=True):
        if a.fallback:
            a.result.diagnostics["batched_fallback"] = a.fallback
        try:
            fields = answer_image(
                img, cell, it.choice, image_name=it.image, locate_fn=lambda *_, _r=a.result, **__: _r
            ).fields
        except Exception as e:  # noqa: BLE001 - as locate_item: one bad image must not end the run
            records.append(
                _failed(
                    it,
                    "internal_error",
                    f"locate failed on this image ({type(e).__name__}: {e}); please report it",
                    cell,
                )
            )
            continue
        fields["status"] = ANSWERED if fields["ok"] else REFUSED
        records.append(fields)
    return records


# ---------------------------------------------------------------------------------------------- the job


def run_job(
    items: list[BatchItem],
    log: ResultsLog,
    backend: Callable[[list[BatchItem]], Iterable[dict[str, Any]]],
    on_record: Callable[[dict[str, Any]], None] | None = None,
) -> BatchSummary:
    """Run the items without a record in ``log`` through ``backend``, appending each record as it comes.

    Returns the summary over all planned items (those done by an earlier, interrupted run included).
    """
    todo = [it for it in items if it.image not in log.done]
    for record in backend(todo):
        log.append(record)
        if on_record is not None:
            on_record(record)
    planned = {it.image for it in items}
    return summarize((r for name, r in log.done.items() if name in planned), skipped=len(items) - len(todo))


# ---------------------------------------------------------------------------------------------- summary


def summarize(records: Iterable[dict[str, Any]], skipped: int = 0) -> BatchSummary:
    """Answered, refused by reason, failed."""
    s = BatchSummary(skipped=skipped)
    refused: Counter[str] = Counter()
    failed: Counter[str] = Counter()
    for r in records:
        status = r.get("status") or (ANSWERED if r.get("ok") else REFUSED)
        if status == ANSWERED:
            s.answered += 1
        elif status == FAILED:
            s.failed += 1
            if r.get("error_code"):
                failed[r["error_code"]] += 1
        else:
            refused[r.get("error_code") or "unknown"] += 1
    s.refused = dict(refused)
    s.failed_reasons = dict(failed)
    return s


#: provenance items a resumed job must share with the records already written
_PROVENANCE_KEYS = ("version", "cell_sha256", "calibration_sha256")
_PROVENANCE_WORDS = {
    "version": "the doorloc version",
    "cell_sha256": "the cell file",
    "calibration_sha256": "the camera calibration",
    "recipe_version": "the recipe",
}


def check_resume(done: dict[str, dict[str, Any]], items: list[BatchItem], cell: Cell) -> None:
    """Refuse (BatchSetupError naming what changed) to add records made with another model to a results file.

    Every record already written must carry the provenance this run would write: the same doorloc version,
    cell file and calibration, and, for each door from a recipe, the same recipe version.
    """
    by_image = {it.image: it for it in items}
    for image, record in done.items():
        it = by_image.get(image)
        want = provenance_of(cell, it.choice if it is not None else DoorChoice(cell.default_door)).model_dump(
            mode="json"
        )
        have = record.get("provenance")
        if not isinstance(have, dict):
            raise BatchSetupError(
                f"cannot resume: the record of '{image}' has no provenance (written by an older doorloc), so it "
                "cannot be shown to come from the same cell, calibration and recipes; start a new --out"
            )
        keys = [*_PROVENANCE_KEYS, *(["recipe_version"] if it is not None and it.choice.door_id else [])]
        for k in keys:
            if have.get(k) != want.get(k):
                raise BatchSetupError(
                    f"cannot resume: {_PROVENANCE_WORDS[k]} changed since the results were written ({k} "
                    f"{have.get(k)!r} in the record of '{image}', {want.get(k)!r} now); one results file must "
                    "not mix two models: start a new --out, or restore what changed"
                )


# ---------------------------------------------------------------------------------------------- one call


@dataclass(frozen=True)
class BatchOptions:
    """How a job runs: ``backend`` local or ray, ``workers`` processes, ``device`` (cpu, cuda, auto: batches
    of ``batch_size`` frames on torch; None: one frame at a time)."""

    backend: str = "local"
    workers: int = 1
    ray_address: str | None = None
    device: str | None = None
    batch_size: int = 32

    def check(self) -> None:
        """Raise BatchSetupError with a sentence for an unknown backend or an unusable device."""
        if self.backend not in ("local", "ray"):
            raise BatchSetupError(f"--backend must be 'local' or 'ray', not '{self.backend}'")
        if self.device is None:
            return
        try:
            from doorloc.vision.batched import resolve_device

            resolve_device(self.device)
        except ImportError:
            raise BatchSetupError("--device needs torch: pip install 'doorloc[torch]'") from None
        except ValueError as e:
            raise BatchSetupError(str(e)) from None

    def backend_for(self, cell: Cell) -> Callable[[list[BatchItem]], Iterable[dict[str, Any]]]:
        """``items -> records`` on the chosen backend."""

        def run(todo: list[BatchItem]) -> Iterable[dict[str, Any]]:
            if self.device is not None:
                return run_batched(
                    todo, cell, device=self.device, batch_size=self.batch_size, workers=self.workers
                )
            if self.backend == "ray":
                return run_ray(todo, cell, workers=self.workers, ray_address=self.ray_address)
            return run_local(todo, cell, workers=self.workers)

        return run


@dataclass
class BatchJob:
    """A job ready to run: its items, its open results file, the files left out as no images."""

    items: list[BatchItem]
    log: ResultsLog
    not_images: list[str] = field(default_factory=list)


def open_job(
    folder: str | os.PathLike,
    cell: Cell,
    out: str | os.PathLike,
    *,
    manifest: str | os.PathLike | None = None,
    recipe_lookup: Callable[[str], Any] | None = None,
    resume: bool = False,
) -> BatchJob:
    """The job's items and its results file, opened (and checked against ``--resume``'s records).

    Raises BatchSetupError (or OSError) with a sentence; nothing is left open then.
    """
    own_files = [out, *([manifest] if manifest else [])]
    not_images: list[str] = []
    if manifest is None:
        if not Path(folder).is_dir():
            raise BatchSetupError(f"{folder} is not a folder; give the folder that holds the images")
        items, not_images = plan_folder(folder, cell, own_files)
    else:
        items = plan_batch(folder, cell, manifest, recipe_lookup, exclude=own_files)
    log = ResultsLog(out, resume)
    try:
        check_resume(log.done, items, cell)
    except BatchSetupError:
        log.close()
        raise
    return BatchJob(items, log, not_images)


def not_images_sentence(names: list[str]) -> str:
    """``skipped 2 files that are not images (notes.md, truth.csv)`` (at most five named)."""
    shown = ", ".join(names[:5]) + (f" and {len(names) - 5} more" if len(names) > 5 else "")
    return f"skipped {len(names)} file{'s' if len(names) != 1 else ''} that {'are' if len(names) != 1 else 'is'} not an image ({shown})"
