"""`doorloc check-model`: what the cell model gets wrong on a measured data set, its cause, the extended cell.

A few lines over :func:`doorloc.modelcheck.check_model`. Exit codes: 0 done (whatever it found), 2 bad input
(unreadable cell file, no truth.csv, images missing, too few images).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from doorloc.app.errors import EXIT_USAGE, fail


def register(app: typer.Typer) -> None:
    """Add this area's subcommands to the root app."""

    @app.command("check-model")
    def check_model_cmd(
        dataset: Annotated[
            Path, typer.Argument(help="folder with the images and truth.csv (reference poses)")
        ],
        cell_file: Annotated[Path, typer.Option("--cell", help="the cell file to check (cell.yaml)")],
        out: Annotated[
            Path, typer.Option("--out", help="REPORT_DIR: report.json, report.md, plots, extended cell")
        ],
        seed: Annotated[int, typer.Option(help="seed of the held-out draw")] = 0,
        as_json: Annotated[
            bool, typer.Option("--json", help="print report.json to stdout instead of the summary")
        ] = False,
    ) -> None:
        """Locate every image, name the cause of the errors from the catalogue, fit it, write the extended
        cell and the held-out gain (exit 0 done, 2 bad input)."""
        from doorloc.cell import CellFileError, load_cell
        from doorloc.modelcheck import CheckOptions, DatasetError, check_model

        try:
            cell = load_cell(cell_file)
        except CellFileError as e:
            raise fail(str(e), EXIT_USAGE) from None
        if out.exists() and not out.is_dir():
            raise fail(f"{out} exists and is not a folder; give a folder for the report")
        try:
            rep = check_model(
                dataset,
                cell,
                out,
                options=CheckOptions(seed=seed),
                progress=lambda m: typer.echo(m, err=True),
            )
        except DatasetError as e:
            raise fail(str(e), EXIT_USAGE) from None
        except OSError as e:
            raise fail(f"cannot write the report to {out}: {e.strerror or e}", EXIT_USAGE) from None
        if as_json:
            typer.echo((out / "report.json").read_text(encoding="utf-8"))
            return
        v = rep.verdict
        typer.echo(f"{v['status']}: {v['headline']}")
        typer.echo(f"action: {v['action']}")
        typer.echo(f"report: {out / 'report.md'} (and report.json, the plots, {rep.extended_cell})")
