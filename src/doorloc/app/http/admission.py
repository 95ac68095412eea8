"""Who gets a CPU slot for an image, and how an admitted image is decoded.

- :func:`take_cpu_slot` / :func:`release_cpu_slot`: a bounded queue per worker (its CPU slots plus
  ``max_queue``), within it a share per client (its API key), and within a key's share a smaller one per
  address using that key (the connection's, or the one a trusted proxy forwarded): one client flooding the
  service fills only its own share, so another client's image still finds a place, even one sent with the
  same shared key from another machine; the free CPU slots go to the waiting keys in turn, and within a key
  to its addresses in turn (:class:`~doorloc.app.fairslots.FairSlots`), not in arrival order; a client that
  used more than its share of worker time recently while another client is present
  (:class:`~doorloc.app.fairslots.RecentUse`) waits for the slots of the lower-priority workers instead, so
  the other client's job does not wait behind its job and overtakes it on a busy CPU;
- :func:`locate_upload`: decoding and locating in one of the worker's limited processes
  (:class:`~doorloc.app.decodepool.DecodePool`) within what is left of the request's deadline, one job per
  request; :func:`decode_upload`: decoding alone (there, or in the thread), for a locate that runs in the thread.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, TypeVar

import anyio
import numpy as np

from doorloc.app.decodepool import DecodePool, DecodeRefused, Located, decoded_too_large
from doorloc.app.http.problems import ProblemError
from doorloc.app.http.state import ServiceState
from doorloc.vision.imageio import stored_jpeg_quality

if TYPE_CHECKING:
    from doorloc.domain import DoorSize

_Key = TypeVar("_Key")

__all__ = [
    "client_of",
    "address_of",
    "shedding_problem",
    "hold_refusal",
    "CpuTurn",
    "take_cpu_slot",
    "release_cpu_slot",
    "decode_upload",
    "decodes_apart",
    "locate_upload",
    "refusal_problem",
]


def client_of(scope_state: dict) -> str:
    """The client a request counts against: its API key's name, or "" (no share) for the one anonymous
    caller of an open (loopback development) service and the legacy single key."""
    who = scope_state.get("who")
    if who is not None and getattr(who, "key_id", None) is not None:
        return f"key:{who.name}"
    return ""


def address_of(scope: Mapping[str, Any]) -> str:
    """The address a request came from: the connection's, or the client's that a trusted proxy forwarded
    (uvicorn's proxy headers, ``trusted_proxies``, have replaced it in the scope already)."""
    return str((scope.get("client") or ("", 0))[0])


def shedding_problem(state: ServiceState, client: str, address: str = "") -> ProblemError | None:
    """The 503 for a locate request that would find the worker's queue, ``client``'s share of it, or the share
    of ``address`` within that key's, full; None when it may go on. Asked twice: before the body is read (so a
    flood's refused uploads are never parsed) and again when the image asks for its CPU slot."""
    if state.overloaded:
        return ProblemError(
            503,
            "overloaded",
            f"This worker is already measuring or queueing {state.admitted} images (its limit); retry after the "
            "number of seconds in Retry-After.",
            headers={"Retry-After": "2"},
        )
    held = state.client_admitted.get(client, 0)
    if client and held >= state.per_client_limit:
        return ProblemError(
            503,
            "overloaded",
            f"This client already has {held} images being measured or queued here, its share of this worker; "
            "wait for an answer, then retry after the number of seconds in Retry-After.",
            headers={"Retry-After": "2"},
        )
    from_address = state.address_admitted.get((client, address), 0)
    if client and from_address >= state.per_address_limit:
        return ProblemError(
            503,
            "overloaded",
            f"This address already has {from_address} images being measured or queued here under its API key, "
            "its share of the key's places (others using the same key keep theirs); wait for an answer, then "
            "retry after the number of seconds in Retry-After.",
            headers={"Retry-After": "2"},
        )
    return None


async def hold_refusal(state: ServiceState, delay_s: float) -> None:
    """Wait ``delay_s`` before a refusal is answered: a key refused (401, 429) or an upload that is no measurable
    image (a decoding bomb, a file past the bounds). Twenty clients posting keyless 19 MB uploads were answered
    several hundred times a second, and four posting 260 kB TIFFs that declare 1 GB tiles nearly 150 times a
    second (each a request parsed, a problem answer and the access log): a core of the event loop and worker
    threads that serve every other client. Waiting costs a sleeping task, and a client that waits for its
    answer then sends a few requests a second per connection. Only a quarter of ``max_connections`` may wait at
    once (every kind of refusal together), so that refusals cannot hold the rest; further ones are answered at
    once."""
    if delay_s <= 0 or state.refusals_waiting >= max(1, state.settings.max_connections // 4):
        return
    state.refusals_waiting += 1
    try:
        await anyio.sleep(delay_s)
    finally:
        state.refusals_waiting -= 1


@dataclass
class CpuTurn:
    """A CPU slot held: in the lower-priority workers' slots (``over_share``) or the others', since
    ``started`` (monotonic seconds); ``worker_cpu_s``: the CPU seconds its job took in a worker process, once
    known (else the time the slot was held is counted as the client's: a refused or stopped job's)."""

    over_share: bool
    started: float
    worker_cpu_s: float | None = None


async def take_cpu_slot(
    state: ServiceState, deadline: float | None, client: str, address: str = ""
) -> CpuTurn:
    """Take a place in the worker's bounded queue and wait for a CPU slot until the request's deadline.

    503 Retry-After at once when the queue is full or ``client`` already holds its share of it, or when no
    slot came free by the deadline. The slot is one of the lower-priority workers' (``over_share``) when
    ``client`` used more than its share of worker time recently while another client is present; then, with
    another image in flight, even while an ordinary slot is idle (the lower-priority workers have as many
    slots, so such a client alone still has every core), and with none, only until the lower slots are all
    taken (then an idle ordinary slot nobody waits for is its). On return
    the caller holds a limiter token and a queue place and must give both back with :func:`release_cpu_slot`.
    """
    problem = shedding_problem(state, client, address)
    if problem is not None:
        raise problem
    held = state.client_admitted.get(client, 0)
    left = (deadline - time.monotonic()) if deadline is not None else state.settings.request_deadline_s
    state.admitted += 1
    state.client_admitted[client] = held + 1
    state.address_admitted[(client, address)] = state.address_admitted.get((client, address), 0) + 1
    lower = state.over_share_limiter
    over_share = lower is not None and state.recent_use.over_share(client, state.client_admitted)
    if (
        over_share
        and held == 0
        and lower is not None
        and lower.free == 0
        and state.limiter.free > 0
        and not state.limiter.waiting
    ):
        # a client with nothing else in flight takes an idle ordinary slot when the lower-priority ones are
        # taken: a steady client that had the service to itself when a flood arrived is the one over its share
        # for a while, and its images waited for the lower slot (100-190 ms) while the ordinary one stood idle.
        # A client with another image in flight never does: its images then ran beside a steady client's at the
        # same priority, and a flood that took every ordinary slot between that client's images made each of
        # them wait for a whole job of the flood's
        over_share = False
    limiter = lower if over_share and lower is not None else state.limiter
    try:
        with anyio.fail_after(max(left, 0.001)):
            await limiter.acquire(client, address)
    except BaseException as e:  # timed out, or the client went away: give the queue place back
        _forget(state, client, address)
        if not isinstance(e, TimeoutError):
            raise
        raise ProblemError(
            503,
            "overloaded",
            f"No CPU slot came free within the request deadline ({state.settings.request_deadline_s:g} s): this "
            "worker is overloaded; retry after the number of seconds in Retry-After.",
            headers={"Retry-After": "5"},
        ) from None
    return CpuTurn(over_share, time.monotonic())


def _forget(state: ServiceState, client: str, address: str) -> None:
    state.admitted -= 1
    _count_down(state.client_admitted, client)
    _count_down(state.address_admitted, (client, address))


def _count_down(counts: dict[_Key, int], key: _Key) -> None:
    left = counts.get(key, 1) - 1
    if left > 0:
        counts[key] = left
    else:
        counts.pop(key, None)


def release_cpu_slot(
    state: ServiceState, client: str, address: str = "", turn: CpuTurn | None = None
) -> None:
    """Give back what :func:`take_cpu_slot` gave (``turn``, its answer; None: a slot of the normal workers),
    counting its job's worker CPU time (else the time the slot was held) as ``client``'s recent use."""
    if turn is not None and turn.over_share and state.over_share_limiter is not None:
        state.over_share_limiter.release()
    else:
        state.limiter.release()
    if turn is not None:
        # the worker's CPU time, not the time held: a job that waited for the CPU behind others at a lower
        # priority must not count that wait against its client (it would keep it there)
        used = turn.worker_cpu_s if turn.worker_cpu_s is not None else time.monotonic() - turn.started
        state.recent_use.add(client, used)
    _forget(state, client, address)


def refusal_problem(e: DecodeRefused) -> ProblemError:
    """The problem answer of an image the limited worker processes did not decode or locate."""
    headers = {"Retry-After": "5"} if e.status == 503 else None
    return ProblemError(e.status, e.code, e.detail, headers=headers)


def decodes_apart(data: bytes) -> bool:
    """Whether an upload is decoded in a decoding-only process before it is located: a progressive JPEG or a
    TIFF, whose decoding work the header bounds only loosely (scans, tiles, compression schemes). A PNG, BMP or
    baseline JPEG, whose decoding work is about its declared pixels (a camera's images), is decoded and located
    in one job."""
    from doorloc.app.imagesniff import sniff_image

    header = sniff_image(data)
    return header is None or header.kind == "tiff" or header.progressive


def decode_upload(
    state: ServiceState, data: bytes, name: str, deadline: float | None, pool: DecodePool | None = None
) -> tuple[np.ndarray, float]:
    """The uploaded image decoded within the limits (blocking: call it in a worker thread), in ``pool`` (default:
    the worker processes, or this thread with ``decode_in_threads``), and the CPU seconds a worker process
    spent decoding it (0 where this thread decoded it).

    Raises ProblemError 422 (undecodable, or past the decoding CPU-time or memory limit) or 503 (the
    deadline passed first).
    """
    from doorloc.vision.imageio import ImageDecodeError, decode_image

    left = (deadline - time.monotonic()) if deadline is not None else state.settings.request_deadline_s
    worker_s = 0.0
    try:
        pool = pool or state.workers
        if pool is None:
            image = decode_image(data, name=name)
        else:
            image, worker_s = pool.decode_costed(data, name, timeout_s=left)
    except ImageDecodeError as e:
        raise ProblemError(
            422,
            "undecodable_image",
            f"The image could not be decoded ({e}); the file is probably damaged or truncated: send it again.",
        ) from None
    except DecodeRefused as e:
        raise refusal_problem(e) from None
    if image.nbytes > state.settings.max_decoded_bytes:
        raise refusal_problem(decoded_too_large(name, image.nbytes, state.settings.max_decoded_bytes))
    return image, worker_s


def locate_upload(
    state: ServiceState,
    data: bytes,
    name: str,
    door: DoorSize,
    overlay: bool,
    deadline: float | None,
    turn: CpuTurn | None = None,
) -> Located:
    """The uploaded image decoded and the door located in it, in one limited worker process (blocking: call
    it in a worker thread; ``state.locates_in_workers`` must hold). ``overlay``: draw the overlay of a located
    door there too, for an image of at most ``overlay_max_pixels``. ``turn`` (from :func:`take_cpu_slot`): in
    one of the lower-priority workers for a turn in their slots; the job's worker CPU time is noted in it.

    Raises ProblemError 422 (undecodable, decoded past ``max_decoded_bytes``, past the decoding or the
    locating CPU-time or memory limit) or 503 (the deadline passed first), as :func:`decode_upload` and a
    locate in the worker processes would.
    """
    assert state.workers is not None and state.cell is not None
    image: bytes | np.ndarray = data
    apart_s = 0.0
    if state.decoders is not None and decodes_apart(data):
        image, apart_s = decode_upload(state, data, name, deadline, pool=state.decoders)
    left = (deadline - time.monotonic()) if deadline is not None else state.settings.request_deadline_s
    over_share = turn is not None and turn.over_share and state.over_share is not None
    pool = state.over_share if over_share and state.over_share is not None else state.workers
    try:
        located = pool.decode_and_locate(
            image,
            name,
            state.cell,
            door,
            max_decoded_bytes=state.settings.max_decoded_bytes,
            overlay_max_pixels=state.settings.overlay_max_pixels if overlay else None,
            timeout_s=left,
            jpeg_quality=stored_jpeg_quality(data),
        )
    except DecodeRefused as e:
        raise refusal_problem(e) from None
    if turn is not None:
        turn.worker_cpu_s = located.worker_cpu_s
    return replace(located, decoded_apart_cpu_s=apart_s)
