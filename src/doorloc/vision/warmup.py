"""Compile (or load from numba's disk cache) every kernel one locate runs, before the first image.

``python -m doorloc.vision.warmup [--jobs N]`` does it once for a machine (the setup script, the container
image): N processes (by default one per CPU, at most four) each compile a share of the kernels into the disk
cache, then this process loads them all, compiling whatever a share left out. :func:`compile_locate_kernels`
does it in a process (the service at start), so that no request waits for numba. It stands above
:mod:`doorloc.vision.locate` in the import graph: the kernel library (:mod:`doorloc.vision.jit`) registers
kernels as the modules defining them are imported and knows none of them.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import time
from concurrent.futures import ProcessPoolExecutor

import doorloc.vision.locate  # noqa: F401  (the modules it imports define the kernels)
from doorloc.vision import jit

__all__ = ["compile_locate_kernels"]


def compile_locate_kernels(part: int = 0, parts: int = 1) -> int:
    """Compile or load every kernel of :func:`doorloc.vision.locate.locate` (``part`` of ``parts``: a share
    of them, :func:`doorloc.vision.jit.compile_kernels`); the count of every kernel."""
    return jit.compile_kernels(part, parts)


def _fill_cache(jobs: int) -> int:
    """Compile the kernels in ``jobs`` processes sharing the disk cache, then load them all here; their count.

    Why processes: numba compiles one kernel at a time under the GIL, and compiling (not running) is what a
    fresh machine's first warm-up spends its minutes on. A share that a process failed to cache (a cache
    written by two at once) is compiled here, so the count is always complete;
    where numba has no disk cache, only here.
    """
    if jobs > 1 and jit.cached_on_disk():
        # spawn, not fork: each child imports and compiles afresh, as a process started apart would
        with ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("spawn")) as pool:
            list(pool.map(compile_locate_kernels, range(jobs), [jobs] * jobs))
    return compile_locate_kernels()


if __name__ == "__main__":
    parser = argparse.ArgumentParser(
        prog="python -m doorloc.vision.warmup", description=__doc__.split("\n")[0]
    )
    parser.add_argument(
        "--jobs",
        type=int,
        default=min(os.cpu_count() or 1, 4),
        help="processes compiling at once (default: CPUs, at most 4)",
    )
    args = parser.parse_args()
    if args.jobs < 1:
        parser.error("--jobs must be at least 1")
    t0 = time.perf_counter()
    n = _fill_cache(args.jobs)
    print(f"doorloc: {n} numba kernels compiled or loaded from the cache in {time.perf_counter() - t0:.1f} s")
