"""What the terrain means for a vehicle: ``terracone mobility``."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import click

from terracone.cli.common import UNITS, emit_json, parse_length


def parse_layer(text: str | None, units: str) -> tuple[float, float] | None:
    """'TOP:BOTTOM' (lengths with a unit, or bare numbers in --units) -> (top, bottom) [m]."""
    if not text:
        return None
    if ":" not in text:
        raise click.BadParameter(f"--layer: expected TOP:BOTTOM such as 0:6in, got {text!r}")
    top_s, bottom_s = text.split(":", 1)
    if not top_s.strip() or not bottom_s.strip():
        raise click.BadParameter(f"--layer: give both TOP and BOTTOM, got {text!r}")
    top, bottom = parse_length(top_s, units, "--layer"), parse_length(bottom_s, units, "--layer")
    if not 0 <= top < bottom:
        raise click.BadParameter(f"--layer: need 0 <= TOP < BOTTOM, got {text!r}")
    return top, bottom


def parse_critical_layer(text: str | None, units: str):
    """'rule' or 'weakest:THICKNESS[:TOP:BOTTOM]' (lengths with a unit, or in --units)
    -> a :class:`terracone.apps.mobility.LayerChoice`."""
    from terracone.apps.mobility import LayerChoice

    if text is None or text.strip() == "rule":
        return LayerChoice()
    parts = text.split(":")
    if (
        parts[0].strip() != "weakest"
        or len(parts) not in (2, 4)
        or not all(p.strip() for p in parts)
    ):
        raise click.BadParameter(
            "--critical-layer: expected 'rule', 'weakest:THICKNESS' or "
            f"'weakest:THICKNESS:TOP:BOTTOM' (e.g. weakest:6in, weakest:15cm:0:45cm), got {text!r}"
        )
    lengths = [parse_length(p, units, "--critical-layer") for p in parts[1:]]
    window = tuple(lengths[1:]) if len(lengths) == 3 else None
    try:
        if window is None:
            return LayerChoice("weakest", thickness=lengths[0])
        return LayerChoice("weakest", thickness=lengths[0], window=window)
    except ValueError as exc:
        raise click.BadParameter(f"--critical-layer: {exc}") from None


def _progress(count: int):
    """tqdm over the profiles when there are many and stderr is a terminal."""
    if count < 500 or not sys.stderr.isatty():
        return None
    from tqdm.auto import tqdm

    return lambda it: tqdm(it, total=count, desc="terracone mobility", unit="profile",
                           file=sys.stderr)  # fmt: skip


@click.command("mobility")
@click.argument("results_path", metavar="RESULTS|MAPDIR", type=click.Path(exists=True))
@click.option(
    "--vehicle",
    "vehicle_path",
    required=True,
    type=click.Path(dir_okay=False),
    help="Vehicle JSON: name, kind (wheeled or tracked), mobility_index (or "
    "mobility_index_inputs), drive, tire_deflection_ratio, wheel {load, diameter, width} "
    "(docs/mobility.md).",
)
@click.option(
    "--passes",
    type=click.Choice(["1", "50"]),
    default="1",
    show_default=True,
    help="VCI_1 (one pass) or VCI_50 (fifty passes).",
)
@click.option(
    "--soil",
    type=click.Choice(["fine", "coarse"]),
    default=None,
    help="Soil class of every profile: fine-grained (RCI = CI x RI) or coarse-grained (CI). "
    "Default: each profile's uscs or soil_class metadata, else assumed fine (and said).",
)
@click.option(
    "--critical-layer",
    "critical_layer",
    default="rule",
    show_default=True,
    help="How the critical layer is chosen: 'rule' (by soil class, vehicle kind and passes, "
    "with its source) or 'weakest:THICKNESS[:TOP:BOTTOM]', the weakest layer of that "
    "thickness within TOP-BOTTOM (default 0-12 in).",
)
@click.option(
    "--layer",
    default=None,
    help="Critical layer TOP:BOTTOM of every profile (e.g. 0:6in); overrides --critical-layer.",
)
@click.option(
    "--remolding-index",
    type=float,
    default=None,
    help="Remolding index RI in (0, 2] of every profile (default: an RI column of the metadata).",
)
@click.option(
    "--by",
    default=None,
    help="Metadata column(s) naming each profile's site or map cell (default: site, if present).",
)
@click.option(
    "--ci",
    "ci_file",
    default=None,
    type=click.Path(dir_okay=False),
    help="CI file of results that keep no CI (a batch directory), matched by profile id.",
)
@click.option(
    "--file-units", type=UNITS, default=None, help="Unit system of a --ci file that states none."
)
@click.option(
    "--library",
    "library_path",
    default=None,
    help="Predict the profiles again with this library's calibrations as the prior (their CI "
    "from RESULTS or --ci; docs/library.md).",
)
@click.option(
    "--units", type=UNITS, default="si", show_default=True, help="SI: m, kPa, N; US: in, psi, lbf."
)
@click.option(
    "--simulations",
    type=int,
    default=None,
    help="MAPDIR: conditional simulations of the map's fields (default 100).",
)
@click.option("--seed", type=int, default=0, show_default=True, help="MAPDIR: simulations' seed.")
@click.option(
    "--workers",
    type=int,
    default=None,
    help="MAPDIR: processes that condition the simulations (default: this one).",
)
@click.option(
    "--scheduler",
    default=None,
    help="MAPDIR: address of a running dask.distributed scheduler, tcp://HOST:PORT.",
)
@click.option(
    "--out",
    type=click.Path(),
    default=None,
    help="RESULTS: write the JSON here too. MAPDIR: the output directory (p_go.tif, "
    "sinkage.tif, mobility.json).",
)
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
def mobility_cmd(
    results_path, vehicle_path, passes, soil, critical_layer, layer, remolding_index, by, ci_file,
    file_units, library_path, units, simulations, seed, workers, scheduler, out, as_json,
):  # fmt: skip
    """NRMM go/no-go and Bekker wheel sinkage of a vehicle on predicted terrain or on a map.

    RESULTS is a predict JSON or Parquet file, or a batch directory.  Per
    profile (and per site): the soil class, the critical layer and what chose
    it, its mean CI, RCI = CI x RI (fine-grained soils), the vehicle cone index
    of the vehicle's kind where its relation applies, GO when RCI >= VCI with
    the margin, and the sinkage and compaction resistance of the vehicle's
    wheel from kc, kphi and n (Bekker), with the 90% band of the posterior
    draws of predict --uncertainty --json.

    MAPDIR is a terracone map directory (it holds map.json): every cell gets
    P(GO), the probability that RCI at a point reaches VCI (p_go.tif), and
    the median and 90% band of the wheel sinkage (sinkage.tif), from
    conditional simulations of the map's fields; --out DIR is required.
    """
    from terracone.apps.maps.directory import is_map_directory

    if is_map_directory(results_path):
        opts = {"--by": by, "--ci": ci_file, "--file-units": file_units, "--library": library_path}
        given = [k for k, v in opts.items() if v is not None]
        if given:
            raise click.UsageError(f"{', '.join(given)}: not with a map directory")
        go_map_cmd(results_path, vehicle_path, passes, soil, critical_layer, layer,
                   remolding_index, units, simulations, seed, workers, scheduler, out, as_json)  # fmt: skip
        return
    extra = {"--simulations": simulations, "--workers": workers, "--scheduler": scheduler}
    given = [k for k, v in extra.items() if v is not None]
    if given:
        raise click.UsageError(f"{', '.join(given)}: only with a map directory (MAPDIR)")
    if out is not None and Path(out).is_dir():
        raise click.BadParameter(
            f"{out!r} is a directory (give a file for RESULTS)", param_hint="'--out'"
        )
    _check_results_path(results_path)
    from terracone.apps.mobility import ci_profiles_by_id, evaluate_mobility
    from terracone.apps.vehicles import load_vehicle
    from terracone.io.outputs import check_outputs
    from terracone.report.mobility import mobility_text
    from terracone.result import read_results

    check_outputs(
        {"--out": out}, {"RESULTS": results_path, "--vehicle": vehicle_path, "--ci": ci_file}
    )
    choice = parse_critical_layer(critical_layer, units)
    vehicle = load_vehicle(vehicle_path)
    results = read_results(results_path)
    ci_profiles = None
    if ci_file:
        from terracone.apps.workflow import Reading

        ci_profiles = ci_profiles_by_id(Reading(file_units=file_units).read(ci_file, units))
    if library_path:
        results = _with_library(results, library_path, ci_profiles)
    run = evaluate_mobility(
        results, vehicle, passes=int(passes), layer=parse_layer(layer, units), choice=choice,
        soil=soil, remolding_index=remolding_index,
        by=None if by is None else [k.strip() for k in by.split(",")],
        ci_profiles=ci_profiles, source=str(results_path), progress=_progress(len(results)),
    )  # fmt: skip
    doc = run.as_dict(units, input=str(results_path))
    if out:
        emit_json(doc, out)
    if as_json:
        emit_json(doc)
    else:
        click.echo(mobility_text(doc))
    if not run.evaluated_any:
        sys.exit(1)


def _check_results_path(path: str) -> None:
    """A directory must be a batch directory (a map directory was taken before)."""
    p = Path(path)
    if p.is_dir() and not any(p.glob("part-*.parquet")):
        raise ValueError(
            f"{p}: neither a terracone map directory (no map.json) nor a batch directory "
            "(no part-*.parquet files)"
        )


@contextmanager
def _pool(workers: int | None, scheduler: str | None) -> Iterator[Any]:
    """None (this process), a process pool of ``workers``, or a Dask client of ``scheduler``."""
    if workers is not None and scheduler is not None:
        raise click.UsageError("give --workers or --scheduler, not both")
    if scheduler is not None:
        from distributed import Client

        try:
            client = Client(scheduler, timeout="20s", set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise ValueError(f"cannot connect to the Dask scheduler {scheduler}: {exc}") from None
        with client:
            yield client
        return
    if workers is None or workers <= 1:
        if workers is not None and workers < 1:
            raise click.BadParameter(f"must be >= 1, got {workers}", param_hint="'--workers'")
        yield None
        return
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(max_workers=workers) as pool:
        yield pool


def go_map_cmd(
    mapdir, vehicle_path, passes, soil, critical_layer, layer, remolding_index, units,
    simulations, seed, workers, scheduler, out, as_json,
) -> None:  # fmt: skip
    """``terracone mobility MAPDIR``: P(GO) and wheel sinkage of every cell of a map."""
    from tqdm import tqdm

    from terracone.apps.go_map import DEFAULT_SIMULATIONS, go_map, write_go_map
    from terracone.apps.maps.directory import read_map_directory
    from terracone.apps.vehicles import load_vehicle
    from terracone.report.mobility import go_map_text

    if out is None:
        raise click.UsageError("a map directory needs --out DIR (p_go.tif, sinkage.tif)")
    if Path(out).exists() and not Path(out).is_dir():
        raise click.BadParameter(
            f"{out!r} is a file (give a directory for MAPDIR)", param_hint="'--out'"
        )
    choice = parse_critical_layer(critical_layer, units)
    lay = parse_layer(layer, units)
    if lay is not None:
        from terracone.apps.mobility import LayerChoice

        choice = LayerChoice("layer", layer=lay)
    vehicle = load_vehicle(vehicle_path)
    d = read_map_directory(mapdir)
    n = DEFAULT_SIMULATIONS if simulations is None else simulations
    cells = d.grid.width * d.grid.height
    with (
        _pool(workers, scheduler) as pool,
        tqdm(
            total=3 * cells, desc="simulating cells", unit="cell", disable=None, leave=False
        ) as bar,
    ):
        result = go_map(d, vehicle, passes=int(passes), soil=soil, choice=choice,
                        remolding_index=remolding_index, simulations=n, seed=seed, pool=pool,
                        progress=bar.update)  # fmt: skip
    _, doc = write_go_map(result, out, units, input=str(mapdir))
    for note in doc["notes"]:
        click.echo(f"note: {note}", err=True)
    if as_json:
        emit_json(doc)
    else:
        click.echo(go_map_text(doc, out))
    if not result.evaluated_any:
        sys.exit(1)


def _with_library(results, library_path: str, ci_profiles):
    """The results predicted again with a library as the prior (``--library``)."""
    from terracone.apps.workflow import repredict
    from terracone.cli.common import load_library_prior
    from terracone.inverse.problem import Problem

    return repredict(results, Problem(library=load_library_prior(library_path)), ci_profiles)


def export_mavs(
    results_path: str | None, profile: str | None, material: str | None, out: str, as_json: bool
):
    """``terracone export --format mavs``: the MAVS surface entry of a profile or a site, and
    the values of MAVS's two SetTerrainProperties calls (docs/export.md)."""
    from terracone.apps.mavs import write_mavs
    from terracone.result import read_results

    if results_path is None:
        raise click.UsageError("--format mavs needs --results (predict JSON or batch directory)")
    if material is None:
        raise click.UsageError("--format mavs needs --material sand or clay (MAVS's soil type)")
    doc, notes = write_mavs(
        read_results(results_path), out, material=material, profile=profile,
        source=str(results_path),
    )  # fmt: skip
    for n in notes:
        click.echo(f"terracone: {n}", err=True)
    entry, tc = doc["Surface Mesh"][0], doc["terracone"]
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
        emit_json({**doc, "set_terrain_properties": stp, "out": str(out)})
    else:
        click.echo(f"wrote {out}")
