"""`doorloc serve --ssl-certfile/--ssl-keyfile`: HTTPS straight from the service (docs/deploy.md)."""

from __future__ import annotations

import shutil
import ssl
import subprocess

import httpx
import pytest

pytestmark = pytest.mark.skipif(shutil.which("openssl") is None, reason="needs the openssl command")


def test_serve_answers_over_tls_with_a_key(tmp_path, start_serve):
    cert, key = tmp_path / "cert.pem", tmp_path / "key.pem"
    subprocess.run(
        [
            "openssl",
            "req",
            "-x509",
            "-newkey",
            "rsa:2048",
            "-nodes",
            "-keyout",
            str(key),
            "-out",
            str(cert),
            "-days",
            "1",
            "-subj",
            "/CN=127.0.0.1",
            "-addext",
            "subjectAltName=IP:127.0.0.1",
        ],
        check=True,
        capture_output=True,
        timeout=60,
    )
    from doorloc.app.access import KeyStore, Role
    from doorloc.recipes.store import RecipeStore

    with RecipeStore(f"sqlite:///{tmp_path / 'recipes.db'}") as store:
        secret = KeyStore(store.engine).create("panel", Role.operator).secret
    ctx = ssl.create_default_context(cafile=str(cert))
    base, _ = start_serve(
        tmp_path, "--ssl-certfile", str(cert), "--ssl-keyfile", str(key), scheme="https", verify=ctx
    )
    assert base.startswith("https://")
    assert httpx.get(base + "/v1/doors", verify=ctx, timeout=10).status_code == 401
    r = httpx.get(base + "/v1/doors", verify=ctx, headers={"X-API-Key": secret}, timeout=10)
    assert r.status_code == 200
    with pytest.raises(httpx.TransportError):  # plain HTTP is not answered on the TLS port
        httpx.get(base.replace("https://", "http://") + "/healthz", timeout=5)
