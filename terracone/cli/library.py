"""The terrain library: ``terracone library list|show|add|remove|import|export``."""

from __future__ import annotations

from typing import Any

import click

from terracone.cli.common import Group, emit_json
from terracone.report.text import library_text


@click.group("library", cls=Group)
@click.option(
    "--library",
    "library_path",
    default=None,
    help="Library path (default: $TERRACONE_LIBRARY or the user data dir).",
)
@click.pass_context
def library_grp(ctx, library_path):
    """The terrain library: reference terrains, calibrations, bevameter fits."""
    ctx.obj = {"library": library_path}


def _open(ctx: click.Context):
    """The library of ``--library``, imported on use (``terracone --help`` stays fast)."""
    from terracone.apps.library import Library

    return Library(ctx.obj["library"])


@library_grp.command("list")
@click.option(
    "--kind", default=None, help="Only this kind (reference, calibration, bevameter-fit)."
)
@click.option("--json", "as_json", is_flag=True)
@click.pass_context
def library_list(ctx, kind, as_json):
    """List the stored terrains."""
    with _open(ctx) as lib:
        recs = lib.list(kind)
    if as_json:
        emit_json([r.to_dict() for r in recs])
        return
    click.echo(library_text(recs))


@library_grp.command("show")
@click.argument("name")
@click.pass_context
def library_show(ctx, name):
    """Show one terrain (JSON, SI)."""
    with _open(ctx) as lib:
        emit_json(lib.get(name).to_dict())


@library_grp.command("add")
@click.argument("name", required=False)
@click.option("--kind", default=None, help="Record kind (default: user; calibration with --from).")
@click.option(
    "--param",
    "params",
    multiple=True,
    help="KEY=VALUE in SI (kc, kphi, n, c_kpa, phi_deg, K_m, cc, phic_deg, r_min, ...).",
)
@click.option(
    "--from-json",
    type=click.Path(dir_okay=False),
    default=None,
    help="Parameters from a JSON object (SI).",
)
@click.option(
    "--from",
    "from_cal",
    type=click.Path(dir_okay=False),
    default=None,
    help="A calibration file of `terracone learn --save`: stored as kind calibration, under "
    "its terrain name unless NAME is given.",
)
@click.option(
    "--soil-class",
    default=None,
    help="Soil class of the terrain (a USCS symbol such as SP, or fine or coarse), kept in "
    "the provenance: the prior weight of the library as a prior.",
)
@click.option("--source", default=None, help="Provenance: where the values come from.")
@click.option("--replace", is_flag=True)
@click.pass_context
def library_add(ctx, name, kind, params, from_json, from_cal, soil_class, source, replace):
    """Add a terrain (NAME), or a calibration file (--from cal.json)."""
    from terracone.apps.library import add_calibration, add_terrain

    if from_cal:
        if from_json or params:
            raise click.UsageError("give --from alone: a calibration file holds its parameters")
        if kind not in (None, "calibration"):
            raise click.UsageError(f"--from stores kind calibration (got --kind {kind})")
        rec = add_calibration(ctx.obj["library"], from_cal, name, source=source,
                              soil_class=soil_class, replace=replace)  # fmt: skip
        click.echo(f"added {rec.name!r} ({rec.kind}) from {from_cal}")
        return
    if name is None:
        raise click.UsageError("give the terrain's NAME (or --from cal.json)")
    p: dict[str, Any] = {}
    for kv in params:
        if "=" not in kv:
            raise click.BadParameter(f"--param: expected KEY=VALUE, got {kv!r}")
        k, v = kv.split("=", 1)
        try:
            p[k.strip()] = float(v)
        except ValueError:
            p[k.strip()] = v.strip()
    rec = add_terrain(ctx.obj["library"], name, kind or "user", p, from_json=from_json,
                      source=source, soil_class=soil_class, replace=replace)  # fmt: skip
    click.echo(f"added {rec.name!r} ({rec.kind})")


@library_grp.command("seed-paper")
@click.option("--replace", is_flag=True, help="Overwrite records of the same names.")
@click.pass_context
def library_seed_paper(ctx, replace):
    """Store the paper's parameter sets as calibrations: LETE sand (Table 4-1), KRC (Table 4-3)."""
    from terracone.apps.library import seed_paper

    with _open(ctx) as lib:
        rep = seed_paper(lib, replace=replace)
    click.echo(f"seeded {len(rep.imported)} calibrations, skipped {len(rep.skipped)}")
    for n in rep.imported:
        click.echo(f"  {n}")
    for n, why in rep.skipped:
        click.echo(f"  skipped {n!r}: {why}", err=True)


@library_grp.command("remove")
@click.argument("name")
@click.pass_context
def library_remove(ctx, name):
    """Remove a terrain (reference terrains cannot be removed)."""
    with _open(ctx) as lib:
        lib.remove(name)
    click.echo(f"removed {name!r}")


@library_grp.command("import")
@click.argument("path", type=click.Path(dir_okay=False))
@click.option("--replace", is_flag=True)
@click.pass_context
def library_import(ctx, path, replace):
    """Import terrains from a JSON file written by `library export`."""
    with _open(ctx) as lib:
        rep = lib.import_(path, replace=replace)
    click.echo(f"imported {len(rep.imported)}, skipped {len(rep.skipped)}")
    for name, why in rep.skipped:
        click.echo(f"  skipped {name!r}: {why}", err=True)


@library_grp.command("export")
@click.argument("path", type=click.Path(dir_okay=False))
@click.option("--include-builtin", is_flag=True, help="Also the packaged reference terrains.")
@click.pass_context
def library_export(ctx, path, include_builtin):
    """Export terrains to a JSON file."""
    from terracone.io.outputs import check_outputs

    with _open(ctx) as lib:
        check_outputs({"PATH": path}, {"--library": lib.path})
        k = lib.export(path, include_builtin=include_builtin)
    click.echo(f"exported {k} terrains to {path}")
