"""`doorloc serve` (the HTTP service) and `doorloc batch` (a folder of images to a JSONL file)."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from doorloc.app.access import is_loopback
from doorloc.app.cli_common import DbAliasOption, DbOption, load_cell_or_fail, recipe_lookup
from doorloc.app.errors import EXIT_FAILED, EXIT_OK, EXIT_REFUSED, fail

if TYPE_CHECKING:
    from doorloc.app.batch import BatchJob, BatchSummary
    from doorloc.cell import Cell

__all__ = ["register", "is_loopback"]


def serve_cmd(
    cell: Annotated[Path | None, typer.Option(help="cell file (cell.yaml); default: $DOORLOC_CELL")] = None,
    host: Annotated[
        str, typer.Option(help="address to listen on (0.0.0.0 for every interface)")
    ] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="TCP port")] = 8000,
    workers: Annotated[
        int, typer.Option(min=1, help="worker processes (each answers requests in parallel)")
    ] = 1,
    db: DbOption = None,
    database_url: DbAliasOption = None,
    log_level: Annotated[str, typer.Option(help="debug, info, warning or error")] = "info",
    open_access: Annotated[
        bool,
        typer.Option(
            "--open",
            envvar="DOORLOC_OPEN_ACCESS",
            help="answer without API keys while none exists (every caller an engineer): loopback "
            "addresses only, for development; /readyz says 'access: open'",
        ),
    ] = False,
    create_database: Annotated[
        bool,
        typer.Option(
            "--create-database",
            envvar="DOORLOC_CREATE_DATABASE",
            help="create the recipe database if its SQLite file does not exist (else an error)",
        ),
    ] = False,
    ssl_certfile: Annotated[
        Path | None, typer.Option(help="serve HTTPS with this PEM certificate (chain)")
    ] = None,
    ssl_keyfile: Annotated[Path | None, typer.Option(help="private key of --ssl-certfile (PEM)")] = None,
) -> None:
    """Run the HTTP service (POST /v1/locate, operator page at /, OpenAPI at /docs).

    Every request needs an API key (doorloc keys create); only --open on a loopback address answers
    without one, while no key exists.
    """
    cell_path = _checked_cell(cell)
    _check_access(host, db or database_url, open_access, create_database)
    if (ssl_certfile is None) != (ssl_keyfile is None):
        raise fail("give both --ssl-certfile and --ssl-keyfile for HTTPS, or neither")
    for f in (ssl_certfile, ssl_keyfile):
        if f is not None and not f.is_file():
            raise fail(f"no such file: {f}")
    # The workers are separate processes that build the app from the environment (create_app_from_env).
    os.environ["DOORLOC_CELL"] = str(Path(cell_path).resolve())
    os.environ["DOORLOC_LOG_LEVEL"] = log_level.upper()
    from doorloc.app.settings import default_locate_concurrency

    os.environ.setdefault("DOORLOC_LOCATE_CONCURRENCY", str(default_locate_concurrency(workers)))
    _run_uvicorn(host, port, workers, log_level, ssl_certfile, ssl_keyfile, _checked_settings())


#: ``doorloc batch --device``
DeviceOption = Annotated[
    str | None,
    typer.Option(
        help="cpu, cuda or auto: locate batches of frames on torch (the doorloc torch extra); default: one frame at a time"
    ),
]
#: ``doorloc batch --stated-response``
StatedResponseOption = Annotated[
    bool,
    typer.Option(
        "--stated-response",
        help="locate with the cell's stated camera response as it is; by default, where the cell states it "
        "without a measurement, it is measured first from up to 8 of the doors with rounded arrises",
    ),
]


def batch_cmd(
    folder: Annotated[
        Path,
        typer.Argument(
            help="folder of images (searched recursively; by content or name: other files are skipped with a count)"
        ),
    ],
    cell: Annotated[Path, typer.Option(help="cell file (cell.yaml)")],
    out: Annotated[Path, typer.Option(help="results file, one JSON line per image")],
    manifest: Annotated[
        Path | None,
        typer.Option(
            help="CSV: image and door_id, or width_mm,thickness_mm[,height_mm]; default: every image, the cell's door"
        ),
    ] = None,
    resume: Annotated[
        bool, typer.Option("--resume", help="continue an interrupted job: skip images already in --out")
    ] = False,
    workers: Annotated[int, typer.Option(min=1, help="parallel worker processes")] = max(
        1, (os.cpu_count() or 2) - 1
    ),
    backend: Annotated[
        str, typer.Option(help="local (worker processes) or ray (Ray Data: the doorloc ray extra)")
    ] = "local",
    ray_address: Annotated[
        str | None, typer.Option(help="Ray cluster address (ray backend); default: a local instance")
    ] = None,
    db: DbOption = None,
    database_url: DbAliasOption = None,
    device: DeviceOption = None,
    batch_size: Annotated[int, typer.Option(min=1, help="frames per batch with --device")] = 32,
    stated_response: StatedResponseOption = False,
) -> None:
    """Locate the door in every image of a folder; append one result line per image to --out.

    Where the cell states its camera's response without a measurement and at least five doors have rounded
    arrises, the response is measured from them first (a minute or two) and every door located with it.
    Exit code 0 when every image was answered, 1 when some were refused or failed, 2 for bad arguments.
    """
    from doorloc.app import batch as batch_mod

    options = batch_mod.BatchOptions(backend, workers, ray_address, device, batch_size)
    the_cell = load_cell_or_fail(cell)
    try:
        options.check()
        lookup = recipe_lookup(db or database_url) if manifest else None
        job = batch_mod.open_job(
            folder, the_cell, out, manifest=manifest, recipe_lookup=lookup, resume=resume
        )
    except (batch_mod.BatchSetupError, OSError) as e:
        raise fail(str(e)) from None
    if job.not_images:
        typer.echo(f"doorloc: {batch_mod.not_images_sentence(job.not_images)}", err=True)
    if not stated_response:
        the_cell = _response_measured(job, the_cell)
    summary = _run_or_fail(job, options.backend_for(the_cell), out)
    typer.echo(f"{out}: {summary.text()}", err=True)
    raise typer.Exit(EXIT_OK if summary.answered == summary.total else EXIT_REFUSED)


def register(app: typer.Typer) -> None:
    """Add `doorloc serve` and `doorloc batch` to the root app."""
    app.command("serve")(serve_cmd)
    app.command("batch")(batch_cmd)


def _response_measured(job: BatchJob, cell: Cell) -> Cell:
    """The cell the job's doors are located with (:func:`doorloc.app.batch.batch_response`: the camera's response
    measured from the job's rounded doors where the cell only states it), its lines and sentence told."""
    from doorloc.app.batch import batch_response

    said = batch_response(job.items, cell, progress=lambda line: typer.echo(line, err=True))
    if said.sentence:
        typer.echo(f"doorloc: {said.sentence}", err=True)
    return said.cell


def _run_or_fail(job: BatchJob, backend: Callable, out: Path) -> BatchSummary:
    """Run the job with a progress bar; exit 2 for a backend that cannot start, 3 for a results file that
    cannot be written. Returns the summary."""
    from doorloc.app.batch import BatchSetupError

    with job.log:
        try:
            return _run_with_progress(job.items, job.log, backend)
        except BatchSetupError as e:
            raise fail(str(e)) from None
        except OSError as e:
            raise fail(f"cannot write {out}: {e.strerror or e}", EXIT_FAILED) from None


def _checked_cell(cell: Path | None) -> str:
    """The cell file's path, loaded once here so a bad one fails with a sentence rather than in every worker."""
    from doorloc.cell import CellFileError, load_cell

    cell_path = str(cell) if cell is not None else os.environ.get("DOORLOC_CELL")
    if not cell_path:
        raise fail("give the cell file: doorloc serve --cell cell.yaml (or set DOORLOC_CELL)")
    try:
        load_cell(cell_path)
    except CellFileError as e:
        raise fail(str(e)) from None
    return cell_path


def _check_access(host: str, database_url: str | None, open_access: bool, create_database: bool) -> None:
    """Fail closed before any worker starts: a database that exists (unless created on purpose), keys or
    an explicit --open on loopback, and the Host names the service answers to."""
    if open_access:
        os.environ["DOORLOC_OPEN_ACCESS"] = "true"
    if create_database:
        os.environ["DOORLOC_CREATE_DATABASE"] = "true"
    missing = _missing_database(database_url, create_database)
    # a database that does not exist holds no key: on a public address that is the first thing to say
    _check_bind(host, open_access, missing is None and _has_keys())
    if missing is not None:
        raise fail(missing)
    _default_allowed_hosts(host)


def _missing_database(database_url: str | None, create: bool) -> str | None:
    """Why the recipe database cannot be used (it does not exist and ``create`` is not given), or None.

    A mistyped SQLite URL must not start a service on a fresh database without recipes or keys.
    """
    if database_url:
        os.environ["DOORLOC_DATABASE_URL"] = database_url
    from doorloc.app.settings import missing_database
    from doorloc.recipes.store import database_url as resolve_url

    return None if create else missing_database(resolve_url(None))


def _has_keys() -> bool:
    """Migrate the recipe database once (so N workers do not race to) and say whether any API key exists."""
    from doorloc.recipes.store import database_url as resolve_url

    url = resolve_url(None)
    try:
        from doorloc.app.access import KeyStore
        from doorloc.recipes.store import RecipeStore

        with RecipeStore(url) as store:
            return KeyStore(store.engine).any_active() or bool(os.environ.get("DOORLOC_API_KEY"))
    except Exception as e:  # noqa: BLE001 - any database failure is reported as one sentence
        raise fail(f"cannot open the recipe database: {e}") from None


def _check_bind(host: str, open_access: bool, has_keys: bool) -> None:
    """Without API keys, refuse to start unless --open on a loopback address (then say so)."""
    if has_keys:
        if open_access:
            typer.echo(
                "doorloc: API keys exist, so --open has no effect: every request needs a key", err=True
            )
        return
    if not is_loopback(host):
        raise fail(
            f"refusing to listen on {host} without API keys: anyone who reaches it could change the door "
            "recipes that drive the robot. Create keys first (doorloc keys create --role engineer NAME); "
            "a reverse proxy does not replace them, and there is no --insecure override"
        )
    if not open_access:
        raise fail(
            "no API key exists, so every request would be refused: create one (doorloc keys create --role "
            "engineer NAME), or pass --open to answer without keys on this loopback address (development)"
        )
    typer.echo(
        f"doorloc: warning: --open: {host} answers without API keys (every caller may change door recipes) "
        "until the first key is created",
        err=True,
    )


def _default_allowed_hosts(host: str) -> None:
    """DOORLOC_ALLOWED_HOSTS, when not set: the loopback names and the address listened on."""
    if os.environ.get("DOORLOC_ALLOWED_HOSTS"):
        return
    if host in ("0.0.0.0", "::", ""):
        raise fail(
            f"listening on every interface ({host or 'all'}): set DOORLOC_ALLOWED_HOSTS to the names and "
            "addresses clients use to reach this service (e.g. doorloc.plant.example,10.0.4.7), or '*'"
        )
    names = ["localhost", "127.0.0.1", "::1"]
    if host not in names:
        names.append(host)
    os.environ["DOORLOC_ALLOWED_HOSTS"] = ",".join(names)


def _checked_settings():
    """The service's settings from DOORLOC_*, validated once here (the workers read the same)."""
    from pydantic import ValidationError

    from doorloc.app.settings import ServiceSettings

    try:
        return ServiceSettings()
    except ValidationError as e:
        raise fail(f"invalid DOORLOC_* setting: {e}") from None


def _run_uvicorn(
    host: str,
    port: int,
    workers: int,
    log_level: str,
    ssl_certfile: Path | None,
    ssl_keyfile: Path | None,
    settings,  # noqa: ANN001 - doorloc.app.settings.ServiceSettings
) -> None:
    """Run uvicorn with the server's own limits; /metrics adds up every worker through a prometheus
    multiprocess folder made here and removed at exit, SIGTERM included."""
    import shutil
    import signal
    import tempfile

    import uvicorn

    from doorloc.app.logs import uvicorn_log_config

    own_metrics_dir = "PROMETHEUS_MULTIPROC_DIR" not in os.environ
    if own_metrics_dir:
        os.environ["PROMETHEUS_MULTIPROC_DIR"] = tempfile.mkdtemp(prefix="doorloc-metrics-")

    def exit_on_signal(_signum: int, _frame: object) -> None:
        # a requested stop after uvicorn's graceful shutdown is a success, as it is with several workers
        raise SystemExit(0)

    # uvicorn handles SIGTERM itself while it runs, then restores the handler it found and raises the signal
    # again: with the default handler that would end the process before the finally below removes the folder
    previous = signal.signal(signal.SIGTERM, exit_on_signal)
    try:
        uvicorn.run(
            "doorloc.app.http:create_app_from_env",
            factory=True,
            host=host,
            port=port,
            workers=workers,
            log_level=log_level.lower(),
            access_log=False,  # the service logs every request itself, as JSON with its request id
            log_config=uvicorn_log_config(log_level),  # uvicorn's own lines as JSON too
            ssl_certfile=str(ssl_certfile) if ssl_certfile else None,
            ssl_keyfile=str(ssl_keyfile) if ssl_keyfile else None,
            http=_http_protocol(),
            timeout_keep_alive=max(1, round(settings.keep_alive_s)),
            limit_concurrency=settings.max_connections,
            h11_max_incomplete_event_size=settings.max_header_bytes,
            # X-Forwarded-For / -Proto believed only from the configured proxies (uvicorn's default trusts 127.0.0.1)
            proxy_headers=bool(settings.trusted_proxies),
            forwarded_allow_ips=",".join(settings.trusted_proxies) or None,
        )
    finally:
        signal.signal(signal.SIGTERM, previous)
        if own_metrics_dir:
            shutil.rmtree(os.environ.pop("PROMETHEUS_MULTIPROC_DIR"), ignore_errors=True)


def _http_protocol() -> str:
    """uvicorn's HTTP protocol: the httptools one with problem+json 400s when httptools is installed."""
    import importlib.util

    return "doorloc.app.http.protocol:ProblemJsonHTTP" if importlib.util.find_spec("httptools") else "auto"


def _run_with_progress(items, log, run_backend):
    """Run the batch job with a progress bar on stderr (images done, rate, ETA); returns its summary."""
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    from doorloc.app import batch as batch_mod

    todo = sum(1 for it in items if it.image not in log.done)
    columns = (
        TextColumn("[bold]locating"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[rate]}"),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
    )
    with Progress(*columns, console=Console(stderr=True), transient=False) as progress:
        task = progress.add_task("locate", total=todo, rate="")

        def advance(_record) -> None:
            progress.advance(task)
            speed = progress.tasks[0].speed
            progress.update(task, rate=f"{speed:.2f} img/s" if speed else "")

        return batch_mod.run_job(items, log, run_backend, advance)
