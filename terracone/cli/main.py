"""The ``terracone`` command group and its entry point; every sub-command is registered here."""

from __future__ import annotations

import click

from terracone import __version__
from terracone.cli.batch import batch_cmd
from terracone.cli.bevameter import fit_plates_cmd, fit_shear_cmd
from terracone.cli.common import Group
from terracone.cli.export import export_cmd
from terracone.cli.fit import design_cmd, evaluate_cmd, learn_cmd, predict_cmd, sites_cmd
from terracone.cli.forward import ci_cmd, plate_cmd
from terracone.cli.library import library_grp
from terracone.cli.map import map_cmd
from terracone.cli.match import match_cmd
from terracone.cli.mobility import mobility_cmd
from terracone.cli.report import demo_cmd, report_cmd, reproduce_cmd


@click.group(
    cls=Group, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100}
)
@click.version_option(__version__, prog_name="terracone")
def cli() -> None:
    """terracone: Bekker-Wong terrain parameters from cone penetrometer data.

    Forward models (ci, plate), the prediction and learning processes of
    Huang, Wong, Preston-Thomas and Jayakumar (predict, learn), evaluation
    against plate tests (evaluate), and a worked example (demo).

    Units: --units si (m, kPa, kN/m^(n+1), kN/m^(n+2)) or us (in, psi,
    lb/in^(n+1), lb/in^(n+2)); files carry their unit in every column name.
    """


def main() -> None:
    """Console-script entry point."""
    cli(prog_name="terracone")


for _command in (
    ci_cmd,
    plate_cmd,
    predict_cmd,
    learn_cmd,
    evaluate_cmd,
    sites_cmd,
    design_cmd,
    match_cmd,
    mobility_cmd,
    fit_plates_cmd,
    fit_shear_cmd,
    library_grp,
    export_cmd,
    map_cmd,
    batch_cmd,
    report_cmd,
    reproduce_cmd,
    demo_cmd,
):
    cli.add_command(_command)
