"""Bevameter tests: ``fit-plates`` and ``fit-shear``."""

from __future__ import annotations

import click

from terracone.cli.common import UNITS, emit_json, shared, store_in_library
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


def _finish(fit, source, method, units, save_as, library, as_json, text) -> None:
    """Store ``fit`` in the library when asked, then print it as JSON or as ``text``."""
    if save_as:
        from terracone.apps.library import make_provenance

        provenance = make_provenance(source=str(source), method=method)
        store_in_library(library, save_as, "bevameter-fit", fit.params(), provenance)
    d = fit.as_dict(units)
    d["saved_as"] = save_as
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
    from terracone.inverse.bevameter.plates import fit_plates
    from terracone.io import read_plate_tests

    fit = fit_plates(read_plate_tests(plates_file), method=method)
    method = f"fit-plates ({method})"
    _finish(fit, plates_file, method, units, save_as, library, as_json, plate_fit_text)


@click.command("fit-shear")
@click.argument("shear_file", type=click.Path(dir_okay=False))
@fit_output_options
def fit_shear_cmd(shear_file, units, save_as, library, as_json):
    """Fit Janosi-Hanamoto tau = (c + sigma tan phi)(1 - exp(-j/K)) to shear tests."""
    from terracone.inverse.bevameter.shear import fit_shear
    from terracone.io import read_shear_tests

    fit = fit_shear(read_shear_tests(shear_file))
    _finish(fit, shear_file, "fit-shear", units, save_as, library, as_json, shear_fit_text)
