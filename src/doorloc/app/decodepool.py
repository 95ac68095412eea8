"""Decode uploaded images, and locate the door in them, in worker processes that have a CPU-time and a memory limit.

The header checks (:mod:`doorloc.app.imagesniff`) refuse every bomb whose cost the header declares: pixels,
sample size, JPEG scans, TIFF tiles. A decoder can still be made to work harder than its header says (a format
feature those checks do not know, a decoder bug), and a decoding thread can be neither stopped nor limited:
it would hold the CPU slot and the memory it took however long it ran. So each image is decoded in a small
pool of processes (one per CPU slot), each with an address-space limit (``RLIMIT_AS``) and, per image, a
CPU-time limit (``RLIMIT_CPU``) and a wall-clock limit (the request's deadline). A bomb kills only its own
worker: the request is answered 422 (or 503 when the deadline passed on a busy machine), a fresh worker takes
its place, and every other request goes on.

The same holds for locating: an image the header checks pass can still make the pipeline work far harder than
a camera frame does. A pool given ``locate_fn`` runs a request's whole measurement in one of its workers
(:meth:`DecodePool.decode_and_locate`): the worker decodes the bytes within the decoding limits, then locates
within locate's own CPU-time and memory limits, and sends back the result (and the overlay, when asked for),
never the decoded array. A decoding bomb ends its worker as a decode (422 ``decode_limit``), a pathological
image as a locate (422 ``locate_limit``): the worker tells the pool when decoding is done. Such a pool's workers
load locate's numba kernels when they start (:mod:`doorloc.vision.warmup`), before their memory limit is set,
and a worker ended by a limit is replaced at once in the background, so no request waits for the kernels.

The pipe carries the encoded bytes in and, for :meth:`DecodePool.decode`, the decoded array out (a 1080p grey
frame: 2 MB, ~1 ms); for :meth:`DecodePool.decode_and_locate` the bytes, the cell and the door in and the
result out. ``multiprocessing``'s forkserver starts workers: a fork of a process that has imported only numpy
and OpenCV, not of the service with its threads and event loop.

Examples
--------
>>> import cv2, numpy as np
>>> png = cv2.imencode(".png", np.full((4, 6), 7, np.uint8))[1].tobytes()
>>> with DecodePool(1, cpu_s=5, memory_bytes=200_000_000) as pool:
...     pool.decode(png, "door.png", timeout_s=60).shape
(4, 6)
"""

from __future__ import annotations

import math
import multiprocessing
import os
import queue
import signal
import threading
import time
from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import TYPE_CHECKING, Any

import numpy as np

__all__ = [
    "DecodePool",
    "DecodeRefused",
    "Located",
    "decoded_too_large",
    "lower_cpu_priority",
    "nice_at_least",
]

if TYPE_CHECKING:
    from doorloc.cell import Cell
    from doorloc.domain import DoorSize
    from doorloc.vision.result import LocateResult

#: modules the forkserver imports once, so that each worker it forks starts in milliseconds. Not doorloc
#: itself: a child sets the parent's sys.path only after the fork, and a doorloc imported before that could
#: be another copy than the parent's
_PRELOAD = ["numpy", "cv2"]


#: a worker's exit status when an upload did not fit its memory limit
_OUT_OF_MEMORY = 3


class DecodeRefused(Exception):
    """The image was not decoded: ``status`` (422 or 503), ``code`` and a sentence for the caller."""

    def __init__(self, status: int, code: str, detail: str) -> None:
        super().__init__(detail)
        self.status = status
        self.code = code
        self.detail = detail


class _DecodedTooLarge(Exception):
    def __init__(self, nbytes: int) -> None:
        super().__init__(nbytes)
        self.nbytes = nbytes


@dataclass(frozen=True)
class _Step:
    """One step of a job: its name (``decode``, ``locate``), the past participle a refusal says, its budget."""

    job: str
    what: str
    cpu_s: float
    memory_bytes: int


@dataclass(frozen=True)
class Located:
    """What :meth:`DecodePool.decode_and_locate` gives back: locate's result, the overlay (base64 PNG, or None:
    not asked for, not located, or the image was too large to draw), and this thread's CPU ms until the
    worker had decoded the image (handing the bytes over), and the worker's own CPU time for the job."""

    result: LocateResult
    overlay_png: str | None
    decode_thread_ms: float
    #: the worker process's CPU seconds for the whole job (decoding and locating)
    worker_cpu_s: float = 0.0
    #: of them, until it had decoded the image (0: it was given the image decoded)
    worker_decode_cpu_s: float = 0.0
    #: a decoding-only process's CPU seconds for an image decoded apart before the job (0: none)
    decoded_apart_cpu_s: float = 0.0

    def cpu_ms(self, thread_s: float) -> dict[str, float]:
        """What the request cost the service's CPUs, ms, in decoding and in measuring (``decode``,
        ``locate``): this thread's ``thread_s`` (seconds, the whole request) and the worker processes' CPU
        time together. The thread alone hands bytes over and waits: it was a twentieth of a realistic
        frame's cost."""
        decoding_s = self.worker_decode_cpu_s + self.decoded_apart_cpu_s
        return {
            "decode": self.decode_thread_ms + decoding_s * 1e3,
            "locate": thread_s * 1e3
            - self.decode_thread_ms
            + (self.worker_cpu_s - self.worker_decode_cpu_s) * 1e3,
        }


def _address_space_bytes() -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    return 0


def lower_cpu_priority(increment: int, every_thread: bool = True) -> bool:
    """Lower this process's CPU priority by ``increment`` nice levels (an unprivileged process may only lower
    its own); True if it was lowered.

    Linux keeps a nice level per thread, and a thread inherits its creator's: ``every_thread`` lowers each
    thread running now (``/proc/self/task``), so every thread started later is lowered too. Elsewhere a nice
    level is the process's. Where the platform has none (Windows) or refuses, nothing changes (False).
    """
    if increment <= 0 or not hasattr(os, "setpriority"):
        return False
    try:
        tids = [int(t) for t in os.listdir("/proc/self/task")] if every_thread else [0]
    except OSError:
        tids = [0]  # no /proc (macOS, BSD): the nice level is the process's
    lowered = False
    for tid in tids:
        try:
            now = os.getpriority(os.PRIO_PROCESS, tid)
            os.setpriority(os.PRIO_PROCESS, tid, min(now + increment, 19))
            lowered = True
        except OSError:
            pass  # a thread that ended meanwhile, or a platform that refuses
    return lowered


def nice_at_least(level: int) -> bool:
    """Lower every thread of this process to nice ``level`` (at most 19) where it runs at a better priority;
    True if this process now runs at ``level`` or below it.

    Idempotent, unlike :func:`lower_cpu_priority`: a process that holds a second service (an application
    that embeds it, or tests) is not lowered twice.
    """
    if not hasattr(os, "getpriority"):
        return False
    try:
        now = os.getpriority(os.PRIO_PROCESS, 0)
    except OSError:
        return False
    return lower_cpu_priority(min(level, 19) - now) or now >= min(level, 19)


def _worker_main(conn: Connection, memory_bytes: int, locate_fn: Any = None, nice: int = 0) -> None:
    """A worker: (job, arguments, step budgets) in, ("ok", value) or (code, sentence) out, until EOF.

    ``memory_bytes`` bounds what the worker ever adds to its start-up size (the hard limit); each step's own
    budget, ``(cpu seconds, memory bytes)``, is a soft limit below it, from the worker's size when the step
    starts.

    Jobs: ``("decode", (bytes, name))`` -> the decoded array; ``("decode_locate", (bytes, name, cell, door,
    max_decoded_bytes, overlay_max_pixels, jpeg_quality))`` -> ``("decoded", nbytes)`` once decoding is done
    (so the pool knows which step a limit ended), then ``(LocateResult, overlay PNG or None)`` from ``locate_fn`` (given
    only to a pool that locates); a decoded image of more than ``max_decoded_bytes`` answers
    ``("too_big", nbytes)`` and is not located.
    """
    import resource

    import cv2

    cv2.setNumThreads(1)  # one image per worker; its own thread pool would only add address space
    import doorloc.vision.imageio  # noqa: F401 - imported now, not under the first image's limits

    if isinstance(locate_fn, str):  # "module:function", imported here only (the service never loads it)
        import importlib

        module, _, function = locate_fn.partition(":")
        locate_fn = getattr(importlib.import_module(module), function)
    if locate_fn is not None:
        # locate's kernels, loaded (or compiled) now and not counted in the limit: no request waits for them
        from doorloc.vision.warmup import compile_locate_kernels

        compile_locate_kernels()
    # (after loading the kernels, which then take no longer than in any other worker)
    lower_cpu_priority(nice, every_thread=False)
    # the limit is what the worker has now plus the budget: numpy's, OpenCV's and numba's own mappings are not counted
    hard = _address_space_bytes() + memory_bytes
    resource.setrlimit(resource.RLIMIT_AS, (hard, hard))

    def budget(cpu_s: float, step_bytes: int) -> None:
        usage = resource.getrusage(resource.RUSAGE_SELF)
        # RLIMIT_CPU counts the process's whole life: the soft limit is moved to "now + budget" per step;
        # past it the kernel sends SIGXCPU, whose default action ends the worker
        soft = math.ceil(usage.ru_utime + usage.ru_stime + cpu_s)
        resource.setrlimit(resource.RLIMIT_CPU, (soft, resource.RLIM_INFINITY))
        # likewise the memory: "now + this step's budget", never past the worker's hard limit
        resource.setrlimit(resource.RLIMIT_AS, (min(_address_space_bytes() + step_bytes, hard), hard))

    conn.send(("ready", None))
    while True:
        try:
            job, args, budgets = conn.recv()
        except (EOFError, OSError):
            return
        except MemoryError:  # the upload itself did not fit: end quietly, the parent answers 422
            os._exit(_OUT_OF_MEMORY)
        started = time.process_time()
        budget(*budgets[0])
        # (an image decoded already, in a decoding-only process, skips the step)
        reply = ("ok", args[0]) if isinstance(args[0], np.ndarray) else _decode_step(args[0], args[1])
        if job == "decode_locate" and reply[0] == "ok":
            image, reply = reply[1], ("decoded", reply[1].nbytes)
            if image.nbytes > args[4]:
                reply = ("too_big", image.nbytes)
            else:
                conn.send((*reply, time.process_time() - started))  # (the decoding's CPU seconds)
                budget(*budgets[1])
                reply = _locate_step(locate_fn, image, args[1], args[2], args[3], args[5], args[6])
            del image
        # the job's CPU seconds (this process's), for the service's account of who used the workers
        try:
            conn.send((*reply, time.process_time() - started))
        except MemoryError:
            conn.send(("memory", "", time.process_time() - started))
        del reply


def _decode_step(data: bytes, name: str) -> tuple[str, Any]:
    from doorloc.vision.imageio import ImageDecodeError, decode_image

    try:
        return "ok", decode_image(data, name=name)
    except ImageDecodeError as e:
        # OpenCV reports an allocation past the limit as a decoding error of its own
        out_of_memory = "Insufficient memory" in str(e) or "Failed to allocate" in str(e)
        return ("memory", "") if out_of_memory else ("undecodable", str(e))
    except MemoryError:
        return "memory", ""


def _locate_step(
    locate_fn: Any,
    image: np.ndarray,
    name: str,
    cell: Any,
    door: Any,
    overlay_max_pixels: int | None,
    jpeg_quality: int,
) -> tuple[str, Any]:
    """("ok", (result, overlay)): the overlay (base64 PNG) is drawn here, where the image is, for a located
    door of at most ``overlay_max_pixels`` (None: no overlay asked for)."""
    try:
        trace = None
        if overlay_max_pixels is not None:
            from doorloc.vision.locate import LocateTrace

            trace = LocateTrace()
        result = locate_fn(
            image,
            cell,
            door,
            image_name=name,
            jpeg_quality=jpeg_quality,
            **({} if trace is None else {"trace": trace}),
        )
        drawn = None
        if (
            overlay_max_pixels is not None
            and result.ok
            and image.shape[0] * image.shape[1] <= overlay_max_pixels
        ):
            from doorloc.app.answer import overlay_png

            drawn = overlay_png(image, result, cell, door, trace)
        return "ok", (result, drawn)
    except MemoryError:
        return "memory", ""


@dataclass
class _Worker:
    process: Any  # multiprocessing.Process (forkserver context)
    conn: Connection

    def kill(self) -> None:
        if self.process.is_alive():
            self.process.kill()
        self.process.join(timeout=5)
        self.conn.close()


class DecodePool:
    """Up to ``size`` decoding worker processes, started on first use and replaced when one dies.

    Parameters
    ----------
    size : int
        Workers (the service's CPU slots: at most that many images are decoded at once).
    cpu_s : float
        CPU seconds one image may take to decode (rounded up to whole seconds by the kernel's limit).
    memory_bytes : int
        Address space a worker may add to what it holds after start-up (the decoded image, the decoder's
        buffers; for a locating pool the pipeline's arrays too), bytes.
    locate_fn : callable or str, optional
        The locate step (:func:`doorloc.vision.locate.locate`; picklable by name, or named
        ``"module:function"`` so that only the workers import it) that :meth:`decode_and_locate` runs in the
        workers after decoding; None: a pool that only decodes.
    locate_cpu_s : float
        CPU seconds one locate may take (after the image's decoding, which has its own ``cpu_s``).
    locate_memory_bytes : int or None
        Address space one locate may add to its worker, the decoded image held (None: ``memory_bytes``); a
        locating worker's own limit is the sum of the two budgets.
    nice : int
        Nice levels the workers lower their CPU priority by once started, counted from the forkserver they
        start from (it keeps the priority this process had when its first worker of any pool started; a
        service lowers its own after that): on a busy CPU a job here yields to one in a pool of better
        priority.
    """

    def __init__(
        self,
        size: int,
        cpu_s: float,
        memory_bytes: int,
        locate_fn: Any = None,
        locate_cpu_s: float = 10.0,
        locate_memory_bytes: int | None = None,
        nice: int = 0,
    ) -> None:
        self.size = size
        self.nice = nice
        self.cpu_s = cpu_s
        self.memory_bytes = memory_bytes
        self.locate_fn = locate_fn
        self.locate_cpu_s = locate_cpu_s
        self.locate_memory_bytes = memory_bytes if locate_memory_bytes is None else locate_memory_bytes
        self._idle: queue.SimpleQueue[_Worker] = queue.SimpleQueue()
        self._slots = threading.BoundedSemaphore(size)
        self._lock = threading.Lock()
        self._workers: list[_Worker] = []
        self._closed = False
        #: workers ended by a limit or a crash since the pool started (the service's metrics read it)
        self.killed = 0
        #: replacements being started in the background
        self._starting = 0

    def __enter__(self) -> DecodePool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _start(self) -> _Worker:
        return self._ready(self._spawn())

    def _spawn(self) -> _Worker:
        """A worker process started, not yet ready (:meth:`_ready` waits for it)."""
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(_PRELOAD)
        parent, child = ctx.Pipe()
        process = ctx.Process(
            target=_worker_main,
            args=(child, self._worker_bytes(), self.locate_fn, self.nice),
            daemon=True,
            name=("doorloc-decode" if self.locate_fn is None else "doorloc-locate")
            + ("-low" if self.nice > 0 else ""),
        )
        process.start()
        child.close()
        return _Worker(process, parent)

    def _ready(self, worker: _Worker) -> _Worker:
        """``worker`` once it says it is ready, counted in the pool; one that ends first is refused."""
        try:
            worker.conn.recv()  # "ready": its kernels are loaded (a locating worker), its limits set
        except (EOFError, OSError):
            worker.kill()
            raise DecodeRefused(
                503, "not_ready", "A worker process could not start; retry shortly."
            ) from None
        with self._lock:
            self._workers.append(worker)
        return worker

    def _worker_bytes(self) -> int:
        """What a worker may ever add to its start-up size: a decode's budget, and a locate's on top of the
        image it decoded."""
        return self.memory_bytes + (self.locate_memory_bytes if self.locate_fn is not None else 0)

    def _retire(self, worker: _Worker) -> None:
        worker.kill()
        with self._lock:
            if worker in self._workers:
                self._workers.remove(worker)

    def start(self) -> None:
        """Start every worker now (the service at start-up: a locating worker loads locate's kernels first)."""
        start_pools([self])

    def worker_nice(self) -> int | None:
        """The nice level of a started worker (None: none started, or the platform has no nice levels)."""
        if not hasattr(os, "getpriority"):
            return None
        for worker in list(self._workers):
            if worker.process.pid:
                try:
                    return os.getpriority(os.PRIO_PROCESS, worker.process.pid)
                except OSError:  # it ended meanwhile
                    continue
        return None

    def _replace_soon(self) -> None:
        """A fresh worker for one that was ended, started in the background (it may load kernels for seconds)."""

        def start() -> None:
            try:
                if not self._closed:
                    worker = self._start()
                    if self._closed:  # the pool closed while this one loaded its kernels
                        self._retire(worker)
                    else:
                        self._idle.put(worker)
            except DecodeRefused:
                pass  # it could not start (the pool closing, the machine out of processes): a request starts one
            finally:
                with self._lock:  # the count is read and written from request threads and refill threads
                    self._starting -= 1

        if self.locate_fn is not None:
            with self._lock:
                self._starting += 1
            threading.Thread(target=start, daemon=True, name="doorloc-pool-refill").start()

    def _next_worker(self, timeout_s: float, what: str) -> _Worker:
        """A worker when none is idle: the one being started in the background (waited for), else a new one."""
        if self._starting <= 0:
            return self._start()
        try:
            return self._idle.get(timeout=max(timeout_s, 0.001))
        except queue.Empty:
            raise _deadline_passed(what) from None

    def _run(
        self, job: str, args: tuple, steps: tuple[_Step, ...], timeout_s: float
    ) -> tuple[Any, float, float, float]:
        """Run one job in an idle worker (started if none is), its steps in turn; its value, this thread's
        CPU seconds until its first step was done, the worker's CPU seconds for the job and of them until
        its first step was done (all of them for a one-step job), or DecodeRefused naming the step that was
        stopped."""
        if self._closed:
            raise DecodeRefused(503, "not_ready", "The service is shutting down; retry shortly.")
        end = time.monotonic() + max(timeout_s, 0.001)
        t0 = time.thread_time()
        first_done = worker_first = 0.0
        step = steps[0]
        if not self._slots.acquire(timeout=max(timeout_s, 0.001)):
            raise _deadline_passed(step.what)
        try:
            try:
                worker = self._idle.get_nowait()
            except queue.Empty:
                worker = self._next_worker(end - time.monotonic(), step.what)
            try:
                worker.conn.send((job, args, [(s.cpu_s, s.memory_bytes) for s in steps]))
                while True:
                    if not worker.conn.poll(max(end - time.monotonic(), 0.001)):
                        self._retire(worker)
                        self._replace_soon()
                        raise _deadline_passed(step.what)
                    kind, value, *cpu = worker.conn.recv()
                    if kind != "decoded":
                        break
                    # the worker decoded the image and now locates: a limit past here is locate's
                    step, first_done = steps[1], time.thread_time() - t0
                    worker_first = cpu[0] if cpu else 0.0
            except (EOFError, OSError):
                worker.process.join(timeout=5)
                code = worker.process.exitcode
                self._retire(worker)
                self.killed += 1
                self._replace_soon()
                raise _limit_reached(step, code) from None
            self._idle.put(worker)
        finally:
            self._slots.release()
        if kind == "ok":
            worker_s = cpu[0] if cpu else 0.0
            return value, first_done, worker_s, worker_first if len(steps) > 1 else worker_s
        if kind == "memory":
            raise _limit_reached(step, None)
        if kind == "too_big":
            raise _DecodedTooLarge(value)
        raise DecodeRefused(
            422,
            "undecodable_image",
            f"The image could not be decoded ({value}); the file is probably damaged or truncated: send it again.",
        )

    def _decoding(self) -> _Step:
        return _Step("decode", "decoded", self.cpu_s, self.memory_bytes)

    def decode(self, data: bytes, name: str, timeout_s: float) -> np.ndarray:
        """The decoded image (as :func:`doorloc.vision.imageio.decode_image` returns it); blocks, so call it
        from a worker thread.

        Raises
        ------
        DecodeRefused
            422 ``undecodable_image`` (not an image the decoder reads), 422 ``decode_limit`` (the image needed
            more CPU time or memory than a decode may take: its worker was ended), 503 ``overloaded`` (no
            answer within ``timeout_s``, the request's deadline).
        """
        return self.decode_costed(data, name, timeout_s=timeout_s)[0]

    def decode_costed(self, data: bytes, name: str, *, timeout_s: float) -> tuple[np.ndarray, float]:
        """:meth:`decode`'s image and the CPU seconds the worker spent decoding it."""
        image, _, worker_s, _ = self._run("decode", (data, name), (self._decoding(),), timeout_s)
        return image, worker_s

    def decode_and_locate(
        self,
        data: bytes | np.ndarray,
        name: str,
        cell: Cell,
        door: DoorSize,
        *,
        max_decoded_bytes: int,
        overlay_max_pixels: int | None = None,
        timeout_s: float,
        jpeg_quality: int = 0,
    ) -> Located:
        """Decode ``data`` and locate the door in it, both in one worker; blocks, so call it from a worker
        thread.

        The image is decoded within the decoding limits (``cpu_s``, ``memory_bytes``), then
        ``locate_fn(image, cell, door, image_name=name, jpeg_quality=jpeg_quality)`` runs within locate's
        (``locate_cpu_s``, ``locate_memory_bytes``; ``jpeg_quality``: the file's, as
        :func:`doorloc.vision.imageio.stored_jpeg_quality` reads it); the image never leaves the worker.
        ``overlay_max_pixels`` (None: no overlay) asks for the overlay of a located door in an image of at
        most that many pixels. ``data`` may be the
        image decoded already (a decoding-only pool's :meth:`decode`): it then crosses the pipe and is located.

        Raises
        ------
        DecodeRefused
            as :meth:`decode` for the decoding (``undecodable_image``, ``decode_limit``, 503 ``overloaded``
            "not decoded"); 422 ``too_many_pixels`` (decoded to more than ``max_decoded_bytes``: not
            located); 422 ``locate_limit`` (the image made locate need more CPU time or memory than one may
            take: its worker was ended); 503 ``overloaded`` "not located" (the deadline passed while locating).
        """
        if self.locate_fn is None:
            raise RuntimeError("this pool was made without a locate_fn: it only decodes")
        locating = _Step("locate", "located", self.locate_cpu_s, self.locate_memory_bytes)
        args = (data, name, cell, door, max_decoded_bytes, overlay_max_pixels, jpeg_quality)
        try:
            (result, drawn), decode_s, worker_s, worker_decode_s = self._run(
                "decode_locate", args, (self._decoding(), locating), timeout_s
            )
        except _DecodedTooLarge as e:
            raise decoded_too_large(name, e.nbytes, max_decoded_bytes) from None
        return Located(result, drawn, decode_s * 1e3, worker_s, worker_decode_s)

    def close(self) -> None:
        """End every worker (the service's shutdown)."""
        self._closed = True
        with self._lock:
            workers, self._workers = self._workers, []
        for w in workers:
            w.kill()


def _deadline_passed(what: str = "decoded") -> DecodeRefused:
    return DecodeRefused(
        503,
        "overloaded",
        f"The image was not {what} within the request deadline: this worker is overloaded; retry after the "
        "number of seconds in Retry-After.",
    )


def _limit_reached(step: _Step, exitcode: int | None) -> DecodeRefused:
    name = "Locating the door in the image" if step.job == "locate" else "Decoding the image"
    if exitcode == -signal.SIGXCPU:
        why = f"more than {step.cpu_s:g} s of CPU time"
    elif exitcode is None or exitcode == _OUT_OF_MEMORY:
        why = f"more than {step.memory_bytes / 1e6:.0f} MB of memory"
    else:
        why = f"more than one may take (its process ended with code {exitcode})"
    if step.job == "locate":
        return DecodeRefused(
            422,
            "locate_limit",
            f"{name} took {why}, so it was stopped; a camera image of a door never does: send the camera's "
            "own image of the door in the cell.",
        )
    return DecodeRefused(
        422,
        "decode_limit",
        f"{name} took {why}, so it was stopped; a camera image never does: send the camera's "
        "own PNG or baseline JPEG.",
    )


def decoded_too_large(name: str, nbytes: int, max_decoded_bytes: int) -> DecodeRefused:
    """The 422 of an image that decoded to more than ``max_decoded_bytes`` (its header said less)."""
    return DecodeRefused(
        422,
        "too_many_pixels",
        f"The image '{name}' decoded to {nbytes / 1e6:.0f} MB, more than is accepted here "
        f"({max_decoded_bytes / 1e6:.0f} MB); send the camera's own image.",
    )


def start_pools(pools: list[DecodePool]) -> None:
    """Start every missing worker of ``pools`` at once, then wait for them all: a locating worker spends
    seconds loading locate's kernels, and a service with several pools would otherwise start them one after
    another. Where one cannot start, those already started stay in their pools and the rest are ended."""
    spawned = [(pool, pool._spawn()) for pool in pools for _ in range(pool.size - len(pool._workers))]
    for i, (pool, worker) in enumerate(spawned):
        try:
            pool._idle.put(pool._ready(worker))
        except DecodeRefused:
            for _, rest in spawned[i + 1 :]:
                rest.kill()
            raise
