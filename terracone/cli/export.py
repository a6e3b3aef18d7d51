"""Simulator and GIS inputs: ``terracone export``."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import click

from terracone.cli.common import UNITS, parse_length
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
    return parse_length(parts[0], units, "--patch"), parse_length(parts[1], units, "--patch")


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
        from terracone.cli.mobility import export_mavs

        return export_mavs(results_path, profile, material, out, as_json)
    if fmt in ("json", "csv"):
        return _export_plain(terrain, results_path, profile, fmt, out, units or "si", library)
    chrono["map_dir"], chrono["force"] = map_dir, force
    return _export_chrono(terrain, results_path, profile, fmt, out, units or "si", library, chrono)


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
    from terracone.apps.export import export_terrain

    if terrain is not None:
        from terracone.apps.library import Library

        with Library(library) as lib:
            name, params = terrain, lib.get(terrain)
    else:
        from terracone.apps.export import pick_profile
        from terracone.result import read_results

        res = pick_profile(read_results(results_path), profile, str(results_path))
        name, params = res.id, res.params
    missing = export_terrain(params, fmt, out, units=units, name=name)
    if missing:
        click.echo(f"terracone: {name!r} lacks {', '.join(missing)}: left out of {out}", err=True)
    click.echo(f"wrote {out}")


def _export_geojson(results_path: str | None, out: str, units: str | None) -> None:
    from terracone.apps.export import write_geojson
    from terracone.result import read_results

    if results_path is None:
        raise click.UsageError("--format geojson needs --results (predict JSON or batch directory)")
    results = read_results(results_path)
    units = units or results.settings.get("units") or "si"
    unlocated = write_geojson(results, out, units)
    n = len(results) - len(unlocated)
    msg = f"terracone: {out}: {n} located profile{'s' if n != 1 else ''} of {len(results)}"
    if unlocated:
        shown = ", ".join(unlocated[:3]) + (", ..." if len(unlocated) > 3 else "")
        msg += f"; {len(unlocated)} without coordinates (no lat/lon in their metadata: {shown})"
    click.echo(msg, err=True)
    click.echo(f"wrote {out}")


def _shear_layers(opts: dict, units: str, library: str | None, base: tuple | None):
    """(values, sources) of the terrain's shear values: terrain, then --shear, then options."""
    from terracone.apps.export import merge_shear, shear_of

    layers = [base] if base else []
    if opts["shear"] is not None:
        values, source = shear_of(opts["shear"], library)
        layers.append((source, values))
    for key, opt, parse in (
        ("c_kpa", "cohesion", lambda t: parse_pressure(t, units, "--cohesion")),
        ("phi_deg", "friction", lambda t: parse_angle(t, "--friction")),
        ("K_m", "janosi", lambda t: parse_length(t, units, "--janosi")),
    ):
        if opts[opt] is not None:
            layers.append((f"--{opt}", {key: parse(opts[opt])}))
    return merge_shear(layers)


def _chrono_soils(terrain, results_path, profile, fmt, units, library, opts):
    """The soils to write and the lines said on stderr about them."""
    from terracone.apps.chrono import SPEC_SOIL_KEYS

    bekker = ", ".join(SPEC_SOIL_KEYS[:3])
    source = results_path if opts["map_dir"] is None else f"map {opts['map_dir']}"
    origin = f"library terrain {terrain!r}" if terrain else f"the cone ({source})"
    notes, base, record = [f"{bekker} from {origin}"], None, None
    if terrain is not None:
        from terracone.apps.library import Library

        with Library(library) as lib:
            record = lib.get(terrain)
        base = (f"library terrain {terrain!r}", record.params)
    shear, sources = _shear_layers(opts, units, library, base)
    keys = dict(zip(("c_kpa", "phi_deg", "K_m"), SPEC_SOIL_KEYS[3:6]))
    by_source: dict[str, list[str]] = {}
    for k, src in sources.items():
        by_source.setdefault(src, []).append(keys[k])
    notes += [f"{', '.join(ks)} from {src}" for src, ks in by_source.items()]
    if record is not None:
        from terracone.apps.export import terrain_soil

        if opts["samples"] is not None:
            raise click.UsageError("--samples needs --results with posterior draws")
        return [terrain_soil(record, shear)], notes, []
    if opts["map_dir"] is not None:
        from terracone.apps.export import map_soils

        if opts["samples"] is not None:
            raise click.UsageError("--samples needs --results with posterior draws")
        return map_soils(opts["map_dir"], shear), notes, []
    from terracone.apps.export import result_soils
    from terracone.result import read_results

    soils, left = result_soils(
        read_results(results_path),
        shear,
        profile=profile,
        several=fmt == "pychrono",
        source=str(results_path),
        samples=opts["samples"],
        seed=opts["seed"],
    )
    if opts["vehicle"] is not None:
        soils, notes, left = _effective(results_path, soils, notes, left, opts["vehicle"])
    return soils, notes, left


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


def _progress(count: int):
    """tqdm over the profiles when there are many and stderr is a terminal."""
    if count < 200 or not sys.stderr.isatty():
        return None
    from tqdm.auto import tqdm

    def bar(it):
        return tqdm(it, total=count, desc="terracone export: effective soils", unit="profile",
                    file=sys.stderr)  # fmt: skip

    return bar


def _effective(results_path, soils, notes, left, vehicle):
    """The soils replaced by their effective soils for the vehicle, and what is said of them."""
    from terracone.apps.export import effective_soils, running_gear
    from terracone.result import read_results

    gear = running_gear(vehicle)
    results = read_results(results_path)
    soils, more = effective_soils(results, soils, gear, str(results_path), _progress(len(soils)))
    rms = [s.effective["error"]["pressure_rms"] for s in soils]
    worst = max((v for v in rms if v is not None), default=float("nan"))
    notes = [
        notes[0].replace(
            "from the cone",
            f"of the effective soil (kc = 0, kphi = k at the width) for {gear.describe()}, "
            f"fitted to the layered fit of the cone",
        ),
        *notes[1:],
        f"effective soil: sinkage as the layered ground's; pressure error (relative RMS over the "
        f"sinkage) at most {worst:.3g}; per profile in the notes' 'effective'",
    ]
    return soils, notes, left + more


def _export_chrono(terrain, results_path, profile, fmt, out, units, library, opts) -> None:
    from terracone.apps.chrono import scm_settings

    settings = scm_settings(
        elastic_k=opts["elastic_k"],
        damping_r=opts["damping"],
        patch=None if opts["patch"] is None else parse_patch(opts["patch"], units),
        grid_spacing=(
            None
            if opts["grid_spacing"] is None
            else parse_length(opts["grid_spacing"], units, "--grid-spacing")
        ),
    )
    soils, notes, left = _chrono_soils(terrain, results_path, profile, fmt, units, library, opts)
    try:
        source = terrain or results_path or opts["map_dir"]
        what = _write_chrono(soils, fmt, out, settings, opts, source, notes)
    except ValueError as exc:
        found = f" (found: {'; '.join(notes)})" if notes else ""
        raise ValueError(f"{exc}{found}") from None
    for line in (*notes, settings.defaults_text(spec=fmt == "chrono-scm")):
        if line:
            click.echo(f"terracone: {out}: {line}", err=True)
    if left:
        more = "; ..." if len(left) > 5 else ""
        click.echo(f"terracone: {out}: left out {len(left)}: {'; '.join(left[:5])}{more}", err=True)
    click.echo(f"wrote {what} to {Path(out)}")


def _write_chrono(soils, fmt, out, settings, opts, source, notes) -> str:
    """Write the Chrono output; returns what was written, in words."""
    from terracone.apps.chrono import write_pychrono, write_scm_spec, write_scm_specs

    if opts["origin"] is not None and (fmt != "pychrono" or len(soils) < 2):
        raise click.UsageError("--origin: only with --format pychrono and several located profiles")
    if fmt == "pychrono":
        origin = None if opts["origin"] is None else parse_origin(opts["origin"])
        write_pychrono(out, soils, settings, origin=origin, source=str(source), notes=notes)
        what = f"{len(soils)} located soils" if len(soils) > 1 else f"the soil of {soils[0].id!r}"
        if opts["samples"]:
            what += f" with {opts['samples']} posterior draws"
        return what
    if opts["samples"] is not None:
        write_scm_specs(out, soils[0], settings, force=opts["force"])
        return f"{opts['samples']} Chrono SCM specs and draws.csv of {soils[0].id!r}"
    effective = soils[0].effective
    spec_notes = (
        None
        if effective is None
        else {
            "profile": soils[0].id,
            "source": str(source),
            "notes": list(notes),
            "effective": dict(effective),
        }  # fmt: skip
    )
    write_scm_spec(out, soils[0].params, settings, repr(soils[0].id), spec_notes)
    return f"the Chrono SCM spec of {soils[0].id!r}"
