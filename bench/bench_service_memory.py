"""Resident memory of a real `doorloc serve` after a few locates: every process of it (the serving process, the
forkserver, the limited worker processes), and their sum.

    OMP_NUM_THREADS=1 python bench/bench_service_memory.py --workers 1 --slots 1 --locates 5

The locates are rendered 1080p doors of the bundled thesis cell (PNG with sensor noise); each must answer 200.
A process that has numba loaded (llvmlite mapped: a locating worker, with locate's kernels) is marked
"numba". PSS shares the pages several processes map (the forkserver's libraries, copy-on-write in the workers
it forks) among them: its sum is the memory the service takes; RSS counts a shared page in each process.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import httpx
from service_harness import doorloc_serve, process_tree, rendered_pngs


def _rss_pss_mb(pid: int) -> tuple[float, float]:
    """Resident memory, and its proportional share (pages shared with other processes, e.g. a forkserver's
    copy-on-write ones, divided among them), MB."""
    values = {}
    for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
        key, _, rest = line.partition(":")
        if key in ("Rss", "Pss"):
            values[key] = int(rest.split()[0]) / 1024
    return values.get("Rss", 0.0), values.get("Pss", 0.0)


def _describe(pid: int) -> str:
    """What the process is: the serving process, multiprocessing's forkserver or resource tracker, or a
    limited worker (a child of the forkserver); "(kernels)" when it holds locate's compiled kernels."""
    cmd = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
    parent = int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])
    parent_cmd = Path(f"/proc/{parent}/cmdline").read_bytes().decode(errors="replace")
    if "resource_tracker" in cmd:
        kind = "resource tracker"
    elif "forkserver" in parent_cmd:
        kind = "worker"
    elif "forkserver" in cmd:
        kind = "forkserver"
    else:
        kind = "serve"
    if "llvmlite" in Path(f"/proc/{pid}/maps").read_text():
        kind += " (numba)"
    return kind


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--locates", type=int, default=5)
    ap.add_argument("--slots", type=int, default=1, help="DOORLOC_LOCATE_CONCURRENCY: CPU slots per worker")
    args = ap.parse_args()
    pngs = rendered_pngs(2)
    env = {"OMP_NUM_THREADS": "1", "DOORLOC_LOCATE_CONCURRENCY": str(args.slots)}
    with doorloc_serve(args.workers, extra_env=env) as (base, pid):
        with httpx.Client(base_url=base, timeout=120) as c:
            for i in range(args.locates):
                png = pngs[i % len(pngs)][0]
                r = c.post("/v1/locate", files={"image": (f"d{i}.png", png, "image/png")})
                assert r.status_code == 200 and r.json()["ok"], r.text
        rows = [(p, _describe(p), *_rss_pss_mb(p)) for p in process_tree(pid)]
    print(
        f"`doorloc serve --workers {args.workers}`, {args.slots} CPU slot(s) each, after {args.locates} locates\n"
    )
    print("| process | RSS MB | PSS MB |\n|---|---|---|")
    for p, kind, rss, pss in rows:
        print(f"| {p} {kind} | {rss:.0f} | {pss:.0f} |")
    print(f"| all | {sum(r[2] for r in rows):.0f} | {sum(r[3] for r in rows):.0f} |")


if __name__ == "__main__":
    main()
