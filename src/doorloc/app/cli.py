"""The `doorloc` console script: one Typer app, each area registering its own subcommands.

Every command turns expected failures (bad files, bad arguments) into one sentence on stderr and a
non-zero exit code; a stack trace reaches the user only with ``DOORLOC_DEBUG=1``.
"""

from __future__ import annotations

import os
import sys
from typing import Annotated

import typer

from doorloc import __version__
from doorloc.app import (
    cli_calibrate,
    cli_cell,
    cli_keys,
    cli_light,
    cli_locate,
    cli_modelcheck,
    cli_reach,
    cli_recipes,
    cli_render,
    cli_serve,
)

app = typer.Typer(
    name="doorloc",
    help="Locate a wooden door in a milling cell and turn its recipe into robot targets.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
)


def _print_version(value: bool) -> None:
    if value:
        typer.echo(f"doorloc {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    show_version: Annotated[
        bool,
        typer.Option(
            "--version", is_eager=True, callback=_print_version, help="Print the doorloc version and exit."
        ),
    ] = False,
) -> None:
    """Locate a wooden door in a milling cell and turn its recipe into robot targets."""


for _module in (
    cli_calibrate,
    cli_cell,
    cli_light,
    cli_locate,
    cli_render,
    cli_recipes,
    cli_reach,
    cli_serve,
    cli_keys,
    cli_modelcheck,
):
    _module.register(app)


@app.command("version", hidden=True)  # kept for scripts; `doorloc --version` is the documented one
def version() -> None:
    """Print the doorloc version."""
    typer.echo(__version__)


def quiet_opencv() -> None:
    """Keep OpenCV's own ``[ WARN:...]`` lines off the terminal: where an image cannot be read doorloc says so
    itself, in a sentence (OPENCV_LOG_LEVEL, when set, wins). Set before OpenCV loads; workers inherit it."""
    os.environ.setdefault("OPENCV_LOG_LEVEL", "FATAL")
    if "cv2" in sys.modules:
        cv2 = sys.modules["cv2"]
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_FATAL)


def main() -> None:
    """Console-script entry point."""
    quiet_opencv()
    try:
        app()
    except (ValueError, OSError) as e:  # a last line of defence; commands report their own errors first
        if os.environ.get("DOORLOC_DEBUG"):
            raise
        typer.echo(f"doorloc: error: {e}", err=True)
        sys.exit(2)
