"""`doorloc check-model`: what the cell model gets wrong on a measured data set, its cause, the extended cell.

A few lines over :func:`doorloc.modelcheck.check_model`. Exit codes: 0 done (whatever it found), 2 bad input
(unreadable cell file, no truth.csv, images missing, too few images).

With ``--boards IMAGES_DIR`` it checks the camera's image model on photographs of a chessboard instead
(:func:`doorloc.photometric.report.board_model_check`, :func:`check_boards_cmd`).
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
        out: Annotated[
            Path, typer.Option("--out", help="REPORT_DIR: report.json, report.md, plots, extended cell")
        ],
        dataset: Annotated[
            Path | None, typer.Argument(help="folder with the images and truth.csv (reference poses)")
        ] = None,
        cell_file: Annotated[
            Path | None, typer.Option("--cell", help="the cell file to check (cell.yaml)")
        ] = None,
        seed: Annotated[int, typer.Option(help="seed of the held-out draw")] = 0,
        as_json: Annotated[
            bool, typer.Option("--json", help="print report.json to stdout instead of the summary")
        ] = False,
        boards: Annotated[
            Path | None,
            typer.Option("--boards", help="IMAGES_DIR: check the camera on chessboard photographs"),
        ] = None,
        pattern: Annotated[str, typer.Option(help="with --boards: inner corners COLSxROWS (e.g. 9x6)")] = "",
        square: Annotated[float, typer.Option(help="with --boards: square side, mm")] = 0.0,
        calibration: Annotated[
            Path | None,
            typer.Option(help="with --boards: the camera's calibration file (else calibrated here)"),
        ] = None,
    ) -> None:
        """Locate every image, name the cause of the errors from the catalogue, fit it, write the extended
        cell and the held-out gain (exit 0 done, 2 bad input). With --boards: the same for the camera's
        image model on chessboard photographs (report.json, report.md, plots, extended calibration)."""
        if boards is not None:
            return check_boards_cmd(boards, pattern, square, calibration, out)
        if dataset is None or cell_file is None:
            raise fail("give DATASET and --cell, or --boards IMAGES_DIR --pattern COLSxROWS --square MM")
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


def check_boards_cmd(boards: Path, pattern: str, square: float, calibration: Path | None, out: Path) -> None:
    """``check-model --boards``: a few lines over :func:`doorloc.photometric.report.board_model_check`."""
    from doorloc.app.cli_calibrate import parse_pattern
    from doorloc.photometric.check import BoardCheckError
    from doorloc.photometric.report import board_model_check

    try:
        check, extended = board_model_check(
            boards,
            parse_pattern(pattern),
            square,
            calibration,
            out,
            progress=lambda m: typer.echo(m, err=True),
        )
    except (BoardCheckError, ValueError) as e:
        raise fail(str(e), EXIT_USAGE) from None
    except OSError as e:
        raise fail(f"cannot write the report to {out}: {e.strerror or e}", EXIT_USAGE) from None
    off = check.heldout_rms("offset")
    typer.echo(f"causes: {', '.join(check.causes) if check.causes else 'none (no significant effect)'}")
    typer.echo(
        f"held-out edge offset RMS ({len(check.photographs)} photographs) {off['before']:.3f} -> {off['after']:.3f} px"
    )
    typer.echo(f"wrote {out / 'report.json'}, {out / 'report.md'} and {extended}")
