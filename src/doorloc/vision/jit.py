"""Compiled loops for the few places where locate's time goes to many small array operations.

Why numba: a robust line fit re-weights one or two thousand points nine times per call; written with
numpy, each iteration is ~20 array calls of a few microseconds on arrays too small to amortise them,
and the fits were a sixth of a clean frame (issue 14). The same loop compiled runs several times faster.
The kernels are plain Python over numpy arrays (``kernel.py_func`` runs one uncompiled;
``NUMBA_DISABLE_JIT=1`` runs them all so), written to give the numbers the numpy code gave up to
rounding.

numba compiles a kernel on its first call and caches the machine code on disk (beside the source, or
under ``NUMBA_CACHE_DIR``; where neither can be written, each process compiles its own). The first call on
a machine takes seconds; later processes load the cached code in a fraction of a second.
:func:`compile_kernels` compiles them all: the service calls it at start so that no request waits for it,
and the container image calls it when it is built.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import numba
import numpy as np
from numba import types
from numba.extending import overload

__all__ = ["kernel", "compile_kernels", "grey"]

F = TypeVar("F", bound=Callable[..., Any])

# (kernel, warm-up) of every kernel defined so far: what compile_kernels compiles (definitions, not state)
_KERNELS: list[tuple[Any, Callable[[Any], None] | None]] = []


def kernel(warm_up: Callable[[Any], None] | None = None) -> Callable[[F], F]:
    """Decorator: compile ``fn`` with numba (``njit``, no GIL held, numpy's float errors, cached on disk
    where it can be).

    ``warm_up(k)`` calls the kernel ``k`` once with the argument types locate passes (numba compiles one
    version per type signature): :func:`compile_kernels` runs it. A kernel only other kernels call needs none.
    """

    def wrap(fn: F) -> F:
        # error_model="numpy": a float division by zero gives inf or NaN, as the array code did (numba's
        # default raises ZeroDivisionError, as Python does)
        try:
            k = numba.njit(cache=True, nogil=True, error_model="numpy")(fn)
        except RuntimeError:  # numba found no writable place for its cache: compile in each process
            k = numba.njit(nogil=True, error_model="numpy")(fn)
        _KERNELS.append((k, warm_up))
        return k  # type: ignore[return-value]

    return wrap


def grey(lut: np.ndarray, value: Any) -> np.float32:
    """A stored grey level as float32, mapped by ``lut`` (float32, one entry per level) unless it is empty.

    For kernels: an integer plane's level indexes the table; a float plane's (synthetic images, tests)
    is taken as it is (no table applies). Called from Python, the same.
    """
    if lut.size > 0 and np.issubdtype(type(value), np.integer):
        return np.float32(lut[value])
    return np.float32(value)


@overload(grey)
def _grey_compiled(lut, value):  # the kernel version: chosen by the level's type when a kernel is compiled
    if isinstance(value, types.Integer):
        return lambda lut, value: lut[value] if lut.size > 0 else np.float32(value)
    return lambda lut, value: np.float32(value)


def compile_kernels() -> int:
    """Compile (or load from the disk cache) every kernel of the modules imported so far; their count."""
    for k, warm_up in _KERNELS:
        if warm_up is not None:
            warm_up(k)
    return len(_KERNELS)


if (
    __name__ == "__main__"
):  # python -m doorloc.vision.jit: compile locate's kernels (scripts/setup, the image)
    import time

    import doorloc.vision.locate  # noqa: F401  (defines the kernels)
    from doorloc.vision import jit  # the imported module (this file runs as __main__, with its own list)

    t0 = time.perf_counter()
    n = jit.compile_kernels()
    print(f"doorloc: {n} numba kernels compiled or loaded from the cache in {time.perf_counter() - t0:.1f} s")
