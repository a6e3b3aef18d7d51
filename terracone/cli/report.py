"""Reports and worked examples: ``report``, ``reproduce`` and ``demo``."""

from __future__ import annotations

import click

from terracone.cli.common import UNITS


@click.command("demo")
@click.option("--units", type=UNITS, default="si", show_default=True)
@click.option(
    "--out",
    type=click.Path(file_okay=False),
    default=None,
    help="Also write the JSON results here.",
)
def demo_cmd(units, out):
    """Learn, predict and evaluate on the bundled synthetic LETE-sand example."""
    from terracone.apps.example import run_demo
    from terracone.report.text import demo_text

    click.echo(demo_text(run_demo(units=units, out=out)))


@click.command("report")
@click.argument("results", type=click.Path(exists=True))
@click.option(
    "--out", required=True, type=click.Path(dir_okay=False), help="The HTML file to write."
)
@click.option(
    "--map-by",
    type=click.Choice(["n", "kc", "kphi", "cc", "phic", "rmsd", "r2"]),
    default="n",
    show_default=True,
    help="Parameter that colours the map of located profiles (lon/lat in their metadata).",
)
def report_cmd(results, out, map_by):
    """One self-contained HTML report of predict, learn, evaluate, batch or reproduce results.

    Many profiles (predict JSON, a batch directory) get a summary of the field first, a map when
    they carry coordinates, a sortable table and a panel per profile.
    """
    from terracone.io.outputs import check_outputs
    from terracone.report import build_report

    check_outputs({"--out": out}, {"RESULTS": results})
    click.echo(f"wrote {build_report(results, out, map_by=map_by)}")


@click.command("reproduce")
@click.option(
    "--out", type=click.Path(file_okay=False), default="terracone-reproduce", show_default=True
)
@click.option("--quick", is_flag=True, help="Smaller grids and fewer draws (a smoke run).")
@click.option("--workers", type=int, default=None, help="Processes (default 2).")
def reproduce_cmd(out, quick, workers):
    """Re-create the paper's LETE sand and KRC case studies (synthetic data), with figures, tables and a report."""
    from terracone.report.reproduce import reproduce_report

    s = reproduce_report(out, quick=quick, workers=workers)
    click.echo(f"report: {s.report}")
    click.echo(f"figures and tables in {s.out_dir} ({s.seconds:.0f} s)")
