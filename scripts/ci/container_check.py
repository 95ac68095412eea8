"""Do what the Dockerfile does, outside a container, so that the file cannot silently rot.

No container engine runs on the development or CI machines. This script reads the Dockerfile and
replays it on the host: the build stage's COPY instructions into a scratch build context, its RUN
instructions there (the same `scripts/install-venv` from the lock into a clean virtual environment,
at a scratch path instead of $VIRTUAL_ENV), then with the runtime stage's environment:
`doorloc --version`, a locate of the bundled image, and the image's CMD (on a free local port) until
its HEALTHCHECK command passes. It also checks what the host cannot replay: the runtime stage runs as
a non-root user, copies only the virtual environment, and the lock matches the base image's Python.

Run by `.ci/run` (in the background while the system services install); by hand:
`python3 scripts/ci/container_check.py`.
Standard library only: it runs before any virtual environment exists.
"""

from __future__ import annotations

import fnmatch
import json
import os
import re
import shlex
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BUNDLED_IMAGE = "fixtures/rendered/distractors/img_0003.png"
BUNDLED_CELL = "fixtures/rendered/distractors/cell.yaml"


@dataclass
class Stage:
    base: str
    name: str | None
    instructions: list[tuple[str, str]] = field(default_factory=list)

    def all(self, keyword: str) -> list[str]:
        return [arg for kw, arg in self.instructions if kw == keyword]


def parse_dockerfile(text: str) -> list[Stage]:
    """Stages with their (KEYWORD, argument) instructions; continuation lines joined, comments dropped."""
    lines = [ln for ln in text.splitlines() if not ln.lstrip().startswith("#")]
    joined = re.sub(r"\\\n", " ", "\n".join(lines))
    stages: list[Stage] = []
    for line in joined.splitlines():
        if not line.strip():
            continue
        keyword, _, arg = line.strip().partition(" ")
        keyword, arg = keyword.upper(), arg.strip()
        if keyword == "FROM":
            m = re.fullmatch(r"(\S+)(?:\s+AS\s+(\S+))?", arg, re.I)
            if not m:
                raise SystemExit(f"container check: cannot read FROM {arg!r}")
            stages.append(Stage(m.group(1), m.group(2)))
        elif not stages:
            raise SystemExit(f"container check: {keyword} before FROM")
        else:
            stages[-1].instructions.append((keyword, arg))
    return stages


def env_of(stage: Stage, base: dict[str, str]) -> dict[str, str]:
    """The stage's ENV settings applied over ``base`` (KEY=VALUE pairs, $VAR expanded)."""
    env = dict(base)
    for arg in stage.all("ENV"):
        for pair in shlex.split(arg):
            key, _, value = pair.partition("=")
            env[key] = re.sub(r"\$(\w+)|\$\{(\w+)\}", lambda m: env.get(m.group(1) or m.group(2), ""), value)
    return env


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def run(cmd: list[str] | str, cwd: Path, env: dict[str, str], what: str) -> str:
    print(f"container check: {what}", flush=True)
    proc = subprocess.run(cmd, cwd=cwd, env=env, shell=isinstance(cmd, str), text=True, capture_output=True)
    if proc.returncode != 0:
        raise SystemExit(
            f"container check FAILED: {what} (exit {proc.returncode})\n{proc.stdout}\n{proc.stderr}"
        )
    return proc.stdout


def check_host_python(stages: list[Stage]) -> None:
    """The replay must run on the Python the image runs (its lock is per Python version)."""
    m = re.match(r"python:(\d+)\.(\d+)", stages[0].base)
    assert m is not None  # check_static made sure
    if sys.version_info[:2] != (int(m.group(1)), int(m.group(2))):
        raise SystemExit(
            f"container check FAILED: this host runs Python {sys.version_info[0]}.{sys.version_info[1]}, "
            f"the image {m.group(1)}.{m.group(2)}: run the check with that Python"
        )


def check_static(stages: list[Stage]) -> None:
    """What the host cannot replay: two stages, non-root runtime, the lock for the image's Python."""
    if len(stages) != 2 or not stages[0].name:
        raise SystemExit(
            "container check FAILED: the Dockerfile must have a named build stage and a runtime stage"
        )
    build, runtime = stages
    user = runtime.all("USER")
    if not user or user[-1] in ("root", "0"):
        raise SystemExit("container check FAILED: the runtime stage must end as a non-root USER")
    if not runtime.all("HEALTHCHECK"):
        raise SystemExit("container check FAILED: the runtime stage has no HEALTHCHECK")
    for arg in runtime.all("COPY"):
        if f"--from={build.name}" not in arg:
            raise SystemExit(
                f"container check FAILED: the runtime stage copies {arg!r}, not only the build stage's venv"
            )
    m = re.match(r"python:(\d+)\.(\d+)", build.base)
    locks = re.findall(r"requirements/lock-\S+-py(\d)(\d+)\.txt", " ".join(build.all("RUN")))
    if not m or not locks or any(lk != m.groups() for lk in locks):
        raise SystemExit(
            f"container check FAILED: base {build.base} and the lock(s) {locks} it installs disagree"
        )
    check_context(build)


def check_context(build: Stage) -> None:
    """Every file the build stage copies exists and is not left out of the build context by .dockerignore."""
    ignore_file = ROOT / ".dockerignore"
    ignored = (
        [ln.strip().rstrip("/") for ln in ignore_file.read_text(encoding="utf-8").splitlines()]
        if ignore_file.exists()
        else []
    )
    ignored = [p for p in ignored if p and not p.startswith(("#", "!"))]
    for arg in build.all("COPY"):
        for src in shlex.split(arg)[:-1]:
            if src.startswith("--"):
                continue
            if not (ROOT / src).exists():
                raise SystemExit(f"container check FAILED: COPY {src}: no such file in the repository")
            for pattern in ignored:
                if fnmatch.fnmatch(src, pattern) or src.startswith(pattern + "/"):
                    raise SystemExit(
                        f"container check FAILED: COPY {src}, but .dockerignore leaves out {pattern!r}"
                    )


def replay_build(build: Stage, scratch: Path) -> tuple[Path, dict[str, str]]:
    """COPY into a scratch context, RUN there; returns the virtual environment made."""
    workdir = scratch / "src"
    workdir.mkdir(parents=True)
    venv = scratch / "venv"
    env = env_of(build, {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "VIRTUAL_ENV"))})
    image_venv = env.get("VIRTUAL_ENV")
    if not image_venv:
        raise SystemExit(
            "container check FAILED: the build stage must set ENV VIRTUAL_ENV (where the venv goes)"
        )
    env["VIRTUAL_ENV"] = str(venv)
    for kw, arg in build.instructions:
        if kw == "COPY":
            *sources, dest = shlex.split(arg)
            target = workdir / dest
            for src in sources:
                path = ROOT / src
                if not path.exists():
                    raise SystemExit(f"container check FAILED: COPY {src}: no such file in the repository")
                if path.is_dir():  # Docker copies a directory's contents, not the directory
                    shutil.copytree(
                        path, target, dirs_exist_ok=True, ignore=shutil.ignore_patterns("__pycache__")
                    )
                    continue
                to = target / path.name if dest.endswith("/") or len(sources) > 1 else target
                to.parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(path, to)
        elif kw == "RUN":
            t0 = time.monotonic()
            run(arg, workdir, env, f"RUN {arg}  (VIRTUAL_ENV={venv})")
            print(f"container check:   took {time.monotonic() - t0:.0f} s", flush=True)
        elif kw not in ("ENV", "WORKDIR", "ARG", "LABEL"):
            raise SystemExit(
                f"container check FAILED: the build stage uses {kw}, which this check cannot replay"
            )
    if not (venv / "bin" / "doorloc").exists():
        raise SystemExit(f"container check FAILED: the build stage made no doorloc in {image_venv}")
    return venv, env


def replay_runtime(runtime: Stage, venv: Path, scratch: Path) -> None:
    image_venv = env_of(runtime, {}).get("VIRTUAL_ENV", "/opt/doorloc")
    env = env_of(runtime, {"PATH": os.environ.get("PATH", "/usr/bin:/bin"), "VIRTUAL_ENV": image_venv})
    # paths into the image's venv (PATH, NUMBA_CACHE_DIR) lead into the one made here
    env = {k: v.replace(image_venv, str(venv)) for k, v in env.items()}
    env["DOORLOC_DATABASE_URL"] = f"sqlite:///{scratch}/recipes.db"
    env["DOORLOC_CELL"] = str(ROOT / BUNDLED_CELL)
    home = scratch / "home"
    home.mkdir()
    env["HOME"] = str(home)
    if shutil.which("doorloc", path=env["PATH"]) != str(venv / "bin" / "doorloc"):
        raise SystemExit("container check FAILED: the runtime PATH does not find doorloc in the copied venv")
    print(run(["doorloc", "--version"], home, env, "doorloc --version").strip())
    out = run(
        [
            "doorloc",
            "locate",
            str(ROOT / BUNDLED_IMAGE),
            "--cell",
            str(ROOT / BUNDLED_CELL),
            "--door-width",
            "900",
            "--door-thickness",
            "50",
            "--indent",
            "0",
        ],
        home,
        env,
        f"doorloc locate {BUNDLED_IMAGE}",
    )
    result = json.loads(out)
    if not result.get("ok"):
        raise SystemExit(f"container check FAILED: locate refused the bundled image: {result.get('error')}")
    print(
        f"container check:   x {result['x_mm']:.3f} mm, z {result['z_mm']:.3f} mm, yaw {result['yaw_deg']:.4f} deg"
    )

    port = free_port()
    # The image's CMD listens on 0.0.0.0, which `serve` allows only with API keys: run it as the Dockerfile
    # says a container is run (with DOORLOC_API_KEY set), on loopback here.
    env["DOORLOC_API_KEY"] = "container-check-key"
    cmd = json.loads(runtime.all("CMD")[-1]) + [
        "--host",
        "127.0.0.1",
        "--port",
        str(port),
    ]  # the last option wins
    health = runtime.all("HEALTHCHECK")[-1].split(" CMD ", 1)[1].replace(":8000/", f":{port}/")
    print(f"container check: CMD {' '.join(cmd)}; HEALTHCHECK on port {port}", flush=True)
    server = subprocess.Popen(
        cmd, cwd=home, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    try:
        deadline = time.monotonic() + 120
        while True:
            if server.poll() is not None:
                raise SystemExit(
                    f"container check FAILED: CMD exited {server.returncode}\n{server.communicate()[0]}"
                )
            probe = subprocess.run(health, shell=True, cwd=home, env=env, capture_output=True, text=True)
            if probe.returncode == 0:
                print("container check:   HEALTHCHECK passed")
                break
            if time.monotonic() > deadline:
                raise SystemExit(
                    f"container check FAILED: HEALTHCHECK still failing after 120 s\n{probe.stderr}"
                )
            time.sleep(1)
    finally:
        server.terminate()
        try:
            server.wait(timeout=20)
        except subprocess.TimeoutExpired:
            server.kill()


def main() -> None:
    stages = parse_dockerfile((ROOT / "Dockerfile").read_text(encoding="utf-8"))
    check_static(stages)
    check_host_python(stages)
    with tempfile.TemporaryDirectory(prefix="doorloc-container-check-") as tmp:
        scratch = Path(tmp)
        venv, _ = replay_build(stages[0], scratch)
        replay_runtime(stages[1], venv, scratch)
    print("container check: OK")


if __name__ == "__main__":
    main()
