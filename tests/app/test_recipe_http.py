"""Recipe history over HTTP: versions with the key's name, results naming the recipe version, retire, paging."""

from __future__ import annotations

from doorloc.app.access import KeyStore, Role


def test_changes_are_versions_recorded_with_the_keys_name(client, store, recipe, small_png):
    eng = KeyStore(store.engine).create("j.smith", Role.engineer)
    h = {"X-API-Key": eng.secret}
    conftest_version = store.get_versioned("D-100")[1]
    body = recipe.model_dump(mode="json") | {"width_mm": 1000}
    r = client.put("/v1/doors/D-100", json=body, headers=h)
    assert r.status_code == 200 and r.headers["x-recipe-version"] == str(conftest_version + 1)
    r = client.get("/v1/doors/D-100/history", headers=h)
    assert r.status_code == 200
    last = r.json()["versions"][-1]
    assert last["changed_by"] == "j.smith" and last["action"] == "updated"
    assert last["changes"] == [{"field": "width_mm", "old": 900.0, "new": 1000.0}]
    # the result names the recipe version it used, beside the software and model hashes
    r = client.post(
        "/v1/locate", files={"image": ("d.png", small_png, "image/png")}, data={"door_id": "D-100"}, headers=h
    )
    prov = r.json()["provenance"]
    assert prov["recipe_version"] == conftest_version + 1
    assert prov["version"] and prov["cell_sha256"] and prov["calibration_sha256"]
    # by size: no recipe, no recipe version
    r = client.post("/v1/locate", files={"image": ("d.png", small_png, "image/png")}, headers=h)
    assert r.json()["provenance"]["recipe_version"] is None


def test_retire_then_locate_by_that_door_is_refused(client, small_png):
    assert client.delete("/v1/doors/D-100").status_code == 204
    assert client.delete("/v1/doors/D-100").status_code == 404
    r = client.post(
        "/v1/locate", files={"image": ("d.png", small_png, "image/png")}, data={"door_id": "D-100"}
    )
    assert r.status_code == 422 and r.json()["code"] == "unknown_door"
    assert [v["action"] for v in client.get("/v1/doors/D-100/history").json()["versions"]][-1] == "deleted"
    assert client.get("/v1/doors/NEVER/history").status_code == 404


def test_door_list_is_paged(client, store, recipe):
    store.put_many([recipe.model_copy(update={"door_id": f"P-{k:03d}"}) for k in range(25)])
    r = client.get("/v1/doors", params={"limit": 10})
    page = r.json()
    assert page["total"] == 26 and len(page["door_ids"]) == 10 and page["next_offset"] == 10
    last = client.get("/v1/doors", params={"limit": 10, "offset": 20}).json()
    assert len(last["door_ids"]) == 6 and last["next_offset"] is None
    assert client.get("/v1/doors", params={"limit": 100000}).status_code == 422
