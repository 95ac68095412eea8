"""``POST /v1/locate``: an uploaded image in, the door's pose and robot targets out.

Order of the checks, cheapest first, so a bad upload costs almost nothing: size (while streaming, in
the middleware) -> kind by magic bytes (415) -> declared pixel count (422, before decoding) -> decode
(422) -> locate. Each request holds a CPU slot of the app's FairSlots while decoding and locating, which run in
one limited worker process per request (:class:`~doorloc.app.decodepool.DecodePool`: an image past its
decoding or locating CPU-time or memory limit ends that process and is answered 422), waited for in a worker
thread, so the event loop keeps answering health checks while images are being measured.
"""

from __future__ import annotations

import logging
import time
from dataclasses import replace
from typing import Annotated

import anyio
import anyio.to_thread
from fastapi import APIRouter, Depends, File, Form, Query, Request, Response, UploadFile
from pydantic import Field

from doorloc.app.access import Role
from doorloc.app.answer import Answer, DoorChoice, LocateResponse, overlay_png
from doorloc.app.http.admission import (
    CpuTurn,
    address_of,
    client_of,
    decode_upload,
    hold_refusal,
    locate_upload,
    release_cpu_slot,
    take_cpu_slot,
)
from doorloc.app.http.dependencies import call_store, ready_state, require_role
from doorloc.app.http.problems import ProblemError, problem_responses
from doorloc.app.http.state import ServiceState
from doorloc.app.imagesniff import decode_limit_code, decode_limit_problem, sniff_image
from doorloc.app.services import DoorChoiceError, answer_image, answer_located, resolve_door
from doorloc.recipes.models import DOOR_ID_PATTERN
from doorloc.vision.imageio import stored_jpeg_quality

__all__ = ["router"]

_log = logging.getLogger("doorloc.http")

router = APIRouter(dependencies=[Depends(require_role(Role.operator))])

#: refusals of an upload that is no measurable image (as opposed to a door choice or a full queue): answered
#: after settings.image_refusal_delay_s, so a stream of decoding bombs costs a few requests a second per connection
UNMEASURABLE_UPLOAD_CODES = frozenset(
    {"empty_image", "not_an_image", "undecodable_image", "too_many_pixels", "decode_limit", "locate_limit"}
)

# Coarse bounds here; the accepted door ranges (doorloc.limits) are checked by door_from_fields, naming the field.
DoorMm = Annotated[float | None, Field(gt=0, allow_inf_nan=False)]
ArrisMm = Annotated[float | None, Field(ge=0, le=100, allow_inf_nan=False)]


@router.post(
    "/v1/locate",
    response_model=LocateResponse,
    response_model_exclude_none=False,
    summary="Locate the door in an image and return its pose and hinge targets",
    responses=problem_responses(400, 401, 403, 408, 413, 415, 422, 503),
)
async def post_locate(
    request: Request,
    response: Response,
    image: Annotated[
        UploadFile,
        File(description="the camera image: PNG, JPEG, TIFF or BMP, in the calibrated pixel frame"),
    ],
    state: Annotated[ServiceState, Depends(ready_state)],
    door_id: Annotated[
        str | None, Form(pattern=DOOR_ID_PATTERN, description="door recipe to use (gives targets)")
    ] = None,
    width_mm: Annotated[DoorMm, Form(description="door width, mm (without door_id)")] = None,
    thickness_mm: Annotated[DoorMm, Form(description="door thickness, mm (without door_id)")] = None,
    height_mm: Annotated[DoorMm, Form(description="door height, mm (without door_id)")] = None,
    arris_mm: Annotated[
        ArrisMm, Form(description="arris chamfer/rounding size, mm (default: the recipe's, else the cell's)")
    ] = None,
    overlay: Annotated[
        bool, Query(description="add overlay_png: the image with what was found drawn on it")
    ] = False,
    rapid: Annotated[bool, Query(description="add rapid: the targets as RAPID-readable text")] = False,
) -> LocateResponse:
    """Measure where the door lies (SPEC section 3 result) and move its recipe's hinge targets by that pose.

    A door that cannot be located is still a 200 answer, with ``ok: false`` and ``error`` saying why;
    4xx answers are for requests that cannot be measured at all. The ``Server-Timing`` header gives the
    CPU time of decoding and of measuring (``decode``, ``locate``: locate, targets and what else the answer
    holds), ms, this request's thread and the worker processes it used together: what the request cost the
    server itself, apart from queueing and transfer.
    """
    form = await request.form()  # already parsed for the parameters above: no second read
    if len(form.getlist("image")) > 1:
        raise ProblemError(
            422,
            "several_images",
            "The form holds more than one 'image' part; send exactly one image per request.",
        )
    data = await image.read()
    name = image.filename or "upload"
    state.metrics.in_flight.inc()
    try:
        # in a thread: reading a large JPEG's markers takes tens of ms, which on the event loop would hold up
        # every other client's request meanwhile (an attacker's stream of 12 MB JPEGs held each for that long)
        await anyio.to_thread.run_sync(_check_upload, data, name, state)
        choice = await _door_choice(state, door_id, width_mm, thickness_mm, height_mm, arris_mm)
        deadline = request.scope.get("state", {}).get("deadline")
        client, address = client_of(request.scope.get("state", {})), address_of(request.scope)
        turn = await take_cpu_slot(state, deadline, client, address)
        try:
            answer = await anyio.to_thread.run_sync(
                _measure, data, name, state, choice, overlay, rapid, deadline, turn
            )
        finally:
            release_cpu_slot(state, client, address, turn)
    except ProblemError as e:
        state.metrics.rejected_uploads.labels(e.code).inc()
        if e.code in UNMEASURABLE_UPLOAD_CODES:
            await hold_refusal(state, state.settings.image_refusal_delay_s)
        raise
    finally:
        state.metrics.in_flight.dec()
    response.headers["Server-Timing"] = ", ".join(
        f'{k};dur={v:.3f};desc="CPU ms"' for k, v in answer.cpu_ms.items()
    )
    _log_located(state, request, answer.response, door_id)
    return answer.response


def _log_located(state: ServiceState, request: Request, a: LocateResponse, door_id: str | None) -> None:
    """Count the answer in the metrics and log it (one JSON line with the request id)."""
    state.metrics.observe_locate(a.ok, a.error_code, a.elapsed_ms or 0.0)
    _log.info(
        "located",
        extra={
            "fields": {
                "event": "located",
                "request_id": request.scope.get("state", {}).get("request_id"),
                "image": a.image,
                "ok": a.ok,
                "error_code": a.error_code,
                "x_mm": a.x_mm,
                "z_mm": a.z_mm,
                "yaw_deg": a.yaw_deg,
                "door_id": door_id,
                "elapsed_ms": a.elapsed_ms,
            }
        },
    )


def _check_upload(data: bytes, name: str, state: ServiceState) -> None:
    if not data:
        raise ProblemError(
            422, "empty_image", f"The uploaded file '{name}' is empty; send the camera image itself."
        )
    header = sniff_image(data)
    if header is None:
        raise ProblemError(
            415,
            "not_an_image",
            f"The uploaded file '{name}' is not a PNG, JPEG, TIFF or BMP image (judged by its first bytes); "
            "send the camera image in one of those formats.",
        )
    if header.pixels is None:
        raise ProblemError(
            422,
            "undecodable_image",
            f"The {header.kind.upper()} header of '{name}' is cut short or malformed, so its size cannot be read; "
            "the file is probably truncated: send it again.",
        )
    problem = decode_limit_problem(
        header,
        name,
        state.settings.max_pixels,
        state.settings.max_decoded_bytes,
        state.settings.max_jpeg_scans,
    )
    if problem is not None:
        cam_w, cam_h = state.cell.camera.image_size if state.cell else ("?", "?")
        raise ProblemError(
            422,
            decode_limit_code(header, state.settings.max_pixels, state.settings.max_decoded_bytes),
            f"{problem[0].upper()}{problem[1:]}; send the camera's own image ({cam_w}x{cam_h}).",
        )


async def _door_choice(
    state: ServiceState,
    door_id: str | None,
    width_mm: float | None,
    thickness_mm: float | None,
    height_mm: float | None,
    arris_mm: float | None = None,
) -> DoorChoice:
    """:func:`doorloc.app.services.resolve_door` in a worker thread (it may read the recipe database)."""
    assert state.cell is not None  # the route depends on ready_state
    cell, store = state.cell, state.recipes

    def resolve() -> DoorChoice:
        return resolve_door(
            cell,
            store.get_versioned,
            door_id=door_id,
            width_mm=width_mm,
            thickness_mm=thickness_mm,
            height_mm=height_mm,
            arris_mm=arris_mm,
        )

    try:
        choice: DoorChoice = await call_store(resolve)
    except DoorChoiceError as e:
        raise ProblemError(422, e.code, f"{str(e)[0].upper()}{str(e)[1:]}.") from None
    return choice


def _measure(
    data: bytes,
    name: str,
    state: ServiceState,
    choice: DoorChoice,
    overlay: bool,
    rapid: bool,
    deadline: float | None = None,
    turn: CpuTurn | None = None,
) -> Answer:
    """The answer, with the CPU ms of decoding and of measuring (``decode``, ``locate``).

    When the service locates in its limited worker processes, one of them decodes the image and locates in it
    (one job: the decoded image never crosses a pipe; a lower-priority one for an ``over_share`` turn), and
    ``decode`` and ``locate`` are the workers' CPU time with this thread's (the hand-over, the targets and
    the reach check): :meth:`Located.cpu_ms`. A locate given in code runs here, on the image decoded in a
    worker process (or in this thread: ``decode_in_threads``), and ``decode`` holds that process's time too.
    The overlay is drawn only for an answered image of a sane size: a refused 7.2 MB JPEG once made a
    97 MB answer.
    """
    assert state.cell is not None  # the route depends on ready_state
    if state.locates_in_workers:
        t0 = time.thread_time()
        located = locate_upload(state, data, name, choice.door, overlay, deadline, turn)
        answer = answer_located(located.result, state.cell, choice, rapid=rapid, overlay=located.overlay_png)
        cpu_ms = located.cpu_ms(time.thread_time() - t0)
    else:
        assert state.locate_fn is not None  # a ready service has one
        t0 = time.thread_time()
        image, worker_s = decode_upload(state, data, name, deadline)
        decode_ms = (time.thread_time() - t0 + worker_s) * 1e3
        trace = None
        if overlay:
            from doorloc.vision.locate import LocateTrace

            trace = LocateTrace()
        answer = answer_image(
            image,
            state.cell,
            choice,
            image_name=name,
            locate_fn=state.locate_fn,
            rapid=rapid,
            trace=trace,
            jpeg_quality=stored_jpeg_quality(data),
        )
        drawn = None
        if (
            overlay
            and answer.response.ok
            and image.shape[0] * image.shape[1] <= state.settings.overlay_max_pixels
        ):
            drawn = overlay_png(image, answer.result, state.cell, choice.door, trace)
        answer = replace(answer, response=answer.response.model_copy(update={"overlay_png": drawn}))
        cpu_ms = {"decode": decode_ms, "locate": answer.cpu_ms["locate"]}
    # the overlay of a door located but refused for reach is not shown: only an answered image's is
    drawn = answer.response.overlay_png if answer.response.ok else None
    return replace(
        answer,
        response=answer.response.model_copy(update={"overlay_png": drawn}),
        cpu_ms=cpu_ms,
        requested=answer.requested | ({"overlay_png"} if overlay else set()),
    )
