"""How the command line reports an expected failure: one sentence on stderr, a documented exit code."""

from __future__ import annotations

import typer

#: exit codes of the `doorloc` command line
EXIT_OK = 0
EXIT_REFUSED = 1  # the command ran, but the answer is a refusal (e.g. locate with ok=false)
EXIT_USAGE = 2  # bad arguments or unreadable/invalid input files
EXIT_FAILED = 3  # the work could not be done (e.g. too few usable calibration views)


def fail(message: str, code: int = EXIT_USAGE) -> typer.Exit:
    """Print ``doorloc: error: message`` on stderr and return the Exit to raise."""
    typer.echo(f"doorloc: error: {message}", err=True)
    return typer.Exit(code)
