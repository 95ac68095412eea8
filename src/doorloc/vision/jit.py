"""Compiled loops for the few places where locate's time goes to many small array operations.

Why numba: a robust line fit re-weights one or two thousand points nine times per call; written with
numpy, each iteration is ~20 array calls of a few microseconds on arrays too small to amortise them,
and the fits were a sixth of a clean frame. The same loop compiled runs several times faster.
The kernels are plain Python over numpy arrays (``kernel.py_func`` runs one uncompiled;
``NUMBA_DISABLE_JIT=1`` runs them all so), written to give the numbers the numpy code gave up to
rounding. A few helpers here serve several kernels: :func:`select_kth` (np.partition's order statistic,
in place), :func:`partitioned_median` and :func:`median_in_place` (np.median's value) and
:func:`pairwise_sum` (a row's sum in numpy's own order, so that a compiled sum gives numpy's number to
the bit).

numba compiles a kernel on its first call and caches the machine code on disk (beside the source, or
under ``NUMBA_CACHE_DIR``; where neither can be written, each process compiles its own). The first call on
a machine takes seconds; later processes load the cached code in a fraction of a second.
:func:`compile_kernels` compiles them all (:mod:`doorloc.vision.warmup`, locate's): the service calls it at
start so that no request waits for it, and the container image calls it when it is built. Two things
this module sets in numba keep a cache from running code other than its kernels': compiled functions are
numbered at random (:class:`_RandomCompileIds`: processes sharing a cache), and every kernel's cache is
stamped with all kernel modules' contents (:func:`kernel_sources_digest`: a changed callee).
"""

from __future__ import annotations

import hashlib
import secrets
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import caching
from numba.core.bytecode import FunctionIdentity
from numba.extending import intrinsic, overload

__all__ = [
    "kernel",
    "cached_on_disk",
    "kernel_sources_digest",
    "compile_kernels",
    "compiled_signatures",
    "fma",
    "read_only",
    "grey",
    "median_in_place",
    "pairwise_sum",
    "partitioned_median",
    "select_kth",
]

F = TypeVar("F", bound=Callable[..., Any])


class _RandomCompileIds(Iterator[int]):
    """Random 63-bit numbers, endlessly: the ids numba gives the functions it compiles, in place of its
    count from 1 in each process (``numba.core.bytecode.FunctionIdentity._unique_ids``).

    Why: the id is part of every compiled function's symbol name (its ``v<id>`` tag), which is how numba
    tells apart two functions of one name (its own ``np.sort`` and ``np.argsort`` each build a
    ``run_quicksort1`` for a float64 array), and the disk cache keeps those names. Counted from 1 in every
    process, two processes that compile different functions of one name at the same count (the warm-up's
    two jobs, two test workers, a service's workers meeting a new signature) write cached code whose
    symbols share a name and differ in body, and a process that loads both runs one body for both (LLVM
    keeps the first of two weak definitions). Seen 2026-12-05: a kernel loaded from such a cache crashed in
    the texture reading (its quicksort resolved to another kernel's), and ``tests/vision/test_jit_cache.py``'s
    two modules made ``np.argsort`` sort its input in place and return a float's bits as an index. Reported as
    numba issue #10486 (open; PyTensor works around it likewise). numba has no setting for it, so its
    counter is replaced when this module is imported, before any kernel is compiled; with random ids two
    names meet as often as two draws of 63 bits agree. The ids come from the OS (``secrets``), not from
    ``random``, whose state a forked process would share with its parent. Cached code keeps the ids it was
    compiled with: a cache written before this is dropped by ``scripts/setup`` (this file's kernels
    changed)."""

    def __next__(self) -> int:
        return secrets.randbits(63)


# (numba types it as its itertools.count; it only ever calls next() on it)
FunctionIdentity._unique_ids = _RandomCompileIds()  # type: ignore[assignment]


def kernel_sources_digest(folder: Path) -> bytes:
    """SHA-256 of the modules in ``folder`` that define kernels (``@kernel`` in their text): their file
    names and contents, in name order. The stamp of every kernel's disk cache (:func:`_stamped_locator`)."""
    h = hashlib.sha256()
    for path in sorted(folder.glob("*.py")):
        text = path.read_bytes()
        if b"@kernel" in text:
            h.update(path.name.encode() + b"\0" + text + b"\0")
    return h.digest()


def _stamped_locator(base: type, folder: Path, stamp: bytes) -> type:
    """numba's cache locator ``base`` for the kernels of ``folder`` (None for any other function, which
    numba's own locators then take), their caches stamped ``stamp`` in place of their own file's.

    Why: numba stamps a cached function with its own source file's time and size only, while a kernel's
    cached machine code holds the kernels it calls, from other files: after an edit or a checkout that
    changed only a callee's file, the caller kept the callee's old code, loaded as fresh (benchmarks ran
    old code; ``scripts/setup`` had to drop the cache by hand). With every kernel module's contents in
    the stamp, any change to any of them makes every kernel's cache stale, and numba compiles it again.
    numba offers no setting for this: its locators (``numba.core.caching``) are subclassed and put first."""

    class Located(base):
        def get_source_stamp(self) -> bytes:
            return stamp

        @classmethod
        def from_function(cls, py_func: Any, py_file: str) -> Any:
            if Path(py_file).resolve().parent != folder:
                return None
            return super().from_function(py_func, py_file)

    Located.__name__ = Located.__qualname__ = f"KernelSources{base.__name__}"
    return Located


_KERNEL_FOLDER = Path(__file__).resolve().parent
# (taken once, as this module is imported, before the kernel modules are: each process's caches carry the
# sources it started from)
_KERNEL_STAMP = kernel_sources_digest(_KERNEL_FOLDER)
_STAMPED_LOCATORS: list[Any] = [
    _stamped_locator(base, _KERNEL_FOLDER, _KERNEL_STAMP)
    for base in (caching.UserProvidedCacheLocator, caching.InTreeCacheLocator, caching.UserWideCacheLocator)
]
caching.CacheImpl._locator_classes[:0] = _STAMPED_LOCATORS

# (kernel, warm-up) of every kernel defined so far: what compile_kernels compiles (definitions, not state)
_KERNELS: list[tuple[Any, Callable[[Any], None] | None]] = []
# the kernels numba could give no disk cache (definitions too): compiled in each process that calls them
_UNCACHED: list[Any] = []


def kernel(
    warm_up: Callable[[Any], None] | None = None, inline: bool = False, reassociate: bool = False
) -> Callable[[F], F]:
    """Decorator: compile ``fn`` with numba (``njit``, no GIL held, numpy's float errors, cached on disk
    where it can be).

    ``warm_up(k)`` calls the kernel ``k`` once with the argument types locate passes (numba compiles one
    version per type signature): :func:`compile_kernels` runs it. A kernel only other kernels call needs none.
    ``inline``: other kernels take its body in place of a call (for a small helper called per row).
    ``reassociate``: sums may be reordered and products fused (LLVM's ``reassoc`` and ``contract``: vector
    lanes for the reductions; NaN and infinity keep their meaning) where the code they stand for summed in
    an order of its own (BLAS) anyway: the numbers change by rounding only.
    """

    def wrap(fn: F) -> F:
        # error_model="numpy": a float division by zero gives inf or NaN, as the array code did (numba's
        # default raises ZeroDivisionError, as Python does)
        opts: dict[str, Any] = {
            "nogil": True,
            "error_model": "numpy",
            "inline": "always" if inline else "never",
        }
        if reassociate:
            opts["fastmath"] = {"reassoc", "contract"}
        try:
            k = numba.njit(cache=True, **opts)(fn)
        except RuntimeError:  # numba found no writable place for its cache: compile in each process
            k = numba.njit(**opts)(fn)
            _UNCACHED.append(k)
        _KERNELS.append((k, warm_up))
        return k

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


@intrinsic
def fma(typingctx, a, b, c):
    """For kernels: ``a * b + c`` rounded once (LLVM's ``llvm.fma``, float64), as BLAS's kernels fuse their
    updates; numba offers no fused multiply-add of its own, and ``reassociate`` fuses whatever it may."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        f64 = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [f64], ir.FunctionType(f64, [f64, f64, f64]))
        return builder.call(fn, args)

    return sig, codegen


@kernel()
def select_kth(x, k):
    """Reorder ``x`` in place so that ``x[k]`` is its k-th smallest element, the ones before it no larger
    and the ones after no smaller (as np.partition, without the copy: Hoare's selection)."""
    lo, hi = 0, x.size - 1
    while lo < hi:
        pivot = x[(lo + hi) // 2]
        i, j = lo, hi
        while i <= j:
            while x[i] < pivot:
                i += 1
            while x[j] > pivot:
                j -= 1
            if i <= j:
                x[i], x[j] = x[j], x[i]
                i += 1
                j -= 1
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            break


@kernel(inline=True)
def partitioned_median(p, m):
    """The median of ``p`` partitioned at ``m = p.size // 2`` (as by :func:`select_kth` or np.partition):
    ``p[m]``, or for an even size the mean of the largest element below ``m`` and ``p[m]``, as np.median
    gives it (float64)."""
    if p.size % 2:
        return p[m]
    below = p[0]
    for i in range(1, m):
        below = max(below, p[i])
    return (below + p[m]) / 2.0


@kernel(inline=True)
def median_in_place(x):
    """np.median of ``x`` (no NaN), by selection: ``x`` is reordered."""
    m = x.size // 2
    select_kth(x, m)
    return partitioned_median(x, m)


@kernel(inline=True)
def pairwise_sum(a, lo, n):
    """``a[lo:lo + n].sum()`` in numpy's order: its pairwise summation along a contiguous row (eight
    running sums over blocks of up to 128 values; longer rows split in halves, the first a multiple of 8,
    and the halves' sums added). The halving runs on a stack, not by recursion: numba's disk cache does
    not load a recursive kernel reliably (a cached one crashed the process here)."""
    if n <= 128:
        return _pairwise_block(a, lo, n)
    return _pairwise_halves(a, lo, n)


@kernel()
def _pairwise_halves(a, lo, n):
    """:func:`pairwise_sum` of more than 128 values (its halving, on a stack)."""
    los = np.empty(64, np.int64)
    ns = np.empty(64, np.int64)
    phase = np.zeros(64, np.int64)  # 0: split, 1: left half summed, 2: both
    left = np.empty(64)
    sp = 0
    los[0], ns[0] = lo, n
    ret = 0.0
    while True:
        m = ns[sp]
        h = m // 2 - (m // 2) % 8
        if m <= 128:
            ret = _pairwise_block(a, los[sp], m)
            sp -= 1
        elif phase[sp] == 0:
            phase[sp] = 1
            sp += 1
            los[sp], ns[sp], phase[sp] = los[sp - 1], h, 0
            continue
        elif phase[sp] == 1:
            left[sp] = ret
            phase[sp] = 2
            sp += 1
            los[sp], ns[sp], phase[sp] = los[sp - 1] + h, m - h, 0
            continue
        else:
            ret = left[sp] + ret
            sp -= 1
        if sp < 0:
            return ret


@kernel(inline=True)
def _pairwise_block(a, lo, n):
    """numpy's pairwise sum of ``a[lo:lo + n]``, ``n <= 128`` (see :func:`pairwise_sum`)."""
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[lo + i]
        return res
    # (eight scalars, not an array: an allocation per row cost more than the sum)
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    while i < n - (n % 8):
        r0 += a[lo + i]
        r1 += a[lo + i + 1]
        r2 += a[lo + i + 2]
        r3 += a[lo + i + 3]
        r4 += a[lo + i + 4]
        r5 += a[lo + i + 5]
        r6 += a[lo + i + 6]
        r7 += a[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


def compile_kernels(part: int = 0, parts: int = 1) -> int:
    """Compile (or load from the disk cache) every kernel of the modules imported so far; their count.

    ``part`` of ``parts``: only the kernels ``part``, ``part + parts``, ... in definition order, so that
    ``parts`` processes sharing one disk cache fill it together (:mod:`doorloc.vision.warmup`); the count is
    still that of every kernel.
    """
    if not 0 <= part < parts:
        raise ValueError(f"part {part} of {parts}: part must lie in 0..parts-1")
    for k, warm_up in _KERNELS[part::parts]:
        if warm_up is not None:
            warm_up(k)
    return len(_KERNELS)


def cached_on_disk() -> bool:
    """Whether every kernel defined so far has numba's disk cache (where none can be written, a process
    compiles its own and other processes' compiling gains it nothing)."""
    return not _UNCACHED


def compiled_signatures() -> dict[str, int]:
    """``{module.kernel: signatures compiled so far}`` of every kernel defined so far: where locating an image
    after :func:`compile_kernels` adds one, a warm-up misses an argument type locate passes, and a process
    started from a cache the warm-ups filled compiles it on its first image (seconds)."""
    return {f"{k.py_func.__module__}.{k.py_func.__qualname__}": len(k.signatures) for k, _ in _KERNELS}


def read_only(a: np.ndarray) -> np.ndarray:
    """A read-only copy of ``a``, for warm-ups: numba compiles a kernel apart for read-only arrays (cached
    tables, a camera's coefficients), which locate passes."""
    out = np.array(a)
    out.flags.writeable = False
    return out
