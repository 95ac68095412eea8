"""What decoding and locating in a limited worker process costs a request: a 1080p PNG decoded and located in the
calling thread against the same PNG sent to :class:`doorloc.app.decodepool.DecodePool`, which decodes and
locates it in one worker (the bytes, cell and door pickled to it, the result back: one job, the decoded image
never crosses the pipe), as the service runs it. The worker's kernels are loaded before the timing starts.

    OMP_NUM_THREADS=1 python bench/bench_locate_isolation.py --n 40

Prints the median and 90th percentile wall time of each, ms, locate's own time (``elapsed_ms``, measured
where it ran), and the difference of the medians (what the isolation adds per request). The image is a
rendered 1080p door of the bundled thesis cell (``fixtures/cell_thesis.yaml``) with sensor noise and grain, as
PNG (~1-2 MB, the size a camera's are).
"""

from __future__ import annotations

import argparse
import statistics
import time

from service_harness import CELL, rendered_pngs

from doorloc.app.decodepool import DecodePool
from doorloc.cell import load_cell
from doorloc.vision.imageio import decode_image
from doorloc.vision.locate import locate
from doorloc.vision.warmup import compile_locate_kernels


def _times(fn, n: int) -> tuple[list[float], list[float]]:
    """Wall ms of each call, and the ms locate itself reported (``elapsed_ms``)."""
    wall, inner = [], []
    for _ in range(n):
        t0 = time.perf_counter()
        result = fn()
        wall.append((time.perf_counter() - t0) * 1e3)
        inner.append(result.elapsed_ms)
        assert result.ok, result.error
    return wall, inner


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=30, help="requests of each kind (after 3 unmeasured)")
    args = ap.parse_args()
    cell = load_cell(CELL)
    png = rendered_pngs(1, seed0=5)[0][0]
    door = cell.default_door
    compile_locate_kernels()
    with DecodePool(1, cpu_s=10, memory_bytes=400_000_000, locate_fn=locate, locate_cpu_s=10) as pool:
        pool.start()
        rows = {}
        for name, fn in (
            (
                "in the calling thread",
                lambda: locate(decode_image(png, name="d.png"), cell, door, image_name="d.png"),
            ),
            (
                "in a limited worker process (one job)",
                lambda: (
                    pool.decode_and_locate(
                        png, "d.png", cell, door, max_decoded_bytes=100_000_000, timeout_s=60
                    ).result
                ),
            ),
        ):
            _times(fn, 3)
            rows[name] = _times(fn, args.n)
    print(f"a {len(png) / 1e6:.1f} MB 1080p PNG decoded and its door located, {args.n} each, wall ms\n")
    print("| where | median | p90 | locate's own elapsed_ms (median) |\n|---|---|---|---|")
    for name, (t, inner) in rows.items():
        q = statistics.quantiles(t, n=10)[-1]
        print(f"| {name} | {statistics.median(t):.1f} | {q:.1f} | {statistics.median(inner):.1f} |")
    a, b = (statistics.median(t) for t, _ in rows.values())
    print(f"\nisolation adds {b - a:.1f} ms per request (median), {100 * (b - a) / a:.0f} %")


if __name__ == "__main__":
    main()
