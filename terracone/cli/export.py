"""Simulator and GIS inputs: ``terracone export``."""

from __future__ import annotations

from pathlib import Path

import click

from terracone.cli.common import (
    UNITS,
    parse_length,
)
from terracone.physics import units as u


@click.command("export")
@click.option("--terrain", default=None, help="Name of a terrain in the library.")
@click.option(
    "--results",
    "results_path",
    default=None,
    type=click.Path(exists=True),
    help="predict --json output (a file) or a batch output directory.",
)
@click.option("--profile", default=None, help="With --results: the profile to export.")
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["chrono-scm", "json", "csv", "geojson", "mavs"]),
    required=True,
    help="geojson and mavs need --results.",
)
@click.option(
    "--out",
    required=True,
    type=click.Path(),
    help="Output file (a directory with --samples).",
)
@click.option("--units", type=UNITS, default="si", show_default=True, help="For json/csv.")
@click.option("--library", default=None, help="Terrain library path.")
@click.option(
    "--elastic-k",
    type=float,
    default=None,
    help="chrono-scm: SCM elastic stiffness [Pa/m], above Bekker Kphi "
    "(default 4e8, Chrono's scm_hard.json; not from data).",
)
@click.option(
    "--damping",
    type=float,
    default=None,
    help="chrono-scm: SCM damping R [Pa s/m] (default 3e4, Chrono's soil files; not from data).",
)
@click.option(
    "--cohesion", type=float, default=None, help="chrono-scm: Mohr cohesion [kPa or psi]."
)
@click.option("--friction", type=float, default=None, help="chrono-scm: Mohr friction [deg].")
@click.option(
    "--janosi", default=None, help="chrono-scm: Janosi shear modulus K (e.g. 0.01, 1cm, 0.4in)."
)
@click.option(
    "--samples",
    type=click.IntRange(1),
    default=None,
    help="chrono-scm: N files from N posterior draws (predict --uncertainty --json).",
)
@click.option("--seed", type=int, default=None, help="Seed of the --samples draw.")
@click.option(
    "--material",
    type=click.Choice(["sand", "clay"]),
    default=None,
    help="mavs: MAVS soil type of the surface (its Cone Index: CI for sand, RCI for clay).",
)
def export_cmd(
    terrain,
    results_path,
    profile,
    fmt,
    out,
    units,
    library,
    elastic_k,
    damping,
    cohesion,
    friction,
    janosi,
    samples,
    seed,
    material,
):
    """Write a terrain or a result for a simulator (Chrono SCM JSON), as plain B-W
    parameters, or results as GeoJSON points.

    Chrono SCM files get all eight soil parameters: Elastic K and Dampening R
    are documented defaults unless given (said on stderr); Mohr cohesion,
    friction and Janosi shear come from the terrain (a cone prediction has
    none: give --cohesion, --friction, --janosi).
    """
    if (terrain is None) == (results_path is None):
        raise click.UsageError("give exactly one of --terrain and --results")
    if fmt == "geojson":
        return _export_geojson(results_path, out)
    if fmt == "mavs":
        from terracone.cli.mobility import export_mavs

        return export_mavs(results_path, profile, material, out)
    if samples is not None and (fmt != "chrono-scm" or results_path is None):
        raise click.UsageError("--samples needs --results and --format chrono-scm")
    shear = {
        "cohesion_kpa": None if cohesion is None else float(u.pressure_to_si(cohesion, units)),
        "friction_deg": friction,
        "janosi_m": None if janosi is None else parse_length(janosi, units, "--janosi"),
    }
    if terrain is not None:
        from terracone.apps.library import Library

        with Library(library) as lib:
            rec = lib.get(terrain)
        name, params = terrain, rec
    else:
        from terracone.apps.export import load_results, pick_profile

        res = pick_profile(load_results(results_path), profile, str(results_path))
        name, params = res.id, res.params
    if fmt != "chrono-scm":
        from terracone.apps.export import export_terrain

        missing = export_terrain(params, fmt, out, units=units, name=name)
        if missing:
            click.echo(
                f"terracone: {name!r} lacks {', '.join(missing)}: left out of {out}", err=True
            )
        click.echo(f"wrote {out}")
        return None
    scm = {"elastic_k": elastic_k, "damping_r": damping, **shear}
    if samples is not None:
        return _export_samples(res, samples, seed, out, scm)
    from terracone.apps.export import chrono_scm

    doc = chrono_scm(params, name, **scm)
    doc.write(out)
    if doc.provenance_text():
        click.echo(f"terracone: {out}: {doc.provenance_text()}", err=True)
    click.echo(f"wrote {out}")
    return None


def _export_geojson(results_path: str | None, out: str) -> None:
    from terracone.apps.export import load_results, write_geojson

    if results_path is None:
        raise click.UsageError("--format geojson needs --results (predict JSON or batch directory)")
    results = load_results(results_path)
    unlocated = write_geojson(results, out)
    n = len(results) - len(unlocated)
    msg = f"terracone: {out}: {n} located profile{'s' if n != 1 else ''} of {len(results)}"
    if unlocated:
        shown = ", ".join(unlocated[:3]) + (", ..." if len(unlocated) > 3 else "")
        msg += f"; {len(unlocated)} without coordinates (no lat/lon in their metadata: {shown})"
    click.echo(msg, err=True)
    click.echo(f"wrote {out}")


def _export_samples(res, count: int, seed: int | None, out: str, scm: dict) -> None:
    """N Chrono SCM files from N posterior draws of one profile, and an index CSV."""
    from terracone.apps.export import write_scm_samples

    written = write_scm_samples(res, count, out, seed=seed, **scm)
    if written and written[-1].provenance_text():
        click.echo(f"terracone: {Path(out)}: {written[-1].provenance_text()}", err=True)
    click.echo(f"wrote {count} Chrono SCM files and draws.csv to {Path(out)}")
