#!/usr/bin/env python
"""Speed of locate: one frame on one thread, decode + locate, and frames/s over a folder.

Frames, three columns:

- ``realistic`` (the headline): 1080p frames as a real camera gives them, rendered at the start of the run
  with doorloc's own renderer into a temporary folder (:func:`render_realistic`: a lens with barrel
  distortion, a measured camera response, shot and read noise, blur, a lighting gradient; sharp-edged doors at
  random poses in the envelope; PNG and JPEG; the seed is printed, ``--seed`` repeats it, ``--frames-dir``
  keeps the folder and reuses it);
- ``realistic_calibrated``: the same frames in the same cell with ``locate.response_check:
  where_unmeasured``: the camera response the cell measured (2.2 +- 0.05) is not read again on every frame
  (a tree without that setting has no such column);
- ``fixtures``: every committed fixture (fixtures/rendered/*, 117 clean 1080p grey PNGs with zero
  distortion, each with its door from truth.csv).

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
machine, which whole passes minutes apart do not. The paired run also holds the two trees' answers to each
other (pose within 1e-6 mm / deg, the same refusals) and says where they differ.

Run:  OMP_NUM_THREADS=1 python bench/bench_speed.py [--before /work/main/src] [--rounds 3] [--paired]
      [--frames 24] [--seed 1] [--frames-dir DIR] [--json out.json]
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
import tempfile  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from dataclasses import fields, replace  # noqa: E402
from multiprocessing import get_context  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
FIX = REPO / "fixtures" / "rendered"
SETS = ("grid", "effects", "widths", "distractors")
#: the columns of frames (see the module's docstring)
GROUPS = ("realistic", "realistic_calibrated", "fixtures")


def _read_set(folder: Path, label: str) -> list:
    """``(name, cell, door, image, path)`` of every frame in a folder with ``cell.yaml`` and ``truth.csv``."""
    import cv2

    from doorloc.cell import DoorSize, load_cell

    cell = load_cell(folder / "cell.yaml")
    out = []
    with open(folder / "truth.csv", newline="") as f:
        for r in csv.DictReader(f):
            door = DoorSize(
                float(r["width_mm"]),
                float(r["thickness_mm"]),
                float(r["height_mm"]),
                float(r["arris_mm"]),
                r["arris_profile"],
            )
            path = folder / r["image"]
            out.append(
                (f"{label}/{r['image']}", cell, door, cv2.imread(str(path), cv2.IMREAD_UNCHANGED), path)
            )
    return out


def _frames(sets=SETS, realistic: Path | None = None):
    """The realistic frames in ``realistic`` (if given), again in a cell that trusts its measured response
    (where the tree has that setting), then the fixtures of ``sets``."""
    from doorloc.vision.config import LocateConfig

    out = [] if realistic is None else _read_set(realistic, "realistic")
    if out and "response_check" in {f.name for f in fields(LocateConfig)}:
        out += [
            (
                n.replace("realistic/", "realistic_calibrated/", 1),
                replace(c, locate=replace(c.locate, response_check="where_unmeasured")),
                d,
                img,
                p,
            )
            for n, c, d, img, p in out
        ]
    for s in sets:
        out += _read_set(FIX / s, f"fixtures/{s}")
    return out


#: the lens of the realistic frames: a sane barrel distortion of a 1080p machine-vision lens (k1, k2)
REALISTIC_DIST = (-0.08, 0.05, 0.0, 0.0, 0.0)


def render_realistic(out_dir: Path, count: int, seed: int) -> Path:
    """Render ``count`` realistic 1080p frames into ``out_dir`` with doorloc's own renderer: the thesis cell
    with a distorting lens (:data:`REALISTIC_DIST`), a camera response measured as 2.2 +- 0.05 (the cell
    says so; each frame's true exponent drawn within 2 sigma), shot and read noise of a small sensor, optical
    blur, a lighting gradient and wood grain; sharp-edged doors of random thickness at random poses in the
    envelope. Each frame is written as PNG and as JPEG (quality 95), with ``truth.csv`` and ``cell.yaml``.
    Returns ``out_dir``."""
    import cv2

    from doorloc.calib.camera import CameraModel
    from doorloc.cell import DoorSize, load_cell, save_cell
    from doorloc.sim.dataset import random_poses
    from doorloc.sim.door import render_door
    from doorloc.sim.effects import Effects

    base = load_cell(REPO / "fixtures" / "cell_thesis.yaml")
    cam = base.camera
    cell = replace(
        base,
        camera=CameraModel(cam.camera_matrix, np.array(REALISTIC_DIST), cam.image_size),
        response_gamma=2.2,
        response_gamma_sigma=0.05,
    )
    rng = np.random.default_rng([seed, 38])
    rows = []
    out_dir.mkdir(parents=True, exist_ok=True)
    for k, pose in enumerate(random_poses(cell.envelope, count, seed)):
        # sharp-edged doors of random thickness (the grid fixtures' door: an arrised edge is fitted by
        # another, far slower model, a figure of its own)
        door = DoorSize(900.0, float(rng.uniform(30.0, 62.0)), 2100.0, 0.0, "chamfer")
        fx = Effects(
            arris_profile=door.arris_profile,
            gamma=float(rng.uniform(2.1, 2.3)),
            full_well_e=float(rng.uniform(6000.0, 15000.0)),
            read_noise_dn=float(rng.uniform(0.8, 2.5)),
            blur_sigma_px=float(rng.uniform(0.5, 1.0)),
            gradient_u=float(rng.uniform(-0.15, 0.15)),
            gradient_v=float(rng.uniform(-0.15, 0.15)),
            vignetting=float(rng.uniform(0.0, 0.2)),
            grain_contrast=float(rng.uniform(0.0, 0.08)),
        )
        img = render_door(cell, door, pose, effects=fx, seed=seed * 1000 + k).image
        name = f"img_{k:03d}"
        cv2.imwrite(str(out_dir / f"{name}.png"), img)
        cv2.imwrite(str(out_dir / f"{name}.jpg"), img, [cv2.IMWRITE_JPEG_QUALITY, 95])
        rows.append(
            {
                "image": f"{name}.png",
                "width_mm": door.width_mm,
                "thickness_mm": door.thickness_mm,
                "height_mm": door.height_mm,
                "arris_mm": door.arris_mm,
                "arris_profile": door.arris_profile,
                "x_mm": pose.x_mm,
                "z_mm": pose.z_mm,
                "yaw_deg": pose.yaw_deg,
                "gamma": fx.gamma,
            }
        )
    save_cell(cell, out_dir / "cell.yaml")
    with open(out_dir / "truth.csv", "w", newline="") as f:
        wr = csv.DictWriter(f, fieldnames=list(rows[0]))
        wr.writeheader()
        wr.writerows(rows)
    return out_dir


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


def _encoded(frames, ext: str) -> list:
    """The frames as ``ext`` file bytes: the file on disk where it is one (the realistic frames' PNG and
    JPEG), else the decoded fixture encoded again (JPEG quality 95)."""
    import cv2

    out = []
    for n, c, d, img, p in frames:
        f = p.with_suffix(ext)
        if f.exists():
            data = f.read_bytes()
        else:
            params = [cv2.IMWRITE_JPEG_QUALITY, 95] if ext == ".jpg" else []
            data = cv2.imencode(ext, img, params)[1].tobytes()
        out.append((n, c, d, data, p))
    return out


def measure_one_frame(repeats: int, realistic: Path) -> dict:
    """Per-frame figures of the doorloc found on sys.path (run once per source tree), per column of
    frames (``realistic``, ``fixtures``; ``fixtures.grid``: the 81 grid fixtures)."""
    import cv2

    cv2.setNumThreads(1)
    sys.path.insert(0, str(REPO / "bench"))
    from bench_locate import baseline

    from doorloc.vision.imageio import decode_image
    from doorloc.vision.locate import locate

    frames = _frames(realistic=realistic)
    for _, cell, door, img, _ in frames:  # warm-up (imports, caches)
        locate(img, cell, door)
    out: dict = {"doorloc": str(Path(sys.modules["doorloc"].__file__).parent)}
    for group in GROUPS:
        fs = [f for f in frames if f[0].startswith(group + "/")]
        if not fs:
            continue
        g: dict = {}
        g["locate"] = _time(lambda f: locate(f[3], f[1], f[2]), fs, repeats)
        g["baseline"] = _time(lambda f: baseline(f[3], f[1], f[2]), fs, repeats)
        g["stages_cpu_ms"] = _stages(fs, repeats)
        for ext in (".png", ".jpg"):
            enc = _encoded(fs, ext)
            g[f"decode{ext}"] = _time(lambda f: decode_image(f[3]), enc, repeats)
            g[f"decode+locate{ext}"] = _time(lambda f: locate(decode_image(f[3]), f[1], f[2]), enc, repeats)
            g[f"decode+baseline{ext}"] = _time(
                lambda f: baseline(decode_image(f[3]), f[1], f[2]), enc, repeats
            )
        out[group] = g
    grid = [f for f in frames if f[0].startswith("fixtures/grid/")]
    out["fixtures"]["locate.grid"] = _time(lambda f: locate(f[3], f[1], f[2]), grid, repeats)
    return out


def _answer(r) -> dict:
    """What a locate result says, for holding two trees' answers to each other."""
    return {
        "ok": r.ok,
        "error_code": r.error_code,
        **{k: getattr(r, k) for k in ("x_mm", "z_mm", "yaw_deg", "thickness_mm")},
    }


def serve_paired(repeats: int, realistic: Path) -> None:
    """Paired mode's worker: after a warm-up, reads frame names on stdin and answers each with its
    locate's and the baseline's thread-CPU ms (the best of ``repeats``) and locate's answer, one JSON line
    per frame."""
    import cv2

    cv2.setNumThreads(1)
    sys.path.insert(0, str(REPO / "bench"))
    from bench_locate import baseline

    from doorloc.vision.locate import locate

    frames = _frames(realistic=realistic)
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

    by_name = {f[0]: f for f in frames}
    for line in sys.stdin:
        _, cell, door, img, _ = by_name[line.strip()]
        out = {
            "locate": cpu_ms(locate, img, cell, door),
            "baseline": cpu_ms(baseline, img, cell, door),
            "answer": _answer(locate(img, cell, door)),
        }
        print(json.dumps(out), flush=True)


def _env_for(src: str) -> dict[str, str]:
    """The environment of a worker that measures the doorloc under ``src``: that tree first on the path;
    what else the path holds stays behind it (a lent machine's carried wheels)."""
    return dict(os.environ, PYTHONPATH=os.pathsep.join(x for x in (src, os.environ.get("PYTHONPATH")) if x))


def _answers_differ(a: dict, b: dict, tol: float = 1e-6) -> str | None:
    """How two answers differ (another refusal, or a number by more than ``tol``), or None."""
    if (a["ok"], a["error_code"]) != (b["ok"], b["error_code"]):
        return f"ok/error {a['ok']}/{a['error_code']} vs {b['ok']}/{b['error_code']}"
    for k in ("x_mm", "z_mm", "yaw_deg", "thickness_mm"):
        x, y = a[k], b[k]
        if (x is None) != (y is None) or (x is not None and not abs(x - y) <= tol):
            return f"{k} {x} vs {y}"
    return None


def measure_paired(trees: dict[str, str], rounds: int, repeats: int, realistic: Path) -> dict:
    """Each frame timed in every tree's worker in turn (the order alternating), ``rounds`` times: the trees
    see the machine in the same second, not minutes apart, which a shared machine's drifting speed
    needs (its medians moved by a third from one run to the next). Per frame the median over rounds;
    then per column the medians over the frames, and the median of the per-frame ratios. The two trees'
    answers are held to each other on every frame (``answers_differ``)."""
    procs = {}
    for label, src in trees.items():
        procs[label] = subprocess.Popen(
            [
                sys.executable,
                __file__,
                "--paired-worker",
                "--repeats",
                str(repeats),
                "--frames-dir",
                str(realistic),
            ],
            env=_env_for(src),
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
    # the frames every tree has (a column that an older tree lacks is left out)
    listed = [json.loads(procs[label].stdout.readline())["names"] for label in trees]
    names = [n for n in listed[0] if all(n in other for other in listed[1:])]
    times: dict[str, dict[str, list[list[float]]]] = {
        label: {"locate": [[] for _ in names], "baseline": [[] for _ in names]} for label in trees
    }
    answers: dict[str, list[dict]] = {label: [{} for _ in names] for label in trees}
    order = list(trees)
    for r in range(rounds):
        for i in range(len(names)):
            for label in order if (i + r) % 2 == 0 else order[::-1]:
                p = procs[label]
                p.stdin.write(f"{names[i]}\n")
                p.stdin.flush()
                got = json.loads(p.stdout.readline())
                for k in ("locate", "baseline"):
                    times[label][k][i].append(got[k])
                answers[label][i] = got["answer"]
    for p in procs.values():
        p.stdin.close()
        p.wait()
    out: dict = {"frames": len(names), "rounds": rounds}
    per = {lab: {k: [statistics.median(t) for t in v] for k, v in ts.items()} for lab, ts in times.items()}
    columns = {g: [i for i, n in enumerate(names) if n.startswith(g + "/")] for g in GROUPS}
    columns = {g: idx for g, idx in columns.items() if idx}
    columns["fixtures.grid"] = [i for i, n in enumerate(names) if n.startswith("fixtures/grid/")]
    for label in trees:
        out[label] = {
            g: {
                "locate_ms": statistics.median(per[label]["locate"][i] for i in idx),
                "baseline_ms": statistics.median(per[label]["baseline"][i] for i in idx),
            }
            for g, idx in columns.items()
        } | {
            "per_frame_locate_ms": dict(zip(names, per[label]["locate"], strict=True)),
            "refused": [names[i] for i, a in enumerate(answers[label]) if not a["ok"]],
        }
    if len(trees) == 2:
        a, b = order
        ratio = [x / y for x, y in zip(per[b]["locate"], per[a]["locate"], strict=True)]
        out["speedup"] = {g: statistics.median(ratio[i] for i in idx) for g, idx in columns.items()}
        out["answers_differ"] = {
            names[i]: d
            for i in range(len(names))
            if (d := _answers_differ(answers[a][i], answers[b][i])) is not None
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
    ap.add_argument("--frames", type=int, default=24, help="realistic frames to render")
    ap.add_argument("--seed", type=int, help="seed of the realistic frames (default: a random one, printed)")
    ap.add_argument(
        "--frames-dir",
        type=Path,
        help="keep the realistic frames in this folder (rendered there unless it holds a truth.csv)",
    )
    ap.add_argument("--no-one-frame", action="store_true", help="skip the whole-pass figures (paired only)")
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
        print(json.dumps(measure_one_frame(a.repeats, a.frames_dir)))
        return
    if a.paired_worker:
        serve_paired(a.repeats, a.frames_dir)
        return
    res: dict = {"cpus": os.cpu_count(), "load_avg_at_start": os.getloadavg()}
    with tempfile.TemporaryDirectory(prefix="doorloc-speed-") as tmp:
        frames_dir = a.frames_dir or Path(tmp)
        if (frames_dir / "truth.csv").exists():
            print(f"realistic frames: reusing {frames_dir}")
        else:
            seed = a.seed if a.seed is not None else int(np.random.SeedSequence().entropy % 1_000_000)
            print(f"realistic frames: rendering {a.frames} with seed {seed} into {frames_dir}", flush=True)
            sys.path.insert(0, str(REPO / "src"))
            render_realistic(frames_dir, a.frames, seed)
            res["seed"] = seed
        _measure(a, res, frames_dir)
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1))


def _measure(a, res: dict, frames_dir: Path) -> None:
    runs = [("after", str(REPO / "src"))] + ([("before", a.before)] if a.before else [])
    # Rounds alternate the two source trees, so that both see the same machine load; figures are medians
    # over the rounds and speed-ups medians of the per-round ratios.
    rounds: dict[str, list[dict]] = {label: [] for label, _ in runs}
    for _ in range(0 if a.no_one_frame else a.rounds):
        for label, src in runs:
            p = subprocess.run(
                [
                    sys.executable,
                    __file__,
                    "--worker",
                    "--repeats",
                    str(a.repeats),
                    "--frames-dir",
                    str(frames_dir),
                ],
                env=_env_for(src),
                capture_output=True,
                text=True,
                check=True,
            )
            rounds[label].append(json.loads(p.stdout.strip().splitlines()[-1]))
    if not a.no_one_frame:
        for label, _ in runs:
            rs = rounds[label]
            res[label] = {"doorloc": rs[0]["doorloc"], "rounds": rs}
            for g in (g for g in GROUPS if g in rs[0]):
                out = res[label][g] = {
                    "stages_cpu_ms": {
                        k: statistics.median(r[g]["stages_cpu_ms"][k] for r in rs)
                        for k in rs[0][g]["stages_cpu_ms"]
                    }
                }
                for k, v in rs[0][g].items():
                    if isinstance(v, dict) and "wall_ms" in v:
                        out[k] = {
                            m: statistics.median(r[g][k][m] for r in rs) for m in ("wall_ms", "cpu_ms")
                        } | {"n": sum(r[g][k]["n"] for r in rs)}
    if a.paired and a.before:
        trees = {"after": str(REPO / "src"), "before": a.before}
        res["paired"] = measure_paired(trees, a.rounds, 3, frames_dir)
    if not a.no_throughput:
        sys.path.insert(0, str(REPO / "src"))
        res["throughput"] = measure_throughput(a.repeats, a.cuda)
    res["load_avg_at_end"] = os.getloadavg()
    print(
        f"{os.cpu_count()} CPUs, load average {res['load_avg_at_start'][0]:.1f} at start, "
        f"{res['load_avg_at_end'][0]:.1f} at end (shared machine: wall times are noisy, CPU times less so)"
    )
    for label, _ in runs if not a.no_one_frame else ():
        print(f"\n{label}: {res[label]['doorloc']}")
        for g in (g for g in GROUPS if g in res[label]):
            r = res[label][g]
            print(f"  {g}:")
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
                if k not in r:
                    continue
                v = r[k]
                print(
                    f"    {k:22s} median wall {v['wall_ms']:7.3f} ms   thread CPU {v['cpu_ms']:7.3f} ms   "
                    f"(n={v['n']})"
                )
            print(
                "    stages (thread CPU ms, median, frames without a visible far face): "
                + ", ".join(f"{k} {v:.3f}" for k, v in r["stages_cpu_ms"].items())
            )
            print(
                f"    locate / baseline (same run): wall {r['locate']['wall_ms'] / r['baseline']['wall_ms']:.2f}, "
                f"CPU {r['locate']['cpu_ms'] / r['baseline']['cpu_ms']:.2f}"
            )
    if a.before and not a.no_one_frame:
        print(f"\nspeed-up, median of {a.rounds} per-round ratios (before / after):")
        for g in (g for g in GROUPS if g in rounds["before"][0]):
            for k in ("locate", "locate.grid", "decode+locate.png", "decode+locate.jpg"):
                if k not in rounds["before"][0][g]:
                    continue
                ratio = {
                    m: statistics.median(
                        b[g][k][m] / f[g][k][m]
                        for b, f in zip(rounds["before"], rounds["after"], strict=True)
                    )
                    for m in ("wall_ms", "cpu_ms")
                }
                res.setdefault("speedup", {})[f"{g}.{k}"] = ratio
                print(f"  {g + '.' + k:32s} wall {ratio['wall_ms']:.2f}x, thread CPU {ratio['cpu_ms']:.2f}x")
            sb, sa = res["before"][g]["stages_cpu_ms"], res["after"][g]["stages_cpu_ms"]
            print(
                f"  {g} stages (thread CPU ms, before -> after): "
                + ", ".join(f"{k} {sb[k]:.3f} -> {sa.get(k, float('nan')):.3f}" for k in sb)
            )
    if "paired" in res:
        pr = res["paired"]
        print(
            f"\npaired (each frame in both trees in turn, {pr['rounds']} rounds, best of 3 each; thread CPU ms,"
            " medians over the frames):"
        )
        for g in (g for g in (*GROUPS, "fixtures.grid") if g in pr["speedup"]):
            for label in ("after", "before"):
                v = pr[label][g]
                print(
                    f"  {g:14s} {label:6s} locate {v['locate_ms']:6.3f}   baseline {v['baseline_ms']:6.3f}   "
                    f"locate / baseline {v['locate_ms'] / v['baseline_ms']:.3f}"
                )
            print(f"  {g:14s} speed-up, median of per-frame ratios: {pr['speedup'][g]:.2f}x")
        for label in ("after", "before"):
            print(f"  {label} refused {len(pr[label]['refused'])} of {pr['frames']}: {pr[label]['refused']}")
        diff = pr["answers_differ"]
        print(
            "  answers: the same on every frame (1e-6 mm / deg, same refusals)"
            if not diff
            else f"  answers DIFFER on {len(diff)} frames: {diff}"
        )
    if "throughput" in res:
        print("\nframes/s over the 81 grid PNGs (decode + locate):")
        for k, v in res["throughput"].items():
            print(f"  {k:26s} {v if isinstance(v, str) else f'{v:8.1f}'}")


if __name__ == "__main__":
    main()
