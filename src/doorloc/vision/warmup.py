"""Compile (or load from numba's disk cache) every kernel one locate runs, before the first image.

``python -m doorloc.vision.warmup`` does it once for a machine (the setup script, the container image);
:func:`compile_locate_kernels` does it in a process (the service at start), so that no request waits for
numba. It stands above :mod:`doorloc.vision.locate` in the import graph: the kernel library
(:mod:`doorloc.vision.jit`) registers kernels as the modules defining them are imported and knows none of
them.
"""

from __future__ import annotations

import time

import doorloc.vision.locate  # noqa: F401  (the modules it imports define the kernels)
from doorloc.vision import jit

__all__ = ["compile_locate_kernels"]


def compile_locate_kernels() -> int:
    """Compile or load every kernel of :func:`doorloc.vision.locate.locate`; their count."""
    return jit.compile_kernels()


if __name__ == "__main__":
    t0 = time.perf_counter()
    n = compile_locate_kernels()
    print(f"doorloc: {n} numba kernels compiled or loaded from the cache in {time.perf_counter() - t0:.1f} s")
