"""What the terrain means for a vehicle: ``terracone mobility``."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from terracone.cli.common import UNITS, emit_document, emit_json, parse_length


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
    from terracone.apps.mobility import run_mobility
    from terracone.io.outputs import check_outputs
    from terracone.report.mobility import mobility_text

    check_outputs(
        {"--out": out}, {"RESULTS": results_path, "--vehicle": vehicle_path, "--ci": ci_file}
    )
    choice = parse_critical_layer(critical_layer, units)
    lay = parse_layer(layer, units)
    problem = None
    if library_path:  # predicted again with the library as the prior
        from terracone.cli.common import load_library_prior
        from terracone.inverse.problem import Problem

        problem = Problem(library=load_library_prior(library_path))
    run = run_mobility(
        results_path, vehicle_path, passes=int(passes), layer=lay, choice=choice, soil=soil,
        remolding_index=remolding_index, by=None if by is None else [k.strip() for k in by.split(",")],
        ci_file=ci_file, file_units=file_units, problem=problem, units=units,
    )  # fmt: skip
    doc = run.as_dict(units, input=str(results_path))
    emit_document(doc, out=out, as_json=as_json, text=mobility_text)
    if not run.evaluated_any:
        sys.exit(1)


def go_map_cmd(
    mapdir, vehicle_path, passes, soil, critical_layer, layer, remolding_index, units,
    simulations, seed, workers, scheduler, out, as_json,
) -> None:  # fmt: skip
    """``terracone mobility MAPDIR``: P(GO) and wheel sinkage of every cell of a map."""
    from terracone.apps.go_map import run_go_map
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
    if workers is not None and scheduler is not None:
        raise click.UsageError("give --workers or --scheduler, not both")
    if workers is not None and workers < 1:
        raise click.BadParameter(f"must be >= 1, got {workers}", param_hint="'--workers'")
    run = run_go_map(mapdir, vehicle_path, out, units, passes=int(passes), soil=soil, choice=choice,
                     remolding_index=remolding_index, simulations=simulations, seed=seed,
                     workers=workers, scheduler=scheduler)  # fmt: skip
    doc = run.document
    for note in doc["notes"]:
        click.echo(f"note: {note}", err=True)
    if as_json:
        emit_json(doc)
    else:
        click.echo(go_map_text(doc, out))
    if not run.evaluated_any:
        sys.exit(1)
