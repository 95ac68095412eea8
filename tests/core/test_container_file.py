"""The Dockerfile's static promises, checked on every test run (the full replay runs in .ci/run).

scripts/ci/container_check.py replays the Dockerfile outside a container (install from the lock into a
clean venv, `doorloc --version`, a locate, the CMD until the HEALTHCHECK passes); that takes minutes and
the network, so the test suite checks only what needs neither: two stages, a non-root runtime with a
health check that copies only the build stage's venv, the lock matching the base image's Python, and
every copied file present and not left out by .dockerignore.
"""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[2]
_spec = importlib.util.spec_from_file_location(
    "container_check", ROOT / "scripts" / "ci" / "container_check.py"
)
assert _spec is not None and _spec.loader is not None
container_check = importlib.util.module_from_spec(_spec)
sys.modules["container_check"] = container_check  # its dataclasses look their module up while being made
_spec.loader.exec_module(container_check)
DOCKERFILE = (ROOT / "Dockerfile").read_text(encoding="utf-8")


def test_the_dockerfile_keeps_its_static_promises():
    stages = container_check.parse_dockerfile(DOCKERFILE)
    container_check.check_static(stages)
    build, runtime = stages
    assert any(
        "scripts/install-venv" in run and "requirements/lock-service-py" in run for run in build.all("RUN")
    )
    assert json.loads(runtime.all("CMD")[-1])[:2] == ["doorloc", "serve"]


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (("USER doorloc", "USER root"), "non-root"),
        (("HEALTHCHECK", "# HEALTHCHECK"), "HEALTHCHECK"),
        (("lock-service-py311.txt", "lock-service-py312.txt"), "disagree"),
        (("COPY src src/", "COPY srcs src/"), "no such file"),
        (
            (
                "COPY --from=build /opt/doorloc /opt/doorloc",
                "COPY --from=build /opt/doorloc /opt/doorloc\nCOPY src /src",
            ),
            "not only the build stage",
        ),
    ],
)
def test_a_broken_dockerfile_is_caught(change, message):
    broken = DOCKERFILE.replace(*change)
    assert broken != DOCKERFILE
    with pytest.raises(SystemExit, match=message):
        container_check.check_static(container_check.parse_dockerfile(broken))


def test_a_copied_file_left_out_by_dockerignore_is_caught():
    broken = DOCKERFILE.replace("COPY src src/", "COPY src src/\nCOPY tests tests/")
    with pytest.raises(SystemExit, match="dockerignore"):
        container_check.check_static(container_check.parse_dockerfile(broken))
