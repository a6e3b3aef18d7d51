"""Many profiles on many cores: ``terracone batch``."""

from __future__ import annotations

import sys

import click

from terracone.cli.common import fit_options, problem_from, reading_from, run_from


@click.command("batch")
@click.argument("input_path", metavar="INPUT", type=click.Path(exists=True))
@fit_options
@click.option(
    "--out",
    "out_dir",
    required=True,
    type=click.Path(file_okay=False),
    help="Output directory (Parquet parts).",
)
@click.option(
    "--workers", type=int, default=None, help="Local Dask worker processes (default: all cores)."
)
@click.option(
    "--scheduler",
    default=None,
    help="Address of a running dask.distributed scheduler, tcp://HOST:PORT.",
)
@click.option(
    "--resume", is_flag=True, help="Finish an interrupted run without redoing finished chunks."
)
@click.option("--quiet", is_flag=True, help="No progress bar.")
@click.option("--chunk-size", type=int, default=2000, show_default=True, help="Profiles per task.")
@click.option(
    "--uncertainty",
    is_flag=True,
    help="Posterior 90% intervals and identifiability labels (about 1 s per profile).",
)
@click.option(
    "--draws", type=int, default=1000, show_default=True, help="Posterior draws with --uncertainty."
)
@click.option(
    "--prior",
    type=click.Choice(["bounds", "calibration"]),
    default="bounds",
    show_default=True,
    help="Prior with --uncertainty: the bounds, or the calibration's (its values held in every "
    "draw, as in the fit; the same as bounds with --calibration).",
)
def batch_cmd(input_path, out_dir, workers, scheduler, resume, quiet, chunk_size, **opts):
    """Fit every profile of a CSV/Parquet file or directory on Dask; Parquet results per chunk."""
    from terracone.apps.batch import run_batch

    uncertainty = opts.pop("uncertainty")
    if opts["prior"] == "calibration" and not (opts["calibration"] or opts["terrain"]):
        raise click.UsageError("--prior calibration needs --calibration or --terrain")
    s = run_batch(
        input_path,
        out_dir,
        problem_from(opts, prior=opts["prior"]),
        run_from(opts, uncertainty=uncertainty, draws=opts["draws"]),
        reading=reading_from(opts),
        units=opts["units"],
        chunk_size=chunk_size,
        resume=resume,
        workers=workers,
        scheduler=scheduler,
        progress=False if quiet else None,
    )
    click.echo(
        f"{s.profiles} profiles: {s.profiles_ok} fitted, {s.profiles_error} with errors "
        f"({s.profiles_per_s:.0f} profiles/s, {s.wall_s:.1f} s); results in {s.out_dir}"
    )
    for p in s.problems:
        click.echo(f"terracone: {p}", err=True)
    for note in s.notes:
        click.echo(f"terracone: note: {note}", err=True)
    if s.profiles and not s.profiles_ok:
        # as predict: error profiles are normal, but a run that fitted none is a failure
        click.echo("terracone: no profile could be fitted (see the error column)", err=True)
    if not s.success or (s.profiles and not s.profiles_ok):
        sys.exit(1)
