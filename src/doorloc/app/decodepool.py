"""Decode uploaded images in worker processes that have a CPU-time and a memory limit.

The header checks (:mod:`doorloc.app.imagesniff`) refuse every bomb whose cost the header declares: pixels,
sample size, JPEG scans, TIFF tiles. A decoder can still be made to work harder than its header says (a format
feature those checks do not know, a decoder bug), and a decoding thread can be neither stopped nor limited:
it would hold the CPU slot and the memory it took however long it ran. So each image is decoded in a small
pool of processes (one per CPU slot), each with an address-space limit (``RLIMIT_AS``) and, per image, a
CPU-time limit (``RLIMIT_CPU``) and a wall-clock limit (the request's deadline). A bomb kills only its own
worker: the request is answered 422 (or 503 when the deadline passed on a busy machine), a fresh worker takes
its place, and every other request goes on.

The pipe carries the encoded bytes in and the decoded array out (a 1080p grey frame: 2 MB, ~1 ms).
``multiprocessing``'s forkserver starts workers: a fork of a process that has imported only numpy and OpenCV,
not of the service with its threads and event loop.

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
from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import Any

import numpy as np

__all__ = ["DecodePool", "DecodeRefused"]

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


def _worker_main(conn: Connection, memory_bytes: int) -> None:
    """A decoding worker: (bytes, name, cpu seconds) in, ("ok", array) or (code, sentence) out, until EOF."""
    import resource

    import cv2

    from doorloc.vision.imageio import ImageDecodeError, decode_image

    cv2.setNumThreads(1)  # one image per worker; its own thread pool would only add address space
    # the limit is what the worker has now plus the decoding budget: numpy and OpenCV's own mappings are not counted
    limit = _address_space_bytes() + memory_bytes
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    while True:
        try:
            data, name, cpu_s = conn.recv()
        except (EOFError, OSError):
            return
        except MemoryError:  # the upload itself did not fit: end quietly, the parent answers 422
            os._exit(_OUT_OF_MEMORY)
        usage = resource.getrusage(resource.RUSAGE_SELF)
        # RLIMIT_CPU counts the process's whole life: the soft limit is moved to "now + budget" per image;
        # past it the kernel sends SIGXCPU, whose default action ends the worker
        soft = math.ceil(usage.ru_utime + usage.ru_stime + cpu_s)
        resource.setrlimit(resource.RLIMIT_CPU, (soft, resource.RLIM_INFINITY))
        try:
            image = decode_image(data, name=name)
            reply: tuple[str, Any] = ("ok", image)
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
        buffers), bytes.
    """

    def __init__(self, size: int, cpu_s: float, memory_bytes: int) -> None:
        self.size = size
        self.cpu_s = cpu_s
        self.memory_bytes = memory_bytes
        self._idle: queue.SimpleQueue[_Worker] = queue.SimpleQueue()
        self._slots = threading.BoundedSemaphore(size)
        self._lock = threading.Lock()
        self._workers: list[_Worker] = []
        self._closed = False
        #: workers ended by a limit or a crash since the pool started (the service's metrics read it)
        self.killed = 0

    def __enter__(self) -> DecodePool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _start(self) -> _Worker:
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(_PRELOAD)
        parent, child = ctx.Pipe()
        process = ctx.Process(
            target=_worker_main, args=(child, self.memory_bytes), daemon=True, name="doorloc-decode"
        )
        process.start()
        child.close()
        worker = _Worker(process, parent)
        with self._lock:
            self._workers.append(worker)
        return worker

    def _retire(self, worker: _Worker) -> None:
        worker.kill()
        with self._lock:
            if worker in self._workers:
                self._workers.remove(worker)

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
        if self._closed:
            raise DecodeRefused(503, "not_ready", "The service is shutting down; retry shortly.")
        if not self._slots.acquire(timeout=max(timeout_s, 0.001)):
            raise _deadline_passed()
        try:
            try:
                worker = self._idle.get_nowait()
            except queue.Empty:
                worker = self._start()
            try:
                worker.conn.send((data, name, self.cpu_s))
                if not worker.conn.poll(max(timeout_s, 0.001)):
                    self._retire(worker)
                    raise _deadline_passed()
                kind, value = worker.conn.recv()
            except (EOFError, OSError):
                worker.process.join(timeout=5)
                code = worker.process.exitcode
                self._retire(worker)
                self.killed += 1
                raise _limit_reached(code, self.cpu_s, self.memory_bytes) from None
            self._idle.put(worker)
        finally:
            self._slots.release()
        if kind == "ok":
            return value
        if kind == "memory":
            raise _limit_reached(None, self.cpu_s, self.memory_bytes)
        raise DecodeRefused(
            422,
            "undecodable_image",
            f"The image could not be decoded ({value}); the file is probably damaged or truncated: send it again.",
        )

    def close(self) -> None:
        """End every worker (the service's shutdown)."""
        self._closed = True
        with self._lock:
            workers, self._workers = self._workers, []
        for w in workers:
            w.kill()


def _deadline_passed() -> DecodeRefused:
    return DecodeRefused(
        503,
        "overloaded",
        "The image was not decoded within the request deadline: this worker is overloaded; retry after the "
        "number of seconds in Retry-After.",
    )


def _limit_reached(exitcode: int | None, cpu_s: float, memory_bytes: int) -> DecodeRefused:
    if exitcode == -signal.SIGXCPU:
        why = f"more than {cpu_s:g} s of CPU time"
    elif exitcode is None or exitcode == _OUT_OF_MEMORY:
        why = f"more than {memory_bytes / 1e6:.0f} MB of memory"
    else:
        why = f"more than a decode may take (its decoder ended with code {exitcode})"
    return DecodeRefused(
        422,
        "decode_limit",
        f"Decoding the image took {why}, so it was stopped; a camera image never does: send the camera's "
        "own PNG or baseline JPEG.",
    )
