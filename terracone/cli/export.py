"""Simulator and GIS inputs: ``terracone export``."""

from __future__ import annotations

import re
from pathlib import Path

import click

from terracone.cli.common import UNITS, emit_json, parse_length
from terracone.physics import units as u

#: ``--format`` choices; chrono-scm and pychrono take the Chrono options.
EXPORT_FORMATS = ("chrono-scm", "pychrono", "json", "csv", "geojson", "mavs")
CHRONO_FORMATS = ("chrono-scm", "pychrono")

_PRESSURE_RE = re.compile(r"^\s*([-+0-9.eE]+)\s*([A-Za-z]+)?\s*$")
_ANGLE_RE = re.compile(r"^\s*([-+0-9.eE]+)\s*(deg|°)?\s*$")


def parse_pressure(text: str, units: str, what: str) -> float:
    """'1.3kPa', '0.19psi', '1300Pa', '0.0013MPa' or a bare number in ``units`` -> kPa."""
    m = _PRESSURE_RE.match(text)
    unit = (m.group(2) or "").lower() if m else ""
    if not m or (unit and unit not in u.PRESSURE_UNITS):
        raise click.BadParameter(
            f"{what}: expected a pressure such as 1.3kPa, 0.19psi or a bare number in "
            f"{u.pressure_unit(units)} (--units), got {text!r}"
        )
    try:
        v = float(m.group(1))
    except ValueError:
        raise click.BadParameter(f"{what}: {m.group(1)!r} is not a number") from None
    return v * u.PRESSURE_UNITS[unit] if unit else float(u.pressure_to_si(v, units))


def parse_angle(text: str, what: str) -> float:
    """'31', '31deg' or '31°' -> degrees."""
    m = _ANGLE_RE.match(text)
    try:
        if m:
            return float(m.group(1))
    except ValueError:
        pass
    raise click.BadParameter(
        f"{what}: expected an angle in degrees such as 31 or 31deg, got {text!r}"
    )


def parse_patch(text: str, units: str) -> tuple[float, float]:
    """'LENGTHxWIDTH' (each a length with a unit suffix or in ``units``) -> m."""
    parts = text.lower().split("x")
    if len(parts) != 2:
        raise click.BadParameter(
            f"--patch: expected LENGTHxWIDTH such as 4x1 or 4mx1m, got {text!r}"
        )
    return parse_length(parts[0], units, "--patch", positive=True), parse_length(
        parts[1], units, "--patch", positive=True
    )


def parse_origin(text: str) -> tuple[float, float]:
    """'LAT,LON' in decimal degrees."""
    try:
        lat, lon = (float(s) for s in text.split(","))
    except ValueError:
        raise click.BadParameter(
            f"--origin: expected LAT,LON in decimal degrees, got {text!r}"
        ) from None
    if not (-90 <= lat <= 90 and -180 <= lon <= 180):
        raise click.BadParameter(f"--origin: {text!r} is not a latitude, longitude")
    return lat, lon


@click.command("export")
@click.option("--terrain", default=None, help="Name of a terrain in the library.")
@click.option(
    "--results",
    "results_path",
    default=None,
    type=click.Path(exists=True),
    help="predict --json or --parquet output (a file), or a batch output directory.",
)
@click.option(
    "--map",
    "map_dir",
    type=click.Path(exists=True, file_okay=False),
    default=None,
    help="pychrono: a terrain map directory (terracone map): a soil per cell.",
)
@click.option("--profile", default=None, help="With --results: the profile to export.")
@click.option(
    "--format",
    "fmt",
    type=click.Choice(EXPORT_FORMATS),
    required=True,
    help="chrono-scm: Chrono's co-simulation SCM spec; pychrono: a Python module for "
    "PyChrono's SCMTerrain; json, csv: plain parameters; geojson (needs --results).",
)
@click.option(
    "--out",
    required=True,
    type=click.Path(),
    help="Output file (chrono-scm with --samples: a directory).",
)
@click.option(
    "--units",
    type=UNITS,
    default=None,
    help="json/csv/geojson values, and bare numbers of --cohesion, --janosi, --patch, "
    "--grid-spacing  [default: si; geojson: the run's]",
)
@click.option("--library", default=None, help="Terrain library path.")
@click.option(
    "--shear",
    default=None,
    help="Chrono: Mohr cohesion, friction and Janosi K from a `fit-shear --json` file "
    "or a library terrain.",
)
@click.option("--cohesion", default=None, help="Chrono: Mohr cohesion (1.3kPa, 0.19psi).")
@click.option("--friction", default=None, help="Chrono: Mohr friction angle [deg].")
@click.option("--janosi", default=None, help="Chrono: Janosi shear modulus K (12mm, 0.5in).")
@click.option(
    "--elastic-k",
    type=float,
    default=None,
    help="Chrono: SCM elastic stiffness [Pa/m], above Bekker Kphi (default 4e8; not from data).",
)
@click.option(
    "--damping",
    type=float,
    default=None,
    help="Chrono: SCM damping R [Pa s/m] (default 3e4; not from data).",
)
@click.option(
    "--vehicle",
    default=None,
    type=click.Path(exists=True, dir_okay=False),
    help="Chrono: a vehicle JSON (as for mobility): write, for each profile's layered fit "
    "(predict --layers N --json), the effective one-layer soil for its wheel or track.",
)
@click.option("--patch", default=None, help="Chrono: patch LENGTHxWIDTH (default 4x1 m).")
@click.option("--grid-spacing", default=None, help="Chrono: SCM grid spacing (default 0.1 m).")
@click.option(
    "--origin",
    default=None,
    help="pychrono, located profiles: ORIGIN LAT,LON of the module's frame "
    "(default: the middle of the profiles).",
)
@click.option(
    "--samples",
    type=click.IntRange(1),
    default=None,
    help="Chrono: N posterior draws (predict --uncertainty --json): N spec files, or one "
    "module with N sets.",
)
@click.option("--seed", type=int, default=None, help="Seed of the --samples draw.")
@click.option(
    "--material",
    type=click.Choice(["sand", "clay"]),
    default=None,
    help="mavs: MAVS soil type of the surface (its Cone Index: CI for sand, RCI for clay).",
)
@click.option(
    "--json",
    "as_json",
    is_flag=True,
    help="mavs: print the written entry and set_terrain_properties (the values of MAVS's two "
    "SetTerrainProperties calls) as JSON.",
)
@click.option(
    "--force",
    is_flag=True,
    help="chrono-scm --samples: replace the --out directory whole even when it holds files "
    "that are not an earlier ensemble's (they are deleted); an earlier ensemble is always "
    "replaced whole.",
)
def export_cmd(
    terrain,
    results_path,
    map_dir,
    profile,
    fmt,
    out,
    units,
    library,
    material,
    as_json,
    force,
    **chrono,
):
    """Write a terrain or results for Project Chrono's SCM (a co-simulation spec or a PyChrono
    module), as plain Bekker-Wong parameters, or results as GeoJSON points.

    Chrono needs all eight SCM soil values.  The cone gives Bekker Kphi, Kc
    and n; Mohr cohesion, friction and Janosi K come from --shear, a library
    terrain that has them, or --cohesion, --friction, --janosi.  When one is
    missing nothing is written.  Elastic stiffness, damping, patch and grid
    spacing are defaults unless given (said on stderr).  CSV cells of text that a
    spreadsheet would run as a formula are written after a single quote.
    """
    if sum(x is not None for x in (terrain, results_path, map_dir)) != 1:
        raise click.UsageError("give exactly one of --terrain, --results and --map")
    folder = fmt == "chrono-scm" and chrono["samples"] is not None  # --out is a directory
    if force and not folder:
        raise click.UsageError("--force: only with --format chrono-scm --samples (a directory)")
    _check_paths(out, results_path, map_dir, library, terrain, chrono, folder)
    if map_dir is not None and fmt != "pychrono":
        raise click.UsageError("--map: only with --format pychrono (a terrain map's cells)")
    if material is not None and fmt != "mavs":
        raise click.UsageError("--material: only with --format mavs")
    if as_json and fmt != "mavs":
        raise click.UsageError("--json: only with --format mavs")
    if fmt not in CHRONO_FORMATS:
        given = [f"--{k.replace('_', '-')}" for k, v in chrono.items() if v is not None]
        if given:
            raise click.UsageError(f"{', '.join(given)}: only with --format chrono-scm or pychrono")
    if chrono["vehicle"] is not None:
        _check_vehicle_source(terrain is not None, {**chrono, "map_dir": map_dir})
    if fmt == "geojson":
        return _export_geojson(results_path, out, units)
    if fmt == "mavs":
        return _export_mavs(results_path, profile, material, out, as_json)
    if fmt in ("json", "csv"):
        return _export_plain(terrain, results_path, profile, fmt, out, units or "si", library)
    sources = {"terrain": terrain, "results": results_path, "map_dir": map_dir}
    return _export_chrono(sources, profile, fmt, out, units or "si", library, force, chrono)


def _check_paths(out, results_path, map_dir, library, terrain, chrono, folder) -> None:
    """Refuse an --out that is an input (or, a --samples directory, one that holds an input)."""
    from terracone.io.outputs import check_outputs

    inputs = {"--results": results_path, "--map": map_dir, "--vehicle": chrono["vehicle"]}
    shear = chrono["shear"]
    if shear is not None and Path(shear).is_file():
        inputs["--shear"] = shear
    if terrain is not None or (shear is not None and "--shear" not in inputs):
        from terracone.apps.library import default_library_path

        inputs["--library"] = library or default_library_path()
    check_outputs({"--out": out}, inputs, directories=("--out",) if folder else ())


def _export_plain(terrain, results_path, profile, fmt, out, units, library) -> None:
    from terracone.apps.exporting import export_plain

    run = export_plain(out, fmt, terrain=terrain, results=results_path, profile=profile,
                       units=units, library=library)  # fmt: skip
    if run.missing:
        click.echo(
            f"terracone: {run.name!r} lacks {', '.join(run.missing)}: left out of {out}", err=True
        )
    click.echo(f"wrote {out}")


def _export_geojson(results_path: str | None, out: str, units: str | None) -> None:
    from terracone.apps.exporting import export_geojson

    if results_path is None:
        raise click.UsageError("--format geojson needs --results (predict JSON or batch directory)")
    run = export_geojson(results_path, out, units)
    n, unlocated = run.located, run.unlocated
    msg = f"terracone: {out}: {n} located profile{'s' if n != 1 else ''} of {run.count}"
    if unlocated:
        shown = ", ".join(unlocated[:3]) + (", ..." if len(unlocated) > 3 else "")
        msg += f"; {len(unlocated)} without coordinates (no lat/lon in their metadata: {shown})"
    click.echo(msg, err=True)
    click.echo(f"wrote {out}")


def _export_mavs(
    results_path: str | None, profile: str | None, material: str | None, out: str, as_json: bool
) -> None:
    """``terracone export --format mavs``: the MAVS surface entry of a profile or a site, and
    the values of MAVS's two SetTerrainProperties calls (docs/export.md)."""
    from terracone.apps.exporting import export_mavs

    if results_path is None:
        raise click.UsageError("--format mavs needs --results (predict JSON or batch directory)")
    if material is None:
        raise click.UsageError("--format mavs needs --material sand or clay (MAVS's soil type)")
    run = export_mavs(results_path, out, material=material, profile=profile)
    for n in run.notes:
        click.echo(f"terracone: {n}", err=True)
    entry, tc = run.document["Surface Mesh"][0], run.document["terracone"]
    stp = tc["set_terrain_properties"]
    env, veh = stp["environment"], stp["vehicle"]
    click.echo(
        f"terracone: {out}: Material {entry['Material']}, Cone Index {entry['Cone Index']:.4g} psi "
        f"({tc['cone_index_of']} of the 0-6 in layer, {tc['what']}); MAVS's scene loader reads "
        "this entry but does not pass it to the vehicle: set the soil with\n"
        f"  env.SetTerrainProperties({env['type']!r}, {env['strength']:.6g})  # Pa\n"
        f"  or veh.SetTerrainProperties(soil_type={veh['soil_type']!r}, "
        f"soil_strength={veh['soil_strength']:.6g})  # psi (replaces the mesh by a flat surface)",
        err=True,
    )
    if as_json:
        emit_json(run.as_dict())
    else:
        click.echo(f"wrote {out}")


def _check_vehicle_source(terrain: bool, opts: dict) -> None:
    """--vehicle needs layered results: refuse a library terrain, a map, --samples."""
    if terrain:
        raise click.UsageError(
            "--vehicle: a library terrain has one layer; the effective soil is made of a "
            "profile's layered fit: give --results (the JSON of predict --layers 2 --json)"
        )
    if opts["map_dir"] is not None:
        raise click.UsageError(
            "--vehicle with --map: a terrain map's cells carry one layer (kc, kphi, n per cell, "
            "no layers or interfaces), so there is no layered ground to make an effective soil "
            "of: give --results (the JSON of predict --layers 2 --json)"
        )
    if opts["samples"] is not None:
        raise click.UsageError(
            "--vehicle with --samples: the posterior draws are of the one-layer fit; an "
            "effective soil per draw of the layered fit is not done"
        )


def _chrono_values(opts: dict, units: str) -> dict:
    """The Chrono options in SI: explicit shear values (with their option), SCM values."""
    given = []
    for key, opt, parse in (
        ("c_kpa", "cohesion", lambda t: parse_pressure(t, units, "--cohesion")),
        ("phi_deg", "friction", lambda t: parse_angle(t, "--friction")),
        ("K_m", "janosi", lambda t: parse_length(t, units, "--janosi", positive=True)),
    ):
        if opts[opt] is not None:
            given.append((f"--{opt}", {key: parse(opts[opt])}))
    spacing = opts["grid_spacing"]
    return {
        "shear_given": given,
        "patch": None if opts["patch"] is None else parse_patch(opts["patch"], units),
        "grid_spacing": None
        if spacing is None
        else parse_length(spacing, units, "--grid-spacing", positive=True),
        "origin": None if opts["origin"] is None else parse_origin(opts["origin"]),
    }


def _export_chrono(sources, profile, fmt, out, units, library, force, opts) -> None:
    from terracone.apps.exporting import OptionError, export_chrono

    if opts["origin"] is not None and fmt != "pychrono":
        raise click.UsageError("--origin: only with --format pychrono and several located profiles")
    try:
        run = export_chrono(
            out, fmt, **sources, profile=profile, library=library, shear=opts["shear"],
            elastic_k=opts["elastic_k"], damping_r=opts["damping"], vehicle=opts["vehicle"],
            samples=opts["samples"], seed=opts["seed"], force=force, **_chrono_values(opts, units),
        )  # fmt: skip
    except OptionError as exc:
        raise click.UsageError(str(exc)) from None
    for line in (*run.notes, run.defaults_text):
        if line:
            click.echo(f"terracone: {out}: {line}", err=True)
    left = run.left
    if left:
        more = "; ..." if len(left) > 5 else ""
        click.echo(f"terracone: {out}: left out {len(left)}: {'; '.join(left[:5])}{more}", err=True)
    click.echo(f"wrote {run.written} to {Path(out)}")
