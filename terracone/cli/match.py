"""``terracone match``: which of the stored calibrations is a file, or a site, like?"""

from __future__ import annotations

import sys

import click

from terracone.cli.common import (
    UNITS,
    emit_document,
    json_options,
    load_library_prior,
    parse_length,
    reading_from,
    reading_options,
    shared,
)


@click.command("match")
@click.argument("ci_file", type=click.Path(dir_okay=False))
@click.option(
    "--library",
    "library_path",
    required=True,
    help="The library file (SQLite, `terracone library --library DB`) whose calibrations "
    "are ranked.",
)
@click.option("--by", default=None, help="Metadata column(s) naming each profile's site.")
@click.option(
    "--radius", default=None, help="Group by distance: profiles within this radius (e.g. 10m)."
)
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the check.")
@click.option("--units", type=UNITS, default="si", show_default=True)
@shared(*reading_options)
@click.option(
    "--file-units", type=UNITS, default=None, help="Unit system of an input that states none."
)
@shared(*json_options)
def match_cmd(ci_file, library_path, by, radius, seed, file_units, out, as_json, **opts):
    """Rank the stored calibrations for each profile (or site, --by): weights and the check.

    Each calibration's weight is its evidence on the CI (docs/library.md); a
    profile or site that no calibration explains (posterior predictive check)
    is outside the library.
    """
    from terracone.apps.matching import match_profiles
    from terracone.inverse.problem import Problem
    from terracone.report.text import match_text

    units = opts["units"]
    problem = Problem(library=load_library_prior(library_path))
    run = match_profiles(
        reading_from(opts, file_units).read(ci_file, units),
        problem,
        by=by,
        radius=parse_length(radius, units, "--radius", positive=True) if radius else None,
        seed=seed,
        source=str(ci_file),
    )
    doc = run.as_dict(units, input=str(ci_file))
    emit_document(doc, out=out, as_json=as_json, text=match_text)
    if not run.matched_any:
        sys.exit(1)
