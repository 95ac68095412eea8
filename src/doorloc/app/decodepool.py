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
a camera frame does. A pool given ``locate_fn`` also runs that step of each request in its workers
(:meth:`DecodePool.locate`), each within its own CPU-time limit and the worker's memory limit, and a pathological
image ends its worker (422 ``locate_limit``) instead of holding a CPU slot of the service. Such a pool's workers
load locate's numba kernels when they start (:mod:`doorloc.vision.warmup`), before their memory limit is set, and
a worker ended by a limit is replaced at once in the background, so no request waits for the kernels.

The pipe carries the encoded bytes in and the decoded array out (a 1080p grey frame: 2 MB, ~1 ms), and for a
locate the array, the cell and the door in and the result out. ``multiprocessing``'s forkserver starts workers:
a fork of a process that has imported only numpy and OpenCV, not of the service with its threads and event loop.

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
from dataclasses import dataclass, fields
from multiprocessing.connection import Connection
from typing import TYPE_CHECKING, Any

import numpy as np

__all__ = ["DecodePool", "DecodeRefused"]

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


def _address_space_bytes() -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    return 0


def _worker_main(conn: Connection, memory_bytes: int, locate_fn: Any = None) -> None:
    """A worker: (job, arguments, cpu seconds, memory bytes) in, ("ok", value) or (code, sentence) out, until EOF.

    ``memory_bytes`` bounds what the worker ever adds to its start-up size (the hard limit); each job's own
    budget is a soft limit below it, from the worker's size when the job starts.

    Jobs: ``("decode", (bytes, name))`` -> the decoded array; ``("locate", (image, cell, door, name, traced))``
    -> ``(LocateResult, LocateTrace or None)`` from ``locate_fn`` (given only to a pool that locates).
    """
    import resource

    import cv2

    from doorloc.vision.imageio import ImageDecodeError, decode_image

    cv2.setNumThreads(1)  # one image per worker; its own thread pool would only add address space
    if locate_fn is not None:
        # locate's kernels, loaded (or compiled) now and not counted in the limit: no request waits for them
        from doorloc.vision.warmup import compile_locate_kernels

        compile_locate_kernels()
    # the limit is what the worker has now plus the budget: numpy's, OpenCV's and numba's own mappings are not counted
    hard = _address_space_bytes() + memory_bytes
    resource.setrlimit(resource.RLIMIT_AS, (hard, hard))
    conn.send(("ready", None))
    while True:
        try:
            job, args, cpu_s, job_bytes = conn.recv()
        except (EOFError, OSError):
            return
        except MemoryError:  # the upload itself did not fit: end quietly, the parent answers 422
            os._exit(_OUT_OF_MEMORY)
        usage = resource.getrusage(resource.RUSAGE_SELF)
        # RLIMIT_CPU counts the process's whole life: the soft limit is moved to "now + budget" per job;
        # past it the kernel sends SIGXCPU, whose default action ends the worker
        soft = math.ceil(usage.ru_utime + usage.ru_stime + cpu_s)
        resource.setrlimit(resource.RLIMIT_CPU, (soft, resource.RLIM_INFINITY))
        # likewise the memory: "now + this job's budget", never past the worker's hard limit
        resource.setrlimit(resource.RLIMIT_AS, (min(_address_space_bytes() + job_bytes, hard), hard))
        try:
            if job == "locate":
                reply: tuple[str, Any] = ("ok", _locate(locate_fn, *args))
            else:
                reply = ("ok", decode_image(args[0], name=args[1]))
        except ImageDecodeError as e:
            # OpenCV reports an allocation past the limit as a decoding error of its own
            out_of_memory = "Insufficient memory" in str(e) or "Failed to allocate" in str(e)
            reply = ("memory", "") if out_of_memory else ("undecodable", str(e))
        except MemoryError:
            reply = ("memory", "")
        try:
            conn.send(reply)
        except MemoryError:
            conn.send(("memory", ""))
        del reply


def _locate(
    locate_fn: Any, image: np.ndarray, cell: Any, door: Any, name: str, traced: bool
) -> tuple[Any, Any]:
    trace = None
    if traced:
        from doorloc.vision.locate import LocateTrace

        trace = LocateTrace()
    result = locate_fn(image, cell, door, image_name=name, **({} if trace is None else {"trace": trace}))
    return result, trace


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
    locate_fn : callable, optional
        The locate step (:func:`doorloc.vision.locate.locate`; picklable by name) that :meth:`locate` runs in
        the workers; None: a pool that only decodes.
    locate_cpu_s : float
        CPU seconds one locate may take.
    locate_memory_bytes : int or None
        Address space one locate may add (None: ``memory_bytes``); a worker's own limit is the larger of the two.
    """

    def __init__(
        self,
        size: int,
        cpu_s: float,
        memory_bytes: int,
        locate_fn: Any = None,
        locate_cpu_s: float = 10.0,
        locate_memory_bytes: int | None = None,
    ) -> None:
        self.size = size
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
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(_PRELOAD)
        parent, child = ctx.Pipe()
        process = ctx.Process(
            target=_worker_main,
            args=(child, max(self.memory_bytes, self.locate_memory_bytes), self.locate_fn),
            daemon=True,
            name="doorloc-decode" if self.locate_fn is None else "doorloc-locate",
        )
        process.start()
        child.close()
        worker = _Worker(process, parent)
        try:
            parent.recv()  # "ready": its kernels are loaded (a locating worker), its limits set
        except (EOFError, OSError):
            worker.kill()
            raise DecodeRefused(
                503, "not_ready", "A worker process could not start; retry shortly."
            ) from None
        with self._lock:
            self._workers.append(worker)
        return worker

    def _retire(self, worker: _Worker) -> None:
        worker.kill()
        with self._lock:
            if worker in self._workers:
                self._workers.remove(worker)

    def start(self) -> None:
        """Start every worker now (the service at start-up: a locating worker loads locate's kernels first)."""
        started = [self._start() for _ in range(self.size - len(self._workers))]
        for w in started:
            self._idle.put(w)

    def _replace_soon(self) -> None:
        """A fresh worker for one that was ended, started in the background (it may load kernels for seconds)."""

        def start() -> None:
            try:
                if not self._closed:
                    self._idle.put(self._start())
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
        self, job: str, args: tuple, cpu_s: float, memory_bytes: int, timeout_s: float, what: str
    ) -> Any:
        """Run one job in an idle worker (started if none is); its value, or DecodeRefused."""
        if self._closed:
            raise DecodeRefused(503, "not_ready", "The service is shutting down; retry shortly.")
        if not self._slots.acquire(timeout=max(timeout_s, 0.001)):
            raise _deadline_passed(what)
        try:
            try:
                worker = self._idle.get_nowait()
            except queue.Empty:
                worker = self._next_worker(timeout_s, what)
            try:
                worker.conn.send((job, args, cpu_s, memory_bytes))
                if not worker.conn.poll(max(timeout_s, 0.001)):
                    self._retire(worker)
                    self._replace_soon()
                    raise _deadline_passed(what)
                kind, value = worker.conn.recv()
            except (EOFError, OSError):
                worker.process.join(timeout=5)
                code = worker.process.exitcode
                self._retire(worker)
                self.killed += 1
                self._replace_soon()
                raise _limit_reached(job, code, cpu_s, memory_bytes) from None
            self._idle.put(worker)
        finally:
            self._slots.release()
        if kind == "ok":
            return value
        if kind == "memory":
            raise _limit_reached(job, None, cpu_s, memory_bytes)
        raise DecodeRefused(
            422,
            "undecodable_image",
            f"The image could not be decoded ({value}); the file is probably damaged or truncated: send it again.",
        )

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
        image: np.ndarray = self._run(
            "decode", (data, name), self.cpu_s, self.memory_bytes, timeout_s, "decoded"
        )
        return image

    def locate(
        self,
        image: np.ndarray,
        cell: Cell,
        door: DoorSize,
        *,
        image_name: str = "",
        trace: Any = None,
        timeout_s: float,
    ) -> LocateResult:
        """``locate_fn(image, cell, door, image_name=..., trace=...)`` run in a worker; blocks.

        ``trace`` (a :class:`doorloc.vision.locate.LocateTrace`) is filled with what the worker's locate saw.
        Raises :class:`DecodeRefused`: 422 ``locate_limit`` (the image made locate need more CPU time or memory
        than one may take: its worker was ended), 503 ``overloaded`` (no answer within ``timeout_s``).
        """
        if self.locate_fn is None:
            raise RuntimeError("this pool was made without a locate_fn: it only decodes")
        args = (image, cell, door, image_name, trace is not None)
        result, seen = self._run(
            "locate", args, self.locate_cpu_s, self.locate_memory_bytes, timeout_s, "located"
        )
        if trace is not None and seen is not None:
            for name in (f.name for f in fields(seen)):
                setattr(trace, name, getattr(seen, name))
        return result

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


def _limit_reached(job: str, exitcode: int | None, cpu_s: float, memory_bytes: int) -> DecodeRefused:
    step = "Locating the door in the image" if job == "locate" else "Decoding the image"
    if exitcode == -signal.SIGXCPU:
        why = f"more than {cpu_s:g} s of CPU time"
    elif exitcode is None or exitcode == _OUT_OF_MEMORY:
        why = f"more than {memory_bytes / 1e6:.0f} MB of memory"
    else:
        why = f"more than one may take (its process ended with code {exitcode})"
    if job == "locate":
        return DecodeRefused(
            422,
            "locate_limit",
            f"{step} took {why}, so it was stopped; a camera image of a door never does: send the camera's "
            "own image of the door in the cell.",
        )
    return DecodeRefused(
        422,
        "decode_limit",
        f"{step} took {why}, so it was stopped; a camera image never does: send the camera's "
        "own PNG or baseline JPEG.",
    )
