"""``terracone map``: terrain maps (GeoTIFF, GeoParquet, map.json) from located pushes."""

from __future__ import annotations

import click

from terracone.cli.common import LEN_RE, UNITS, emit_json, parse_length


def parse_layers(text: str | None, units: str) -> list[tuple[float, float]] | None:
    """``--layers-ci 0:15cm,15:30cm`` -> [(0, 0.15), (0.15, 0.30)] [m].

    A bare LO takes HI's unit (``15:30cm``); bare pairs are in ``units``.
    """
    if not text:
        return None
    out = []
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        lo_s, sep, hi_s = part.partition(":")
        if not sep or not lo_s.strip() or not hi_s.strip():
            raise click.BadParameter(f"--layers-ci: expected LO:HI (e.g. 0:15cm), got {part!r}")
        unit = LEN_RE.match(hi_s)
        if unit and unit.group(2) and LEN_RE.match(lo_s) and not LEN_RE.match(lo_s).group(2):
            lo_s += unit.group(2)  # 15:30cm is 15 cm to 30 cm
        lo = parse_length(lo_s, units, "--layers-ci")
        hi = parse_length(hi_s, units, "--layers-ci")
        if not 0 <= lo < hi:
            raise click.BadParameter(f"--layers-ci: need 0 <= LO < HI, got {part!r}")
        out.append((lo, hi))
    return out or None


def _summary(doc: dict, out: str) -> str:
    from terracone.report.text import table

    rows = []
    for name, q in doc["quantities"].items():
        if q.get("skipped"):
            rows.append([name, q["units"], q["pushes"], "not mapped", None, None, None, None, 0])
            continue
        vg, cv = q["variogram"], q["cross_validation"]
        shape = "pure nugget" if not vg["structure"] else f"{vg['nugget'] / vg['sill']:.2f}"
        rows.append(
            [
                name, q["units"], q["pushes"], shape, vg["range"], cv["rmse"],
                cv["mean_standardised_error"], cv["coverage_90"], q["cells"]["masked"],
            ]
        )  # fmt: skip
    head = [
        f"map of {doc['pushes']['located']} located pushes in {doc['crs']} ({doc['crs_name']}): "
        f"{doc['crs_note']}",
        f"cells of {doc['resolution']:g} m ({doc['resolution_note']}), "
        f"{doc['grid']['width']} x {doc['grid']['height']}",
        "",
        table(
            [
                "quantity",
                "units",
                "pushes",
                "nugget/sill",
                "range [m]",
                "LOO RMSE",
                "mean std. error",
                "LOO 90% coverage",
                "masked cells",
            ],
            rows,
        ),  # fmt: skip
        "",
        f"wrote {out}: "
        + ", ".join(q["file"] for q in doc["quantities"].values() if q["file"])
        + ", points.parquet, cells.parquet, map.json",
    ]
    return "\n".join(head)


@click.command("map")
@click.argument("results", type=click.Path(exists=True))
@click.option("--out", required=True, type=click.Path(file_okay=False), help="Output directory.")
@click.option("--plate", default=None, help="Plate radius of the plate_pressure map (e.g. 10cm).")
@click.option("--sinkage", default=None, help="Sinkage of the plate_pressure map (e.g. 5cm).")
@click.option(
    "--layers-ci",
    default=None,
    help="Depth layers of mean CI maps, e.g. 0:15cm,15:30cm (default: one layer over the "
    "depths every push reaches).",
)
@click.option(
    "--resolution",
    default=None,
    help="Cell size, e.g. 5m (default: half the median distance between neighbouring pushes).",
)
@click.option(
    "--crs", default=None, help="Projected CRS in metres, e.g. EPSG:32615 (default: UTM zone)."
)
@click.option("--units", type=UNITS, default="si", show_default=True)
@click.option(
    "--library",
    "library_path",
    default=None,
    help="Predict the pushes again with this library's calibrations as the prior (their CI "
    "from RESULTS, a predict JSON; docs/library.md).",
)
@click.option("--json", "as_json", is_flag=True, help="Print map.json.")
@click.option(
    "--force",
    is_flag=True,
    help="Replace --out whole even when it holds files that are not an earlier map's "
    "(they are deleted); an earlier map is always replaced whole.",
)
def map_cmd(
    results, out, plate, sinkage, layers_ci, resolution, crs, units, library_path, as_json, force
):
    """Kriged maps of plate pressure, n and mean CI, with 90% intervals, from located pushes.

    RESULTS is a predict JSON, a predict Parquet file or a batch output directory whose profiles
    carry lat/lon.  Writes one GeoTIFF per quantity (bands median, lo, hi of the local mean,
    point_lo, point_hi of the value at a point), points.parquet
    (GeoParquet), cells.parquet (each cell's kc, kphi, n for simulators) and map.json, with the
    leave-one-out cross-validation of each map.  DIR then holds this map only: an earlier
    map there is replaced whole, any other non-empty directory is refused unless --force.
    """
    from terracone.apps.maps import is_map_directory, run_map
    from terracone.io.outputs import check_outputs, check_run_directory

    check_outputs({"--out": out}, {"RESULTS": results}, directories=("--out",))
    check_run_directory(out, what="terracone map", is_run=is_map_directory, force=force)

    if (plate is None) != (sinkage is None):
        raise click.UsageError("give --plate and --sinkage together")
    plate_si = None
    if plate is not None:
        plate_si = (
            parse_length(plate, units, "--plate"),
            parse_length(sinkage, units, "--sinkage"),
        )
        if not (plate_si[0] > 0 and plate_si[1] > 0):
            raise click.BadParameter("--plate and --sinkage must be > 0")
    layers = parse_layers(layers_ci, units)
    res = parse_length(resolution, "si", "--resolution", positive=True) if resolution else None
    problem = None
    if library_path:  # the library as the prior, from the CI the results keep
        from terracone.cli.common import load_library_prior
        from terracone.inverse.problem import Problem

        problem = Problem(library=load_library_prior(library_path))
    run = run_map(results, out, plate=plate_si, layers=layers, resolution=res, crs=crs,
                  units=units, problem=problem, force=force)  # fmt: skip
    for note in run.notes:
        click.echo(f"note: {note}", err=True)
    if as_json:
        emit_json(run.document)
    else:
        click.echo(_summary(run.document, out))
