"""Fitting cone index profiles: ``predict``, ``learn``, ``evaluate``, ``sites`` and ``design``."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from terracone.cli.common import (
    UNITS,
    emit_document,
    emit_json,
    fit_options,
    json_options,
    library_option,
    load_prior,
    parse_length,
    parse_lengths,
    parse_r_min_range,
    problem_from,
    reading_from,
    reading_options,
    run_from,
    shared,
)
from terracone.data import TerrainParameters
from terracone.io.outputs import check_outputs
from terracone.report.text import (
    design_text,
    evaluate_text,
    layered_text,
    learn_text,
    library_prior_text,
    posterior_text,
    predict_text,
    sites_text,
)
from terracone.result import write_parquet


@click.command("predict")
@click.argument("ci_file", type=click.Path(dir_okay=False))
@fit_options
@click.option("--solver", type=click.Choice(["exact", "pso"]), default="exact", show_default=True)
@click.option("--seed", type=int, default=None, help="Seed of the particle swarm.")
@click.option(
    "--plates", default=None, help="Plate radii for predicted P-S curves, e.g. 1.5in,2.5in."
)
@click.option(
    "--file-units",
    type=UNITS,
    default=None,
    help="Unit system of an input that does not state its units (an SC900 export without its unit line).",
)
@click.option(
    "--uncertainty",
    is_flag=True,
    help="Posterior 90% intervals, identifiability labels and plate bands (emcee).",
)
@click.option(
    "--draws", type=int, default=2000, show_default=True, help="Posterior draws with --uncertainty."
)
@click.option(
    "--prior",
    default="bounds",
    show_default=True,
    help="bounds (uniform), or terrain:NAME: a stored calibration as the prior (the fit at its "
    "phic, cc and kc/kphi; with --uncertainty the posterior around them).",
)
@json_options[0]  # --out
@click.option(
    "--parquet",
    "parquet_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Also write the results as a Parquet table, with batch's columns (docs/results.md).",
)
@json_options[1]  # --json
def predict_cmd(ci_file, plates, file_units, out, parquet_path, as_json, **opts):
    """Predict kc, kphi, n, cc, phic from CI profiles (section 3.3.2)."""
    from terracone.apps.workflow import predict_profiles, sinkage_grid

    inputs = {"CI_FILE": ci_file, "--calibration": opts["calibration"]}
    check_outputs({"--out": out, "--parquet": parquet_path}, inputs)
    units, uncertainty = opts["units"], opts.pop("uncertainty")
    prior = load_prior(opts["prior"], opts["library"])
    problem = problem_from(opts, prior=prior, library_prior=True)
    if problem.library is not None and (uncertainty or opts["layers"] > 1):
        raise click.UsageError(
            "--library as the prior answers with the mixture of its calibrations (medians and "
            "90% intervals); --uncertainty and --layers do not apply to it"
        )
    settings = run_from(
        opts, solver=opts["solver"], seed=opts["seed"], uncertainty=uncertainty, draws=opts["draws"]
    )
    radii = parse_lengths(plates, units, "--plates", positive=True)
    items = reading_from(opts, file_units).read(ci_file, units)
    run = predict_profiles(
        items,
        problem,
        settings,
        plates=radii,
        sinkage=sinkage_grid(units),
        band_sinkage=sinkage_grid(units, 21),
    )
    results = run.results
    doc = run.as_dict(
        units, input=str(ci_file), depth_ref=opts["depth_ref"], depth_range=opts["depth_range"]
    )
    if out:
        emit_json(doc, out)
    if parquet_path:
        write_parquet(parquet_path, results, units)
    if as_json:
        emit_json(doc)
    elif problem.library is not None:
        click.echo(predict_text(results, units))
        click.echo(library_prior_text(results, units))
    else:
        click.echo(predict_text(results, units))
        posts = {r.id: r.posterior for r in results if r.posterior is not None}
        layered = {r.id: r.layered for r in results if r.layered is not None}
        if posts:
            click.echo(posterior_text(posts, units))
        if layered:
            click.echo(layered_text(layered, units))
    if not any(r.ok for r in results):
        if as_json:  # the table says it otherwise; stdout is the JSON document here
            r0 = results[0] if results else None
            first = f"; first, {r0.id}: {r0.error or r0.status}" if r0 else ""
            click.echo(
                f"terracone: no profile could be fitted ({len(results)} read){first}", err=True
            )
        sys.exit(1)


@click.command("learn")
@click.option(
    "--ci",
    "ci_file",
    required=True,
    type=click.Path(dir_okay=False),
    help="CI profiles of the terrain.",
)
@click.option(
    "--plates",
    "plates_file",
    required=True,
    type=click.Path(dir_okay=False),
    help="Plate tests of the terrain.",
)
@click.option("--model", type=click.Choice(["rm0", "rm1"]), default="rm1", show_default=True)
@click.option("--bounds", default=None, help="kc=LO:HI,... as for predict, in --units.")
@click.option("--units", type=UNITS, default="si", show_default=True)
@shared(*reading_options)
@click.option(
    "--r-min-range",
    default=None,
    help="Search range LO:HI of the RM1 transition radius r_min, in --units or with a unit "
    "suffix (default: 0.5 mm to 3 times the larger plate).",
)
@click.option(
    "--terrain-name", default=None, help="Label of the calibration (default: the CI file's stem)."
)
@click.option(
    "--save",
    type=click.Path(dir_okay=False),
    default=None,
    help="Save the calibration (JSON) here.",
)
@click.option(
    "--save-as", default=None, help="Store the calibration in the terrain library under this name."
)
@library_option
@click.option("--json", "as_json", is_flag=True)
def learn_cmd(ci_file, plates_file, r_min_range, terrain_name, save, save_as, as_json, **opts):
    """Learn r_min, cc, phic and the P-S parameters from CI and plate tests (section 3.3.1)."""
    from terracone.apps.calibrate import learn_calibration
    from terracone.inverse import Bounds
    from terracone.io import read_plate_tests

    check_outputs({"--save": save}, {"--ci": ci_file, "--plates": plates_file})
    units, model = opts["units"], opts["model"]
    rb = parse_r_min_range(r_min_range, units)
    if rb is not None and model != "rm1":
        raise click.BadParameter("--r-min-range: only with --model rm1")
    run = learn_calibration(
        reading_from(opts).read(ci_file, units, on_error="raise"),
        read_plate_tests(plates_file),
        terrain=save_as or terrain_name or Path(ci_file).stem,
        model=model,
        bounds=Bounds.parse(opts["bounds"], units),
        r_min_bounds=rb,
        save=save,
        save_as=save_as,
        library=opts["library"],
        sources={"ci_file": str(ci_file), "plates_file": str(plates_file)},
    )
    d = run.as_dict(units)
    if as_json:
        emit_json(d)
        return
    click.echo(learn_text(d, units))


@click.command("evaluate")
@click.option("--plates", "plates_file", required=True, type=click.Path(dir_okay=False))
@click.option("--kc", type=float, default=None)
@click.option("--kphi", type=float, default=None)
@click.option("--n", "n", type=float, default=None)
@click.option(
    "--params",
    "params_file",
    type=click.Path(dir_okay=False),
    default=None,
    help="JSON of predict or learn.",
)
@click.option("--units", type=UNITS, default="si", show_default=True)
@click.option("--json", "as_json", is_flag=True)
def evaluate_cmd(plates_file, kc, kphi, n, params_file, units, as_json):
    """R, R2, RMSD and CV of predicted against measured plate P-S curves (Tables 4-2, 4-4)."""
    from terracone.apps.bevameter import evaluate_plates

    if params_file and any(v is not None for v in (kc, kphi, n)):
        raise click.UsageError("give either --kc/--kphi/--n or --params, not both")
    if params_file:
        preds = params_file
    else:
        if kc is None or kphi is None or n is None:
            raise click.UsageError("give --kc, --kphi and --n, or --params")
        preds = [
            ("given", TerrainParameters.from_dict({"kc": kc, "kphi": kphi, "n": n, "units": units}))
        ]
    run = evaluate_plates(plates_file, preds)
    if as_json:
        emit_json(run.as_dict(units))
        return
    click.echo(evaluate_text(run.rows, units))


@click.command("sites")
@click.argument("ci_file", type=click.Path(dir_okay=False))
@fit_options
@click.option(
    "--by",
    "by",
    default=None,
    help="Metadata column(s) naming each profile's site, e.g. plot or plot,date.",
)
@click.option(
    "--radius",
    default=None,
    help="Group by distance: profiles with latitude/longitude within this radius (e.g. 10m).",
)
@click.option(
    "--plates",
    default=None,
    help="Plate radii of the site P-S curves, e.g. 1.5in,2in (default 3.75cm,5cm).",
)
@click.option(
    "--target-cv",
    type=float,
    default=0.1,
    show_default=True,
    help="Target CV of the site-mean plate pressure for profiles_needed.",
)
@click.option(
    "--bootstrap",
    type=click.IntRange(0, 1000),
    default=None,
    help="Bootstrap replicates of each push's estimation noise (0: linearised; "
    "default 40 without a calibration, 0 with one).",
)
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the bootstrap.")
@click.option(
    "--file-units",
    type=UNITS,
    default=None,
    help="Unit system of an input that does not state its units.",
)
@shared(*json_options)
def sites_cmd(
    ci_file, by, radius, plates, target_cv, bootstrap, seed, file_units, out, as_json, **opts
):
    """Site statistics: pushes pooled per site (median terrain, push-to-push CV, pushes needed)."""
    from terracone.apps.sites import DEFAULT_SITE_PLATES, pool_sites
    from terracone.inverse.sites.statistics import default_sinkages

    check_outputs({"--out": out}, {"CI_FILE": ci_file, "--calibration": opts["calibration"]})
    if by is None and radius is None:
        raise click.UsageError("give --by COLUMN or --radius L to group the profiles into sites")
    if opts["layers"] > 1:
        raise click.UsageError("sites pools one-layer fits; --layers is not supported here")
    if not target_cv > 0:
        raise click.BadParameter(f"--target-cv: must be > 0, got {target_cv}")
    units = opts["units"]
    run = pool_sites(
        reading_from(opts, file_units).read(ci_file, units),
        problem_from(opts, library_prior=True),
        by=by,
        radius=parse_length(radius, units, "--radius", positive=True) if radius else None,
        plates=parse_lengths(plates, units, "--plates", positive=True) or DEFAULT_SITE_PLATES,
        sinkage=default_sinkages(units),
        target_cv=target_cv,
        bootstrap=bootstrap,
        seed=seed,
        depth_range=opts["depth_range"],
        source=str(ci_file),
    )
    doc = run.as_dict(units, input=str(ci_file))
    emit_document(doc, out=out, as_json=as_json, text=lambda d: _sites_document_text(d, units))
    if not run.fitted_any:
        sys.exit(1)


def _sites_document_text(doc: dict, units: str) -> str:
    """The sites table, then the pushes in no site and the records not read."""
    lines = [sites_text(doc["sites"], units)]
    lines += [f"not in a site: {d['id']}: {d['reason']}" for d in doc["unassigned"]]
    lines += [f"not read: {e}" for e in doc["errors"]]
    return "\n".join(lines)


@click.command("design")
@click.argument("ci_file", type=click.Path(dir_okay=False))
@fit_options
@click.option(
    "--prior",
    default="bounds",
    show_default=True,
    help="bounds (uniform) or terrain:NAME (a stored calibration); --calibration also sets it.",
)
@click.option("--plates", required=True, help="Plate radii of the prediction, e.g. 5cm or 2in.")
@click.option(
    "--candidates",
    default="plate:5cm,plate:10cm,ci,shear",
    show_default=True,
    help="Candidate extra tests: plate:RADIUS, ci, shear.",
)
@click.option(
    "--plate-noise",
    type=float,
    default=0.05,
    show_default=True,
    help="Relative error of one plate reading.",
)
@json_options[1]  # --json
def design_cmd(ci_file, prior, plates, candidates, plate_noise, as_json, **opts):
    """Value of information: which one extra test narrows the predicted plate pressure most."""
    from terracone.apps.sites import plan_tests
    from terracone.inverse.sites.design import parse_candidates

    if opts["layers"] > 1:
        raise click.UsageError("design works on one-layer fits; --layers is not supported here")
    if not plate_noise > 0:
        raise click.BadParameter(f"--plate-noise: must be > 0, got {plate_noise}")
    if prior.startswith("terrain:") and (opts["calibration"] or opts["terrain"]):
        raise click.UsageError("give the calibration once: --prior terrain:NAME or --calibration")
    units = opts["units"]
    try:
        cands = parse_candidates(candidates, units)
    except ValueError as exc:
        raise click.BadParameter(str(exc)) from None
    run = plan_tests(
        reading_from(opts).read(ci_file, units),
        problem_from(opts, prior=load_prior(prior, opts["library"])),
        candidates=cands,
        plates=parse_lengths(plates, units, "--plates", positive=True),
        plate_noise=plate_noise,
        asked={"candidates": candidates, "plate_noise": plate_noise},
    )
    doc = run.as_dict(units, input=str(ci_file))
    if as_json:
        emit_json(doc)
    else:
        click.echo(design_text(doc["designs"], units))
    if not run.planned_any:
        sys.exit(1)
