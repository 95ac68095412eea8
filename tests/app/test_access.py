"""API keys and roles: hashed storage, the role matrix on every endpoint, revocation, the keys CLI, serve's refusal."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from sqlalchemy import select
from typer.testing import CliRunner

from doorloc.app.access import AccessKeyError, FailureBudget, KeyStore, Role, role_allows
from doorloc.app.cli import app as cli_app
from doorloc.app.cli_serve import is_loopback
from doorloc.recipes.store import RecipeStore
from doorloc.recipes.tables import ApiKeyRow

CELL_FILE = str(Path(__file__).resolve().parents[2] / "fixtures" / "cell_thesis.yaml")


@pytest.fixture
def keys(store) -> KeyStore:
    return KeyStore(store.engine)


def test_a_key_is_stored_only_as_a_salted_hash(keys, store):
    k = keys.create("panel 1", Role.operator)
    assert k.secret.startswith(f"dlk_{k.key_id}_")
    with store.engine.connect() as conn:
        row = conn.execute(select(ApiKeyRow)).one()
    secret_part = k.secret[len(f"dlk_{k.key_id}_") :]  # the random part may itself hold "_"
    assert secret_part not in repr(tuple(row)) and len(row.key_hash) == 64
    assert keys.authenticate(k.secret).name == "panel 1"
    # same name twice: two different keys with different salts
    k2 = keys.create("panel 1", Role.operator)
    assert k2.secret != k.secret
    assert keys.authenticate(k.secret[:-1] + ("A" if k.secret[-1] != "A" else "B")) is None


def test_revoked_keys_are_refused_at_once_even_when_cached(keys):
    k = keys.create("scraper", Role.metrics)
    assert keys.authenticate(k.secret) is not None  # now cached
    assert keys.revoke("scraper") == [k.key_id]
    assert keys.authenticate(k.secret) is None
    assert not keys.any_active()
    with pytest.raises(AccessKeyError, match="no active key"):
        keys.revoke("scraper")
    with pytest.raises(AccessKeyError, match="key name"):
        keys.create("", Role.operator)


def test_role_matrix():
    assert role_allows(Role.engineer, Role.operator) and role_allows(Role.engineer, Role.metrics)
    assert not role_allows(Role.operator, Role.engineer) and not role_allows(Role.operator, Role.metrics)
    assert not role_allows(Role.metrics, Role.operator)


def _h(key):
    return {"X-API-Key": key.secret}


def test_endpoints_by_role(client, keys, recipe, small_png):
    op, eng, met = (
        keys.create(n, r) for n, r in (("op", Role.operator), ("eng", Role.engineer), ("prom", Role.metrics))
    )
    body = recipe.model_dump(mode="json")
    img = {"image": ("door.png", small_png, "image/png")}
    # no key, once keys exist: 401 everywhere but the probes and the operator page
    assert client.get("/v1/doors").status_code == 401
    assert client.get("/metrics").status_code == 401
    assert client.post("/v1/locate", files=img).status_code == 401
    assert client.get("/healthz").status_code == 200 and client.get("/readyz").status_code == 200
    # operator: locate and read, not write, not metrics
    assert client.post("/v1/locate", files=img, headers=_h(op)).status_code == 200
    assert client.get("/v1/doors/D-100", headers=_h(op)).status_code == 200
    assert client.get("/v1/cell", headers=_h(op)).status_code == 200
    r = client.put("/v1/doors/D-100", json=body, headers=_h(op))
    assert r.status_code == 403 and "engineer" in r.json()["detail"] and r.json()["code"] == "forbidden"
    assert client.get("/metrics", headers=_h(op)).status_code == 403
    # metrics: only /metrics
    assert client.get("/metrics", headers=_h(met)).status_code == 200
    assert client.post("/v1/locate", files=img, headers=_h(met)).status_code == 403
    # engineer: everything
    assert client.put("/v1/doors/D-100", json=body, headers=_h(eng)).status_code == 200
    assert client.get("/metrics", headers=_h(eng)).status_code == 200
    # a revoked key stops working on the next request
    keys.revoke("eng")
    assert client.put("/v1/doors/D-100", json=body, headers=_h(eng)).status_code == 401


def test_recipe_change_without_a_key_is_refused_once_keys_exist(client, keys, recipe):
    """The issue's first defect: PUT /v1/doors/ID changed a door's width with no key and got 200."""
    keys.create("eng", Role.engineer)
    wider = recipe.model_dump(mode="json") | {"width_mm": 1350}
    r = client.put("/v1/doors/D-100", json=wider)
    assert r.status_code == 401
    assert r.headers["content-type"] == "application/problem+json"


def test_legacy_single_key_is_an_engineer(make_client, recipe):
    c = make_client(api_key="s3cret-legacy")
    body = recipe.model_dump(mode="json")
    assert c.put("/v1/doors/D-100", json=body).status_code == 401
    assert c.put("/v1/doors/D-100", json=body, headers={"X-API-Key": "s3cret-legacy"}).status_code == 200
    assert c.get("/metrics", headers={"X-API-Key": "s3cret-legacy"}).status_code == 200


def test_keys_cli_creates_lists_and_revokes(tmp_path):
    db = f"sqlite:///{tmp_path / 'k.db'}"
    run = CliRunner().invoke
    r = run(cli_app, ["keys", "create", "line 2 panel", "--role", "operator", "--db", db])
    assert r.exit_code == 0, r.output
    secret = r.stdout.strip().splitlines()[0]
    assert secret.startswith("dlk_")
    r = run(cli_app, ["keys", "list", "--db", db])
    assert "line 2 panel" in r.stdout and "operator" in r.stdout and secret not in r.stdout
    r = run(cli_app, ["keys", "create", "x", "--role", "admin", "--db", db])
    assert r.exit_code == 2
    r = run(cli_app, ["keys", "revoke", "line 2 panel", "--db", db])
    assert r.exit_code == 0 and "revoked 1" in r.stdout
    assert "revoked" in run(cli_app, ["keys", "list", "--db", db]).stdout
    assert run(cli_app, ["keys", "revoke", "nobody", "--db", db]).exit_code == 2


@pytest.mark.parametrize(
    ("host", "loop"),
    [
        ("127.0.0.1", True),
        ("127.1.2.3", True),
        ("::1", True),
        ("localhost", True),
        ("0.0.0.0", False),
        ("::", False),
        ("192.168.1.5", False),
        ("doorloc.plant.example", False),
    ],
)
def test_loopback_addresses(host, loop):
    assert is_loopback(host) is loop


def test_serve_refuses_a_non_loopback_bind_without_keys(tmp_path):
    """The issue's first defect: the default (no key) service bound 0.0.0.0. It now refuses before binding."""
    env = {
        "DOORLOC_DATABASE_URL": f"sqlite:///{tmp_path / 'r.db'}",
        "PATH": "/usr/bin:/bin",
        "PYTHONPATH": str(Path(__file__).resolve().parents[2] / "src"),
    }
    p = subprocess.run(
        [sys.executable, "-m", "doorloc", "serve", "--cell", CELL_FILE, "--host", "0.0.0.0", "--port", "1"],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
    )
    assert p.returncode == 2, p.stderr
    assert "refusing to listen on 0.0.0.0 without API keys" in p.stderr and "--insecure" in p.stderr
    assert "Traceback" not in p.stderr
    # a proxy in front is no substitute for keys: the message must not offer one
    assert "reverse proxy does not replace them" in p.stderr and "127.0.0.1 behind" not in p.stderr


def test_serve_open_only_on_loopback(tmp_path):
    env = {
        "DOORLOC_DATABASE_URL": f"sqlite:///{tmp_path / 'r.db'}",
        "PATH": "/usr/bin:/bin",
        "PYTHONPATH": str(Path(__file__).resolve().parents[2] / "src"),
    }
    base = [sys.executable, "-m", "doorloc", "serve", "--cell", CELL_FILE, "--port", "1", "--create-database"]
    p = subprocess.run(
        [*base, "--host", "192.168.1.5", "--open"], capture_output=True, text=True, timeout=120, env=env
    )
    assert p.returncode == 2 and "without API keys" in p.stderr, p.stderr
    p = subprocess.run([*base, "--host", "127.0.0.1"], capture_output=True, text=True, timeout=120, env=env)
    assert p.returncode == 2 and "--open" in p.stderr and "doorloc keys create" in p.stderr, p.stderr


def test_an_unknown_key_id_costs_a_derivation_like_a_known_one(monkeypatch):
    """Issue defect: an unknown id answered in 3.4 ms, a known one with a wrong secret in 67 ms."""
    import hashlib

    keys = KeyStore(RecipeStore("sqlite://").engine)
    known = keys.create("panel", Role.operator)
    calls = []
    real = hashlib.scrypt

    def counting(*a, **k):
        calls.append(1)
        return real(*a, **k)

    monkeypatch.setattr(hashlib, "scrypt", counting)
    assert keys.authenticate(known.secret[:-4] + "AAAA") is None
    assert keys.authenticate("dlk_000000000000_" + "A" * 43) is None
    assert len(calls) == 2


def test_failure_budget_counts_a_sliding_minute():
    now = [0.0]
    b = FailureBudget(3, clock=lambda: now[0])
    for _ in range(3):
        assert b.retry_after("a") is None
        b.record("a")
    assert b.retry_after("a") == 61 and b.retry_after("b") is None
    now[0] = 30.0
    assert 1 <= b.retry_after("a") <= 31
    now[0] = 60.5
    assert b.retry_after("a") is None


def test_a_verified_key_still_passes_when_its_address_is_over_budget(make_client, keys):
    """Guessing from one address (a NAT, a proxy) must not lock out the valid keys used from it."""
    c = make_client(auth_failures_per_minute=2)
    k = keys.create("panel", Role.operator)
    assert c.get("/v1/doors", headers=_h(k)).status_code == 200  # verified once
    wrong = {"X-API-Key": "dlk_000000000000_" + "A" * 43}
    assert [c.get("/v1/doors", headers=wrong).status_code for _ in range(3)] == [401, 401, 429]
    assert c.get("/v1/doors", headers=_h(k)).status_code == 200


def test_a_key_not_verified_yet_is_tried_a_few_times_a_minute_from_an_address_over_budget(make_client, keys):
    """Behind one NAT, a machine that keeps sending a stale key must not lock out for the whole minute another
    machine's valid key that this worker has not verified yet (after a restart): each key is tried once a
    minute, a few keys a minute (each trial a derivation, as for a key within the budget)."""
    c = make_client(auth_failures_per_minute=2)
    stale = {"X-API-Key": "dlk_000000000000_" + "A" * 43}
    assert [c.get("/v1/doors", headers=stale).status_code for _ in range(6)] == [401, 401] + [429] * 4
    panel = keys.create("panel", Role.operator)  # never used
    assert c.get("/v1/doors", headers=_h(panel)).status_code == 200  # its trial (the stale key had one)
    assert c.get("/v1/doors", headers=_h(panel)).status_code == 200  # verified now
    guess = {"X-API-Key": "dlk_000000000000_" + "B" * 43}
    assert c.get("/v1/doors", headers=guess).status_code == 429  # the third trial, failed
    late = keys.create("late panel", Role.operator)
    assert c.get("/v1/doors", headers=_h(late)).status_code == 429  # no trial left this minute


def test_failure_budget_trials_each_key_once_a_minute_and_a_few_keys_a_minute():
    now = [0.0]
    b = FailureBudget(1, clock=lambda: now[0])
    assert b.may_try("a", "k1") and not b.may_try("a", "k1")  # the same key again: not this minute
    assert b.may_try("a", "k2") and b.may_try("a", "k3") and not b.may_try("a", "k4")
    assert b.may_try("b", "k1")  # per address
    now[0] = 60.5
    assert b.may_try("a", "k1")


def test_a_refused_key_is_answered_after_the_refusal_delay_and_only_a_quarter_of_connections_wait(
    make_client, keys, refusal_waits
):
    """A keyless or wrong-key request waits ``auth_refusal_delay_s`` before its 401/429 (a flood of them is
    then answered a few times a second per connection), a valid key never waits, and once a quarter of
    ``max_connections`` are waiting further refusals are answered at once, so refusals cannot hold every
    connection."""
    waits = refusal_waits
    c = make_client(auth_refusal_delay_s=0.75, max_connections=8)
    k = keys.create("panel", Role.operator)
    assert c.get("/v1/doors", headers=_h(k)).status_code == 200
    assert waits == []
    assert c.get("/v1/doors").status_code == 401
    assert c.get("/v1/doors", headers={"X-API-Key": "dlk_000000000000_" + "A" * 43}).status_code == 401
    assert waits == [0.75, 0.75]
    state = c.app.state.service
    state.refusals_waiting = 2  # a quarter of 8 connections already waiting
    assert c.get("/v1/doors").status_code == 401
    assert waits == [0.75, 0.75]
    state.refusals_waiting = 0
    assert make_client(auth_refusal_delay_s=0).get("/v1/doors").status_code == 401
    assert waits == [0.75, 0.75]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="per-thread CPU priority is Linux's")
def test_key_derivations_run_below_the_serving_threads_cpu_priority(store, monkeypatch):
    """A flood of wrong keys costs a scrypt derivation each; they run some nice levels below the thread that
    asks (the service's), so its other answers keep the CPU meanwhile."""
    import hashlib
    import os
    import threading

    def nice_here() -> int:
        return os.getpriority(os.PRIO_PROCESS, threading.get_native_id())

    base = nice_here()
    if base > 16:
        pytest.skip(f"this process already runs at nice {base}")
    seen: list[int] = []
    real_scrypt = hashlib.scrypt

    def scrypt_noting_priority(*a, **k):
        seen.append(nice_here())
        return real_scrypt(*a, **k)

    monkeypatch.setattr(hashlib, "scrypt", scrypt_noting_priority)
    unknown = "dlk_000000000000_" + "A" * 43
    assert KeyStore(store.engine, derivation_nice=3).authenticate(unknown) is None
    assert KeyStore(store.engine).authenticate(unknown) is None
    assert seen == [base + 3, base]
    assert nice_here() == base  # the asking thread keeps its priority
