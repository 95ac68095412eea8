#!/usr/bin/env python
"""Speed of locate: one frame on one thread, decode + locate, and frames/s over a folder.

Frames: every committed fixture (fixtures/rendered/*, 117 1080p grey PNGs, each with its door from truth.csv).

- one-frame locate, decode excluded, one thread: median wall ms and median thread-CPU ms per frame (the
  CPU time is what the machine's other load does not inflate), next to the OpenCV Canny + fitLine baseline of
  bench/bench_locate.py measured in the same process; for this code and, with ``--before SRC``, for another
  source tree (e.g. main's, /work/main/src) run in a subprocess with the same frames;
- decode + locate, PNG and JPEG (quality 95) of the same frames;
- frames/s over a folder of the grid fixtures (PNG): the one-frame path in 1 and 2 worker processes
  (decode + locate), and the batched torch path on CPU (decode + locate_batch, one process; with its default
  step finder, the one-frame one on CPU, and with the torch finder), when torch is installed. CUDA is
  measured only where torch sees a GPU (``--cuda``).

With ``--paired`` (and ``--before``) each frame is also timed in the two trees' processes in turn, frame by
frame (:func:`measure_paired`): on a shared machine whose speed drifts the two trees then see the same
machine, which whole passes minutes apart do not.

Run:  OMP_NUM_THREADS=1 python bench/bench_speed.py [--before /work/main/src] [--rounds 3] [--paired] [--json out.json]
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse  # noqa: E402
import csv  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from multiprocessing import get_context  # noqa: E402
from pathlib import Path  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
FIX = REPO / "fixtures" / "rendered"
SETS = ("grid", "effects", "widths", "distractors")


def _frames(sets=SETS):
    import cv2

    from doorloc.cell import DoorSize, load_cell

    out = []
    for s in sets:
        cell = load_cell(FIX / s / "cell.yaml")
        with open(FIX / s / "truth.csv", newline="") as f:
            for r in csv.DictReader(f):
                door = DoorSize(
                    float(r["width_mm"]),
                    float(r["thickness_mm"]),
                    float(r["height_mm"]),
                    float(r["arris_mm"]),
                    r["arris_profile"],
                )
                path = FIX / s / r["image"]
                out.append(
                    (f"{s}/{r['image']}", cell, door, cv2.imread(str(path), cv2.IMREAD_UNCHANGED), path)
                )
    return out


def _time(fn, frames, repeats):
    wall, cpu = [], []
    for _ in range(repeats):
        for fr in frames:
            t0, c0 = time.perf_counter(), time.thread_time()
            fn(fr)
            cpu.append((time.thread_time() - c0) * 1e3)
            wall.append((time.perf_counter() - t0) * 1e3)
    return {"wall_ms": statistics.median(wall), "cpu_ms": statistics.median(cpu), "n": len(wall)}


def _stages(frames, repeats) -> dict:
    """Median thread-CPU ms of each stage of locate (its own stage clock, ``diagnostics.timing_ms``, read
    with the thread's CPU clock instead of the wall clock) over the frames without a visible far face (the
    median frame's path; the far-face fit of the others is in edges.py, which this work leaves alone)."""
    import importlib
    import types

    import doorloc.vision.locate as L

    # the module whose clock the stages read: locate's own in older trees, doorloc.vision.state's since
    # the stages moved out of locate
    try:
        clock = importlib.import_module("doorloc.vision.state")
        if not hasattr(clock, "StageClock"):
            clock = L
    except ImportError:
        clock = L
    wall = clock.time
    clock.time = types.SimpleNamespace(perf_counter=time.thread_time)
    laps: dict[str, list[float]] = {}
    try:
        for _ in range(repeats):
            for _, cell, door, img, _ in frames:
                r = L.locate(img, cell, door)
                if r.diagnostics.get("far_face_visible") is False:
                    for k, v in r.diagnostics.get("timing_ms", {}).items():
                        laps.setdefault(k, []).append(v)
    finally:
        clock.time = wall
    return {k: round(statistics.median(v), 3) for k, v in laps.items()}


def measure_one_frame(repeats: int) -> dict:
    """Per-frame figures of the doorloc found on sys.path (run once per source tree)."""
    import cv2

    cv2.setNumThreads(1)
    sys.path.insert(0, str(REPO / "bench"))
    from bench_locate import baseline

    from doorloc.vision.imageio import decode_image
    from doorloc.vision.locate import locate

    frames = _frames()
    for _, cell, door, img, _ in frames:  # warm-up (imports, caches)
        locate(img, cell, door)
    out = {"doorloc": str(Path(sys.modules["doorloc"].__file__).parent)}
    out["locate"] = _time(lambda f: locate(f[3], f[1], f[2]), frames, repeats)
    # the grid set alone (81 of the 117 frames: the headline figure)
    grid = [f for f in frames if f[0].startswith("grid/")]
    out["locate.grid"] = _time(lambda f: locate(f[3], f[1], f[2]), grid, repeats)
    out["stages_cpu_ms"] = _stages(frames, repeats)
    out["baseline"] = _time(lambda f: baseline(f[3], f[1], f[2]), frames, repeats)
    for ext, params in ((".png", []), (".jpg", [cv2.IMWRITE_JPEG_QUALITY, 95])):
        enc = [(n, c, d, cv2.imencode(ext, img, params)[1].tobytes(), p) for n, c, d, img, p in frames]
        out[f"decode{ext}"] = _time(lambda f: decode_image(f[3]), enc, repeats)
        out[f"decode+locate{ext}"] = _time(lambda f: locate(decode_image(f[3]), f[1], f[2]), enc, repeats)
        out[f"decode+baseline{ext}"] = _time(lambda f: baseline(decode_image(f[3]), f[1], f[2]), enc, repeats)
    return out


def serve_paired(repeats: int) -> None:
    """Paired mode's worker: after a warm-up, reads frame indices on stdin and answers each with its
    locate's and the baseline's thread-CPU ms (the best of ``repeats``), one JSON line per frame."""
    import cv2

    cv2.setNumThreads(1)
    sys.path.insert(0, str(REPO / "bench"))
    from bench_locate import baseline

    from doorloc.vision.locate import locate

    frames = _frames()
    for _, cell, door, img, _ in frames:
        locate(img, cell, door)
        baseline(img, cell, door)
    print(json.dumps({"names": [f[0] for f in frames]}), flush=True)

    def cpu_ms(fn, *args) -> float:
        best = float("inf")
        for _ in range(repeats):
            c0 = time.thread_time()
            fn(*args)
            best = min(best, (time.thread_time() - c0) * 1e3)
        return best

    for line in sys.stdin:
        _, cell, door, img, _ = frames[int(line)]
        out = {
            "locate": cpu_ms(locate, img, cell, door),
            "baseline": cpu_ms(baseline, img, cell, door),
        }
        print(json.dumps(out), flush=True)


def _env_for(src: str) -> dict[str, str]:
    """The environment of a worker that measures the doorloc under ``src``: that tree first on the path;
    what else the path holds stays behind it (a lent machine's carried wheels)."""
    return dict(os.environ, PYTHONPATH=os.pathsep.join(x for x in (src, os.environ.get("PYTHONPATH")) if x))


def measure_paired(trees: dict[str, str], rounds: int, repeats: int) -> dict:
    """Each frame timed in every tree's worker in turn (the order alternating), ``rounds`` times: the trees
    see the machine in the same second, not minutes apart, which a shared machine's drifting speed
    needs (its medians moved by a third from one run to the next). Per frame the median over rounds;
    then the medians over the frames (all, the grid set), and the median of the per-frame ratios."""
    procs = {}
    for label, src in trees.items():
        procs[label] = subprocess.Popen(
            [sys.executable, __file__, "--paired-worker", "--repeats", str(repeats)],
            env=_env_for(src),
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
    names = [json.loads(procs[label].stdout.readline())["names"] for label in trees][0]
    times: dict[str, dict[str, list[list[float]]]] = {
        label: {"locate": [[] for _ in names], "baseline": [[] for _ in names]} for label in trees
    }
    order = list(trees)
    for r in range(rounds):
        for i in range(len(names)):
            for label in order if (i + r) % 2 == 0 else order[::-1]:
                p = procs[label]
                p.stdin.write(f"{i}\n")
                p.stdin.flush()
                got = json.loads(p.stdout.readline())
                for k in ("locate", "baseline"):
                    times[label][k][i].append(got[k])
    for p in procs.values():
        p.stdin.close()
        p.wait()
    grid = [i for i, n in enumerate(names) if n.startswith("grid/")]
    out: dict = {"frames": len(names), "rounds": rounds}
    per = {lab: {k: [statistics.median(t) for t in v] for k, v in ts.items()} for lab, ts in times.items()}
    for label in trees:
        out[label] = {
            "locate_ms": statistics.median(per[label]["locate"]),
            "locate_grid_ms": statistics.median(per[label]["locate"][i] for i in grid),
            "baseline_ms": statistics.median(per[label]["baseline"]),
            "per_frame_locate_ms": dict(zip(names, per[label]["locate"], strict=True)),
        }
    if len(trees) == 2:
        a, b = order
        ratio = [x / y for x, y in zip(per[b]["locate"], per[a]["locate"], strict=True)]
        out["speedup"] = {
            "locate": statistics.median(ratio),
            "locate_grid": statistics.median(ratio[i] for i in grid),
        }
    return out


def _locate_file(args) -> bool:
    import cv2

    cv2.setNumThreads(1)
    from doorloc.vision.imageio import read_image
    from doorloc.vision.locate import locate

    path, cell, door = args
    return locate(read_image(path), cell, door).ok


def measure_throughput(repeats: int, cuda: bool) -> dict:
    """Frames/s over the grid fixtures (PNG files): one-frame path on 1 and 2 processes, batched on CPU."""
    frames = _frames(("grid",))
    jobs = [(p, c, d) for _, c, d, _, p in frames]
    out = {}
    for workers in (1, 2):
        best = 0.0
        with ProcessPoolExecutor(workers, mp_context=get_context("spawn")) as pool:
            list(pool.map(_locate_file, jobs[: 2 * workers]))  # start-up and warm-up
            for _ in range(repeats):
                t = time.perf_counter()
                list(pool.map(_locate_file, jobs, chunksize=4))
                best = max(best, len(jobs) / (time.perf_counter() - t))
        out[f"one_frame_{workers}proc_fps"] = best
    try:
        import torch
    except ImportError:
        out["batched"] = "torch not installed"
        return out
    torch.set_num_threads(1)
    from doorloc.vision.batched import locate_batch
    from doorloc.vision.imageio import read_image

    cell = frames[0][1]
    # finder "auto": the one-frame step finder on CPU, torch on CUDA; "torch": the torch finder on CPU too
    runs = [("cpu", "auto", "batched_cpu_1proc_fps"), ("cpu", "torch", "batched_cpu_torch_finder_1proc_fps")]
    if cuda and torch.cuda.is_available():
        runs.append(("cuda", "auto", "batched_cuda_1proc_fps"))
    for device, finder, key in runs:
        best = 0.0
        locate_batch(
            [read_image(p) for p, _, _ in jobs[:4]],
            cell,
            [d for _, _, d in jobs[:4]],
            device=device,
            finder=finder,
        )
        for _ in range(repeats):
            t = time.perf_counter()
            for s in range(0, len(jobs), 32):
                part = jobs[s : s + 32]
                locate_batch(
                    [read_image(p) for p, _, _ in part],
                    cell,
                    [d for _, _, d in part],
                    device=device,
                    finder=finder,
                )
            best = max(best, len(jobs) / (time.perf_counter() - t))
        out[key] = best
    if not (cuda and torch.cuda.is_available()):
        out["batched_cuda"] = "not measured (no GPU here)"
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", help="another doorloc source tree (its src/) to measure in the same run")
    ap.add_argument("--repeats", type=int, default=1, help="passes over the frames per round")
    ap.add_argument("--rounds", type=int, default=3, help="rounds, alternating this tree and --before")
    ap.add_argument("--no-throughput", action="store_true")
    ap.add_argument("--cuda", action="store_true")
    ap.add_argument("--json")
    ap.add_argument(
        "--paired",
        action="store_true",
        help="also time locate frame by frame in both trees in turn (needs --before; see measure_paired)",
    )
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--paired-worker", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.worker:
        print(json.dumps(measure_one_frame(a.repeats)))
        return
    if a.paired_worker:
        serve_paired(a.repeats)
        return
    res: dict = {"cpus": os.cpu_count(), "load_avg_at_start": os.getloadavg()}
    runs = [("after", str(REPO / "src"))] + ([("before", a.before)] if a.before else [])
    # Rounds alternate the two source trees, so that both see the same machine load; figures are medians
    # over the rounds and speed-ups medians of the per-round ratios.
    rounds: dict[str, list[dict]] = {label: [] for label, _ in runs}
    for _ in range(a.rounds):
        for label, src in runs:
            p = subprocess.run(
                [sys.executable, __file__, "--worker", "--repeats", str(a.repeats)],
                env=_env_for(src),
                capture_output=True,
                text=True,
                check=True,
            )
            rounds[label].append(json.loads(p.stdout.strip().splitlines()[-1]))
    for label, _ in runs:
        rs = rounds[label]
        res[label] = {
            "doorloc": rs[0]["doorloc"],
            "rounds": rs,
            "stages_cpu_ms": {
                k: statistics.median(r["stages_cpu_ms"][k] for r in rs) for k in rs[0]["stages_cpu_ms"]
            },
        }
        for k, v in rs[0].items():
            if isinstance(v, dict) and "wall_ms" in v:
                res[label][k] = {m: statistics.median(r[k][m] for r in rs) for m in ("wall_ms", "cpu_ms")} | {
                    "n": sum(r[k]["n"] for r in rs)
                }
    if a.paired and a.before:
        res["paired"] = measure_paired({"after": str(REPO / "src"), "before": a.before}, a.rounds, 3)
    if not a.no_throughput:
        sys.path.insert(0, str(REPO / "src"))
        res["throughput"] = measure_throughput(a.repeats, a.cuda)
    res["load_avg_at_end"] = os.getloadavg()
    print(
        f"{os.cpu_count()} CPUs, load average {res['load_avg_at_start'][0]:.1f} at start, "
        f"{res['load_avg_at_end'][0]:.1f} at end (shared machine: wall times are noisy, CPU times less so)"
    )
    for label, _ in runs:
        r = res[label]
        print(f"\n{label}: {r['doorloc']}")
        for k in (
            "locate",
            "locate.grid",
            "baseline",
            "decode.png",
            "decode+locate.png",
            "decode+baseline.png",
            "decode.jpg",
            "decode+locate.jpg",
            "decode+baseline.jpg",
        ):
            v = r[k]
            print(
                f"  {k:22s} median wall {v['wall_ms']:7.3f} ms   thread CPU {v['cpu_ms']:7.3f} ms   (n={v['n']})"
            )
        print(
            "  stages (thread CPU ms, median, frames without a visible far face): "
            + ", ".join(f"{k} {v:.3f}" for k, v in r["stages_cpu_ms"].items())
        )
        print(
            f"  locate / baseline (same run): wall {r['locate']['wall_ms'] / r['baseline']['wall_ms']:.2f}, "
            f"CPU {r['locate']['cpu_ms'] / r['baseline']['cpu_ms']:.2f}"
        )
    if a.before:
        print(f"\nspeed-up, median of {a.rounds} per-round ratios (before / after):")
        for k in ("locate", "locate.grid", "decode+locate.png", "decode+locate.jpg"):
            if k not in rounds["before"][0]:
                continue
            ratio = {
                m: statistics.median(
                    b[k][m] / f[k][m] for b, f in zip(rounds["before"], rounds["after"], strict=True)
                )
                for m in ("wall_ms", "cpu_ms")
            }
            res.setdefault("speedup", {})[k] = ratio
            print(f"  {k:22s} wall {ratio['wall_ms']:.2f}x, thread CPU {ratio['cpu_ms']:.2f}x")
        sb, sa = res["before"]["stages_cpu_ms"], res["after"]["stages_cpu_ms"]
        print(
            "  stages (thread CPU ms, before -> after): "
            + ", ".join(f"{k} {sb[k]:.3f} -> {sa.get(k, float('nan')):.3f}" for k in sb)
        )
    if "paired" in res:
        pr = res["paired"]
        print(
            f"\npaired (each frame in both trees in turn, {pr['rounds']} rounds, best of 3 each; thread CPU ms,"
            " medians over the frames):"
        )
        for label in ("after", "before"):
            v = pr[label]
            print(
                f"  {label:6s} locate {v['locate_ms']:6.3f}   grid {v['locate_grid_ms']:6.3f}   "
                f"baseline {v['baseline_ms']:6.3f}   locate / baseline {v['locate_ms'] / v['baseline_ms']:.2f}"
            )
        sp = pr["speedup"]
        print(
            f"  speed-up, median of per-frame ratios: locate {sp['locate']:.2f}x, grid {sp['locate_grid']:.2f}x"
        )
    if "throughput" in res:
        print("\nframes/s over the 81 grid PNGs (decode + locate):")
        for k, v in res["throughput"].items():
            print(f"  {k:26s} {v if isinstance(v, str) else f'{v:8.1f}'}")
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
