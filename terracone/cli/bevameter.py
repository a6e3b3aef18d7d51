"""Bevameter tests: ``fit-plates`` and ``fit-shear``."""

from __future__ import annotations

import click

from terracone.cli.common import UNITS, emit_json, shared
from terracone.report.text import plate_fit_text, shear_fit_text

#: --units, --save-as, --library and --json of both commands.
fit_output_options = shared(
    click.option("--units", type=UNITS, default="si", show_default=True),
    click.option(
        "--save-as", default=None, help="Store the fit in the terrain library under this name."
    ),
    click.option("--library", default=None, help="Terrain library path."),
    click.option("--json", "as_json", is_flag=True),
)


def _print(run, units, as_json, text) -> None:
    """Print a fit as JSON or as ``text``."""
    d = run.as_dict(units)
    if as_json:
        emit_json(d)
        return
    click.echo(text(d, units))


@click.command("fit-plates")
@click.argument("plates_file", type=click.Path(dir_okay=False))
@click.option(
    "--method",
    type=click.Choice(["wong", "loglog", "nonlinear"]),
    default="wong",
    show_default=True,
)
@fit_output_options
def fit_plates_cmd(plates_file, method, units, save_as, library, as_json):
    """Fit p = k z^n per plate test, and kc, kphi from k = kc/b + kphi (two or more sizes)."""
    from terracone.apps.bevameter import fit_plate_file

    run = fit_plate_file(plates_file, method, save_as=save_as, library=library)
    _print(run, units, as_json, plate_fit_text)


@click.command("fit-shear")
@click.argument("shear_file", type=click.Path(dir_okay=False))
@fit_output_options
def fit_shear_cmd(shear_file, units, save_as, library, as_json):
    """Fit Janosi-Hanamoto tau = (c + sigma tan phi)(1 - exp(-j/K)) to shear tests."""
    from terracone.apps.bevameter import fit_shear_file

    run = fit_shear_file(shear_file, save_as=save_as, library=library)
    _print(run, units, as_json, shear_fit_text)
