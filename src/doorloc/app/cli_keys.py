"""`doorloc keys create|list|revoke`: the HTTP service's API keys, stored hashed in the recipe database."""

from __future__ import annotations

import json

import typer

from doorloc.app.access import Role
from doorloc.app.cli_common import DbOption, open_store
from doorloc.app.errors import EXIT_USAGE, fail

keys_app = typer.Typer(
    name="keys",
    help="API keys of the HTTP service (roles operator, engineer, metrics).",
    no_args_is_help=True,
)


@keys_app.command("create")
def create_cmd(
    name: str = typer.Argument(..., help="who or what holds the key (a person, a panel PC, the scraper)"),
    role: Role = typer.Option(
        ..., "--role", help="operator (locate, read), engineer (also change recipes), metrics"
    ),
    db: DbOption = None,
) -> None:
    """Create a key and print it once (only its hash is stored: keep the printed key safe)."""
    from doorloc.app.access import AccessKeyError, KeyStore

    with open_store(db) as store:
        try:
            created = KeyStore(store.engine).create(name, role)
        except AccessKeyError as e:
            raise fail(str(e), EXIT_USAGE) from None
    typer.echo(created.secret)
    typer.echo(
        f"created {created.role} key '{created.name}' (id {created.key_id}); it is shown only this once",
        err=True,
    )


@keys_app.command("list")
def list_cmd(
    db: DbOption = None,
    as_json: bool = typer.Option(False, "--json", help="print JSON instead of a table"),
) -> None:
    """List the keys (never their secrets), revoked ones too."""
    from doorloc.app.access import KeyStore

    with open_store(db) as store:
        keys = KeyStore(store.engine).list()
    if as_json:
        typer.echo(
            json.dumps(
                [
                    {
                        "key_id": k.key_id,
                        "name": k.name,
                        "role": k.role.value,
                        "created_at": k.created_at.isoformat() if k.created_at else None,
                        "revoked_at": k.revoked_at.isoformat() if k.revoked_at else None,
                    }
                    for k in keys
                ],
                indent=2,
            )
        )
        return
    typer.echo(f"{'key_id':<14} {'role':<9} {'state':<8} name")
    for k in keys:
        typer.echo(f"{k.key_id:<14} {k.role.value:<9} {'revoked' if k.revoked_at else 'active':<8} {k.name}")
    typer.echo(f"{sum(k.revoked_at is None for k in keys)} active key(s)", err=True)


@keys_app.command("revoke")
def revoke_cmd(
    name: str = typer.Argument(..., help="the key's name or key id"),
    db: DbOption = None,
) -> None:
    """Revoke a key (by name: every active key of that name); the service refuses it from the next request."""
    from doorloc.app.access import AccessKeyError, KeyStore

    with open_store(db) as store:
        try:
            ids = KeyStore(store.engine).revoke(name)
        except AccessKeyError as e:
            raise fail(str(e), EXIT_USAGE) from None
    typer.echo(f"revoked {len(ids)} key(s): {', '.join(ids)}")


def register(app: typer.Typer) -> None:
    """Add this area's subcommands to the root app."""
    app.add_typer(keys_app, name="keys")
