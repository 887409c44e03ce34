"""The typer app the commands register on, and its root options (``--version``)."""

from __future__ import annotations

from typing import Annotated

import typer

from skymule.aadm.cli import aadm_app

app: typer.Typer = typer.Typer(
    pretty_exceptions_enable=False,
    no_args_is_help=True,
    rich_markup_mode=None,
    help="UAV data-mule missions: simulate, replay, compare and plot.",
)
app.add_typer(aadm_app, name="aadm")


def _version(value: bool) -> None:
    if value:
        from importlib.metadata import PackageNotFoundError, version

        try:
            number = version("skymule")
        except PackageNotFoundError:  # run from a source tree without installing
            number = "unknown"
        print(f"skymule {number}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool,
        typer.Option("--version", callback=_version, is_eager=True, help="Print the version."),
    ] = False,
) -> None:
    """UAV data-mule missions: simulate, replay, compare and plot."""
