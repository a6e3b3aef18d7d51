"""Forward models on the command line: ``terracone ci`` and ``terracone plate``."""

from __future__ import annotations

import click

from terracone.cli.common import UNITS, check_cone, echo_curve, parse_floats, shared
from terracone.physics.cone import CONES, cone_index
from terracone.physics.plate import plate_pressure

#: --kc, --kphi and --n of both commands.
bekker_options = shared(
    click.option("--kc", type=float, required=True, help="kc [kN/m^(n+1) or lb/in^(n+1)]."),
    click.option("--kphi", type=float, required=True, help="kphi [kN/m^(n+2) or lb/in^(n+2)]."),
    click.option("--n", "n", type=float, required=True, help="Sinkage exponent n [-]."),
)


@click.command("ci")
@bekker_options
@click.option(
    "--cc", type=float, default=0.0, show_default=True, help="Cone-terrain adhesion [kPa or psi]."
)
@click.option(
    "--phic", type=float, default=0.0, show_default=True, help="Cone-terrain friction angle [deg]."
)
@click.option(
    "--Kc",
    "Kc",
    type=float,
    default=None,
    help="Shear deformation parameter [m or in]; omit for fully mobilised shear.",
)
@click.option(
    "--model", type=click.Choice(["rm0", "rm1", "janosi"]), default="rm0", show_default=True
)
@click.option("--r-min", type=float, default=None, help="RM1 transition radius [m or in].")
@click.option(
    "--cone",
    default="asabe-large",
    show_default=True,
    callback=check_cone,
    help=f"{' | '.join(CONES)} | DIAMETER<unit>:ANGLE (20.27mm:30) | AREA<unit>2:ANGLE (5cm2:60)",
)
@click.option("--units", type=UNITS, default="si", show_default=True)
@click.option("--depths", required=True, help="Cone-base depths, comma separated [m or in].")
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
def ci_cmd(phic, Kc, depths, as_json, **params):
    """Cone index at given depths (eqs. (2-1) to (2-7))."""
    z = parse_floats(depths, "--depths")
    ci = cone_index(z, phic_deg=phic, K_cone=Kc, **params)
    echo_curve(("depth", "depth"), z, ("ci", "CI"), ci, params["units"], as_json)


@click.command("plate")
@bekker_options
@click.option("--radius", type=float, default=None, help="Circular plate radius [m or in].")
@click.option(
    "--width", type=float, default=None, help="Rectangular plate, smaller side [m or in]."
)
@click.option("--model", type=click.Choice(["rm0", "rm1"]), default="rm0", show_default=True)
@click.option("--r-min", type=float, default=None, help="RM1 transition radius [m or in].")
@click.option(
    "--plate-pair",
    default=None,
    help="R1,R2: plate radii of the RM1 secant (section 3.2) [m or in].",
)
@click.option("--units", type=UNITS, default="si", show_default=True)
@click.option("--sinkages", required=True, help="Sinkages, comma separated [m or in].")
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
def plate_cmd(plate_pair, sinkages, as_json, **params):
    """Plate pressure at given sinkages (Bekker, or RM1 of section 3.2)."""
    if (params["radius"] is None) == (params["width"] is None):
        raise click.UsageError("give exactly one of --radius and --width")
    s = parse_floats(sinkages, "--sinkages")
    pair = tuple(parse_floats(plate_pair, "--plate-pair")) if plate_pair else None
    if pair is not None and len(pair) != 2:
        raise click.BadParameter("--plate-pair: expected two radii R1,R2")
    p = plate_pressure(s, plate_pair=pair, **params)
    echo_curve(("sinkage", "sinkage"), s, ("pressure", "pressure"), p, params["units"], as_json)
