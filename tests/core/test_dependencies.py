"""Declared dependencies are the imported ones, and the lock pins every declared one.

Read from the source (AST of every import in src/, tests/ and bench/) against pyproject.toml and
requirements/lock-*.txt, so that a new import without a declaration, a declaration nobody imports,
or a pyproject change without `scripts/lock` fails here rather than on a customer's machine.
"""

from __future__ import annotations

import ast
import functools
import re
import sys
import tomllib
from collections.abc import Iterable
from importlib import metadata
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

ROOT = Path(__file__).parents[2]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
LOCKS = sorted((ROOT / "requirements").glob("lock-*.txt"))

#: declared but never imported, each for a stated reason (anything else declared must be imported)
NOT_IMPORTED = {
    "python-multipart": "FastAPI imports it to parse the multipart upload of POST /v1/locate",
    "psycopg": "SQLAlchemy loads it for postgresql+psycopg:// database URLs",
    "pytest-xdist": "a pytest plugin (scripts/test runs pytest -n 2)",
    "ruff": "a command-line tool (lint and format check in CI)",
    "mypy": "a command-line tool (type check in CI)",
    "pyright": "a command-line tool (type check in CI)",
}


def _requirements(names: Iterable[str] = ()) -> dict[str, Requirement]:
    """The runtime requirements plus those of the named extras, by canonical name."""
    reqs = [Requirement(r) for r in PYPROJECT["project"]["dependencies"]]
    for extra in names:
        reqs += [Requirement(r) for r in PYPROJECT["project"]["optional-dependencies"][extra]]
    return {canonicalize_name(r.name): r for r in reqs}


def _is_stub_package(name: str) -> bool:
    return name.startswith("types-") or name.endswith("-stubs")


def _third_party_imports(folder: Path) -> dict[str, str]:
    """Top-level module name -> first file importing it, for every absolute non-stdlib import."""
    found: dict[str, str] = {}
    # the project's own modules (helpers that tests and benchmarks import by path) are not third-party
    local = {p.stem for d in ("src", "tests", "bench") for p in (ROOT / d).rglob("*.py")} | {"doorloc"}
    for path in sorted(folder.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                mods = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                mods = [node.module]
            else:
                continue
            for m in mods:
                top = m.split(".")[0]
                if top not in sys.stdlib_module_names and top not in local:
                    found.setdefault(top, str(path.relative_to(ROOT)))
    return found


@functools.cache
def _module_distributions() -> dict[str, list[str]]:
    return dict(metadata.packages_distributions())


#: extras a fresh `scripts/setup` does not install (their own lock; `scripts/setup --torch`), so their modules
#: may be absent here; an import of one is matched to the extra by the distribution's name instead
SEPARATELY_LOCKED_EXTRAS = ("torch",)


def _distributions(module: str, where: str) -> set[str]:
    dists = _module_distributions().get(module)
    if not dists:
        optional = _requirements(SEPARATELY_LOCKED_EXTRAS).keys() - _requirements().keys()
        if canonicalize_name(module) in optional:
            return {canonicalize_name(module)}
        pytest.fail(
            f"{where} imports {module!r}, which no installed distribution provides: declare it in "
            "pyproject.toml, run scripts/lock and scripts/setup"
        )
    return {canonicalize_name(d) for d in dists}


def _pins(lock: Path) -> dict[str, str]:
    text = lock.read_text(encoding="utf-8")
    return {
        canonicalize_name(m.group(1)): m.group(2)
        for m in re.finditer(r"^([A-Za-z0-9][A-Za-z0-9._-]*)==(\S+)", text, re.M)
    }


def test_every_import_in_src_is_a_declared_dependency():
    runtime = _requirements()
    extras = _requirements(PYPROJECT["project"]["optional-dependencies"])
    for module, where in _third_party_imports(ROOT / "src").items():
        dists = _distributions(module, where)
        assert dists & extras.keys(), (
            f"{where} imports {module!r} ({sorted(dists)}) but pyproject declares none of them"
        )
        # an import that only an extra provides must be one the code imports lazily, where the feature is used
        # (ray: the batch's Ray backend; torch: doorloc.vision.batched, imported only by `batch --device`)
        if not dists & runtime.keys():
            assert module in {"ray", "torch"}, (
                f"{where} imports {module!r}, declared only as an extra: make it a dependency"
            )


def test_every_import_in_tests_and_bench_is_declared_for_development():
    # torch comes from its own lock (scripts/setup --torch, which CI runs); its tests skip without it
    dev = _requirements(["dev", "torch"])
    for folder in ("tests", "bench"):
        for module, where in _third_party_imports(ROOT / folder).items():
            dists = _distributions(module, where)
            assert dists & dev.keys(), (
                f"{where} imports {module!r} ({sorted(dists)}): add it to the dev extra"
            )


def test_every_declared_dependency_is_imported_or_has_a_stated_reason():
    imported: set[str] = set()
    for folder in ("src", "tests", "bench"):
        for module, where in _third_party_imports(ROOT / folder).items():
            imported |= _distributions(module, where)
    declared = _requirements(PYPROJECT["project"]["optional-dependencies"])
    unused = sorted(
        n for n in declared if n not in imported and n not in NOT_IMPORTED and not _is_stub_package(n)
    )
    assert not unused, f"declared in pyproject.toml but imported nowhere: {unused}; use them or drop them"


@pytest.mark.parametrize("lock", [p for p in LOCKS if "-dev-" in p.name], ids=lambda p: p.name)
def test_the_dev_lock_pins_every_declared_requirement_within_its_range(lock):
    pins = _pins(lock)
    extras = [e for e in PYPROJECT["project"]["optional-dependencies"] if e != "torch"]
    for name, req in _requirements(extras).items():
        assert name in pins, f"{lock.name} does not pin {req}: run scripts/lock"
        assert req.specifier.contains(pins[name], prereleases=True), (
            f"{lock.name} pins {name}=={pins[name]} outside pyproject's {req}: run scripts/lock"
        )
    for build_req in PYPROJECT["build-system"]["requires"]:
        assert canonicalize_name(Requirement(build_req).name) in pins, (
            f"{lock.name} lacks the build backend {build_req}"
        )


@pytest.mark.parametrize("lock", [p for p in LOCKS if "-service-" in p.name], ids=lambda p: p.name)
def test_the_service_lock_is_the_dev_lock_s_versions(lock):
    dev = _pins(lock.with_name(lock.name.replace("-service-", "-dev-")))
    service = _pins(lock)
    assert _requirements(["postgres"]).keys() <= service.keys()
    assert {n: v for n, v in service.items() if dev.get(n) != v} == {}


@pytest.mark.parametrize("lock", LOCKS, ids=lambda p: p.name)
def test_every_locked_package_carries_a_hash(lock):
    # pip --require-hashes refuses a file with any unhashed requirement; say which one here
    blocks = re.split(r"\n(?=[A-Za-z0-9])", lock.read_text(encoding="utf-8"))
    pinned = [b for b in blocks if re.match(r"[A-Za-z0-9][A-Za-z0-9._-]*==", b)]
    assert pinned
    assert [b.split()[0] for b in pinned if "--hash=sha256:" not in b] == []


def test_locks_exist_for_the_supported_pythons():
    names = {p.name for p in LOCKS}
    for py in ("311", "312"):
        assert {f"lock-dev-py{py}.txt", f"lock-service-py{py}.txt"} <= names
