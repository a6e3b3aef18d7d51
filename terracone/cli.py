"""The ``terracone`` command line.

Every sub-command reads files in terracone's formats (units in the column
names) or instrument exports, computes in SI, and prints a table, or JSON
with ``--json`` (a stable contract).  Bad input ends with one message naming
the file, profile, row and column, and a non-zero exit; never a traceback.
"""

from __future__ import annotations

import json
import os
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import click
import numpy as np

from terracone import __version__
from terracone.data import InputError, TerrainParameters
from terracone.physics import units as u
from terracone.physics.cone import CONES, cone_index
from terracone.physics.plate import plate_pressure
from terracone.report.text import (
    curve_text,
    design_text,
    evaluate_text,
    learn_text,
    library_text,
    plate_fit_text,
    predict_text,
    shear_fit_text,
    sites_text,
)
from terracone.report.text import layered_text as _layered_text  # the names predict_cmd prints with
from terracone.report.text import posterior_text as _posterior_text

_UNITS = click.Choice(["si", "us"])
_LEN_RE = re.compile(r"^\s*([-+0-9.eE]+)\s*(m|cm|mm|in)?\s*$")


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------


def _floats(text: str, what: str) -> np.ndarray:
    try:
        vals = [float(s) for s in text.split(",") if s.strip()]
    except ValueError as exc:
        raise click.BadParameter(f"{what}: expected comma-separated numbers, got {text!r}") from exc
    if not vals:
        raise click.BadParameter(f"{what}: no values given")
    return np.array(vals)


def _length_si(text: str, units: str, what: str) -> float:
    """'1.5in' or '3.75cm' or a bare number in the unit system's length unit -> m."""
    m = _LEN_RE.match(text)
    if not m:
        raise click.BadParameter(
            f"{what}: expected a length such as 0.05, 5cm or 2in, got {text!r}"
        )
    v = float(m.group(1))
    if m.group(2):
        return v * u.LENGTH_UNITS[m.group(2)]
    return float(u.length_to_si(v, units))


def _lengths_si(text: str | None, units: str, what: str) -> list[float]:
    if not text:
        return []
    return [_length_si(s, units, what) for s in text.split(",") if s.strip()]


def _depth_range(text: str | None, units: str) -> tuple[float | None, float | None]:
    """'LO:HI' (either side may be empty; numbers with a unit suffix or in --units) -> m."""
    if not text:
        return None, None
    if ":" not in text:
        raise click.BadParameter(f"--depth-range: expected LO:HI, got {text!r}")
    lo_s, hi_s = text.split(":", 1)
    lo = _length_si(lo_s, units, "--depth-range") if lo_s.strip() else None
    hi = _length_si(hi_s, units, "--depth-range") if hi_s.strip() else None
    if lo is not None and hi is not None and lo >= hi:
        raise click.BadParameter(f"--depth-range: LO must be below HI, got {text!r}")
    return lo, hi


def _r_min_range(text: str | None, units: str) -> tuple[float, float] | None:
    """'LO:HI' of r_min (numbers with a unit suffix or in --units) -> m."""
    if not text:
        return None
    if ":" not in text:
        raise click.BadParameter(f"--r-min-range: expected LO:HI, got {text!r}")
    lo_s, hi_s = text.split(":", 1)
    if not lo_s.strip() or not hi_s.strip():
        raise click.BadParameter(f"--r-min-range: give both LO and HI, got {text!r}")
    lo = _length_si(lo_s, units, "--r-min-range")
    hi = _length_si(hi_s, units, "--r-min-range")
    if not (0 < lo <= hi):
        raise click.BadParameter(f"--r-min-range: need 0 < LO <= HI, got {text!r}")
    return lo, hi


def _windowed(items, rng: tuple[float | None, float | None], units: str):
    """Restrict profiles to a depth window, with a note; reader errors pass through.

    The window is the package's one depth window,
    :func:`terracone.data.depth_window` (through :meth:`CIProfile.window`,
    as :meth:`ProfileSet.window` and ``terracone batch`` apply it).
    """
    lo, hi = rng
    if lo is None and hi is None:
        return items
    a = "-" if lo is None else f"{float(u.length_from_si(lo, units)):g}"
    b = "-" if hi is None else f"{float(u.length_from_si(hi, units)):g}"
    span = f"depth window {a}:{b} {u.length_unit(units)}"
    out = []
    for it in items:
        if isinstance(it, InputError):
            out.append(it)
            continue
        w = it.window(lo, hi)
        w.notes = list(it.notes) + [f"{span}: {len(w)} of {len(it)} points"]
        out.append(w)
    return out


def _emit_json(obj: Any, out: str | None = None) -> None:
    """Print a JSON document, or write it to ``out`` (terracone.result's one JSON writer)."""
    from terracone.result import dumps

    text = dumps(obj)
    if out:
        Path(out).write_text(text + "\n")
    else:
        click.echo(text)


def _curve_out(xkey, x, ykey, y, units: str, as_json: bool) -> None:
    """A length-pressure curve as JSON ``{x, y, "units"}`` or as a two-column table."""
    if as_json:
        _emit_json(
            {xkey[0]: np.asarray(x).tolist(), ykey[0]: np.asarray(y).tolist(), "units": units}
        )
        return
    heads = [f"{xkey[1]} [{u.length_unit(units)}]", f"{ykey[1]} [{u.pressure_unit(units)}]"]
    click.echo(curve_text(heads, x, y))


def os_error_text(exc: OSError) -> str:
    """A file system error in words: what could not be done to which file, and why.

    ``[Errno 2] No such file or directory: 'out/x.json'`` becomes
    ``cannot use out/x.json: no such file or directory (folder out does not exist)``.
    """
    name = exc.filename
    if name is None:
        return str(exc)
    why = (exc.strerror or str(exc)).lower()
    parent = Path(os.fspath(name)).parent
    if isinstance(exc, FileNotFoundError) and str(parent) not in ("", ".") and not parent.exists():
        why += f" (folder {parent} does not exist)"
    return f"cannot use {os.fspath(name)}: {why}"


class _Group(click.Group):
    """Turns every error into one message and a non-zero exit."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except (click.exceptions.ClickException, click.exceptions.Exit, click.exceptions.Abort):
            raise
        except InputError as exc:
            raise click.ClickException(str(exc)) from None
        except KeyError as exc:
            raise click.ClickException(str(exc.args[0]) if exc.args else repr(exc)) from None
        except OSError as exc:
            raise click.ClickException(os_error_text(exc)) from None
        except ValueError as exc:
            raise click.ClickException(str(exc)) from None
        except Exception as exc:  # pragma: no cover - a bug, but no traceback for users
            if os.environ.get("TERRACONE_DEBUG"):
                raise
            raise click.ClickException(
                f"internal error ({type(exc).__name__}: {exc}); set TERRACONE_DEBUG=1 for a traceback"
            ) from None


@click.group(
    cls=_Group, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100}
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


# ---------------------------------------------------------------------------
# forward models
# ---------------------------------------------------------------------------


@cli.command("ci")
@click.option("--kc", type=float, required=True, help="kc [kN/m^(n+1) or lb/in^(n+1)].")
@click.option("--kphi", type=float, required=True, help="kphi [kN/m^(n+2) or lb/in^(n+2)].")
@click.option("--n", "n", type=float, required=True, help="Sinkage exponent n [-].")
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
    help=f"{' | '.join(CONES)} | DIAMETER<unit>:ANGLE (20.27mm:30) | AREA<unit>2:ANGLE (5cm2:60)",
)
@click.option("--units", type=_UNITS, default="si", show_default=True)
@click.option("--depths", required=True, help="Cone-base depths, comma separated [m or in].")
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
def ci_cmd(kc, kphi, n, cc, phic, Kc, model, r_min, cone, units, depths, as_json):
    """Cone index at given depths (eqs. (2-1) to (2-7))."""
    z = _floats(depths, "--depths")
    ci = cone_index(
        z,
        kc=kc,
        kphi=kphi,
        n=n,
        cc=cc,
        phic=phic,
        Kc=Kc,
        model=model,
        r_min=r_min,
        cone=cone,
        units=units,
    )
    _curve_out(("depth", "depth"), z, ("ci", "CI"), ci, units, as_json)


@cli.command("plate")
@click.option("--kc", type=float, required=True, help="kc [kN/m^(n+1) or lb/in^(n+1)].")
@click.option("--kphi", type=float, required=True, help="kphi [kN/m^(n+2) or lb/in^(n+2)].")
@click.option("--n", "n", type=float, required=True, help="Sinkage exponent n [-].")
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
@click.option("--units", type=_UNITS, default="si", show_default=True)
@click.option("--sinkages", required=True, help="Sinkages, comma separated [m or in].")
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
def plate_cmd(kc, kphi, n, radius, width, model, r_min, plate_pair, units, sinkages, as_json):
    """Plate pressure at given sinkages (Bekker, or RM1 of section 3.2)."""
    if (radius is None) == (width is None):
        raise click.UsageError("give exactly one of --radius and --width")
    s = _floats(sinkages, "--sinkages")
    pair = tuple(_floats(plate_pair, "--plate-pair")) if plate_pair else None
    if pair is not None and len(pair) != 2:
        raise click.BadParameter("--plate-pair: expected two radii R1,R2")
    p = plate_pressure(
        s,
        kc=kc,
        kphi=kphi,
        n=n,
        radius=radius,
        width=width,
        model=model,
        r_min=r_min,
        units=units,
        plate_pair=pair,
    )
    _curve_out(("sinkage", "sinkage"), s, ("pressure", "pressure"), p, units, as_json)


# ---------------------------------------------------------------------------
# prediction, learning, evaluation
# ---------------------------------------------------------------------------


def _shared(*decorators):
    """Apply several click decorators as one (options common to predict and batch)."""

    def apply(f):
        for d in reversed(decorators):
            f = d(f)
        return f

    return apply


_wide_options = (
    click.option(
        "--depth-unit",
        type=click.Choice(list(u.LENGTH_UNITS)),
        default=None,
        help="Wide tables: unit of depth headers written as bare numbers.",
    ),
    click.option(
        "--ci-unit",
        type=click.Choice(["kpa", "mpa", "psi"]),
        default=None,
        help="Wide tables: unit of the readings, unless the file states it.",
    ),
)

#: --out and --json of a command that writes one JSON document.
_json_options = (
    click.option(
        "--out", type=click.Path(dir_okay=False), default=None, help="Write the JSON here too."
    ),
    click.option("--json", "as_json", is_flag=True, help="Print JSON."),
)

_fit_options = _shared(
    click.option("--model", type=click.Choice(["rm0", "rm1"]), default="rm0", show_default=True),
    click.option(
        "--r-min",
        default=None,
        help="RM1 transition radius (e.g. 0.01, 1cm, 0.4in; bare numbers in --units).",
    ),
    click.option(
        "--calibration",
        type=click.Path(dir_okay=False),
        default=None,
        help="Calibration JSON from `terracone learn --save`.",
    ),
    click.option(
        "--terrain", default=None, help="Use a calibration stored in the terrain library."
    ),
    click.option(
        "--library",
        default=None,
        help="Terrain library path (default: $TERRACONE_LIBRARY or the user data dir).",
    ),
    click.option(
        "--bounds", default=None, help="kc=LO:HI,kphi=LO:HI,n=LO:HI,cc=LO:HI,phic=LO:HI in --units."
    ),
    click.option("--units", type=_UNITS, default="si", show_default=True),
    click.option(
        "--cone",
        default="asabe-large",
        show_default=True,
        help="Cone when the input does not name one: a name (asabe-large, asabe-small, "
        "penetrologger-1cm2|2cm2|3.33cm2|5cm2), DIAMETER:ANGLE (20.27mm:30) or AREA:ANGLE (5cm2:60).",
    ),
    click.option(
        "--format",
        "fmt",
        type=click.Choice(["csv", "sc900", "wide"]),
        default=None,
        help="Input format (detected by default); wide: one row per push, one column per depth.",
    ),
    *_wide_options,
    click.option(
        "--depth-ref",
        type=click.Choice(["base", "tip"]),
        default="base",
        show_default=True,
        help="Whether input depths are those of the cone base or tip.",
    ),
    click.option(
        "--depth-range",
        default=None,
        help="Fit only LO:HI of base depth (e.g. 0.05:0.30, 5cm:30cm; bare numbers in --units).",
    ),
    click.option(
        "--layers",
        type=click.IntRange(1, 4),
        default=1,
        show_default=True,
        help="Also fit a terrain of this many layers (interfaces fitted) and compare by BIC.",
    ),
)


def _read_profiles(
    path, cone, fmt, depth_ref, collect=True, units=None, depth_unit=None, ci_unit=None
):
    from terracone.io import read_ci_profiles

    return read_ci_profiles(
        path,
        cone=cone,
        depth_ref=depth_ref,
        format=fmt,
        on_error="collect" if collect else "raise",
        units=units,
        depth_unit=depth_unit,
        ci_unit=ci_unit,
    )


def _fit_items(ci_file, cone, fmt, depth_ref, depth_range, units, file_units, depth_unit, ci_unit):
    """CI profiles of a fit command, read and cut to --depth-range (bad ones as InputError)."""
    return _windowed(
        _read_profiles(
            ci_file,
            cone,
            fmt,
            depth_ref,
            units=file_units,
            depth_unit=depth_unit,
            ci_unit=ci_unit,
        ),
        _depth_range(depth_range, units),
        units,
    )


@dataclass
class _FitArgs:
    """The parsed ``_fit_options`` of a command (lengths in m)."""

    model: str
    r_min: float | None
    calibration: Any
    bounds: Any
    units: str
    layers: int
    depth_range: str | None
    reading: dict[str, Any]

    def items(self, ci_file: str, file_units: str | None = None) -> list[Any]:
        """The command's CI profiles, cut to --depth-range (bad ones as InputError)."""
        r = self.reading
        return _fit_items(
            ci_file, r["cone"], r["fmt"], r["depth_ref"], self.depth_range, self.units,
            file_units, r["depth_unit"], r["ci_unit"],
        )  # fmt: skip

    def check_r_min(self, calibration: Any) -> None:
        if self.model == "rm1" and self.r_min is None and calibration is None:
            raise click.UsageError("--model rm1 needs --r-min (or a --calibration / --terrain)")


def _fit_args(opts: dict[str, Any]) -> _FitArgs:
    """Parse the ``_fit_options`` given to a command as ``**opts``."""
    from terracone.inverse import Bounds

    units = opts["units"]
    return _FitArgs(
        model=opts["model"],
        bounds=Bounds.parse(opts["bounds"], units),
        r_min=_length_si(opts["r_min"], units, "--r-min") if opts["r_min"] else None,
        calibration=_load_calibration(opts["calibration"], opts["terrain"], opts["library"]),
        units=units,
        layers=opts["layers"],
        depth_range=opts["depth_range"],
        reading={k: opts[k] for k in ("cone", "fmt", "depth_ref", "depth_unit", "ci_unit")},
    )


def _load_calibration(calibration: str | None, terrain: str | None, library: str | None):
    from terracone.inverse.learning.learn import Calibration

    if calibration and terrain:
        raise click.UsageError("give at most one of --calibration and --terrain")
    if calibration:
        return Calibration.load(calibration)
    if terrain:
        from terracone.apps.library import Library

        rec = Library(library).get(terrain)
        return Calibration.from_library_record(rec)
    return None


def _prior(prior: str, library: str | None):
    """--prior: "bounds", or the calibration stored in the library as terrain:NAME."""
    from terracone.apps.library import Library
    from terracone.inverse.learning.learn import Calibration

    if prior == "bounds":
        return "bounds"
    if prior.startswith("terrain:"):
        with Library(library) as lib:
            return Calibration.from_library_record(lib.get(prior.split(":", 1)[1]))
    raise click.BadParameter(f"--prior: expected bounds or terrain:NAME, got {prior!r}")


@cli.command("predict")
@click.argument("ci_file", type=click.Path(dir_okay=False))
@_fit_options
@click.option("--solver", type=click.Choice(["exact", "pso"]), default="exact", show_default=True)
@click.option("--seed", type=int, default=None, help="Seed of the particle swarm.")
@click.option(
    "--plates", default=None, help="Plate radii for predicted P-S curves, e.g. 1.5in,2.5in."
)
@click.option(
    "--file-units",
    type=_UNITS,
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
    help="Prior with --uncertainty: bounds (uniform) or terrain:NAME (a stored calibration).",
)
@click.option(
    "--out", type=click.Path(dir_okay=False), default=None, help="Write the JSON here too."
)
@click.option(
    "--parquet",
    "parquet_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Also write the results as a Parquet table, with batch's columns (docs/results.md).",
)
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
def predict_cmd(
    ci_file,
    model,
    r_min,
    calibration,
    terrain,
    library,
    solver,
    seed,
    bounds,
    units,
    plates,
    cone,
    fmt,
    depth_ref,
    depth_range,
    file_units,
    uncertainty,
    draws,
    prior,
    layers,
    out,
    parquet_path,
    as_json,
    depth_unit,
    ci_unit,
):
    """Predict kc, kphi, n, cc, phic from CI profiles (section 3.3.2)."""
    from terracone.apps.workflow import predict_profiles, sinkage_grid
    from terracone.inverse import Bounds

    b = Bounds.parse(bounds, units)
    rm = _length_si(r_min, units, "--r-min") if r_min else None
    if model == "rm1" and rm is None and not (calibration or terrain):
        raise click.UsageError("--model rm1 needs --r-min (or a --calibration / --terrain)")
    cal = _load_calibration(calibration, terrain, library)
    radii = _lengths_si(plates, units, "--plates")
    items = _fit_items(
        ci_file, cone, fmt, depth_ref, depth_range, units, file_units, depth_unit, ci_unit
    )
    run = predict_profiles(
        items,
        model=model,
        r_min=rm,
        calibration=cal,
        solver=solver,
        bounds=b,
        seed=seed,
        plates=radii,
        sinkage=sinkage_grid(units),
        uncertainty=uncertainty,
        prior=_prior(prior, library) if uncertainty else "bounds",
        draws=draws,
        band_sinkage=sinkage_grid(units, 21),
        layers=layers,
    )
    results = run.results
    doc = run.as_dict(units, input=str(ci_file), depth_ref=depth_ref, depth_range=depth_range)
    if out:
        _emit_json(doc, out)
    if parquet_path:
        from terracone.result import write_parquet

        write_parquet(parquet_path, results, units)
    if as_json:
        _emit_json(doc)
    else:
        click.echo(predict_text(results, units))
        if run.posteriors:
            click.echo(_posterior_text(run.posteriors, units))
        if run.layered:
            click.echo(_layered_text(run.layered, units))
    if not any(r.ok for r in results):
        sys.exit(1)


@cli.command("learn")
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
@click.option("--units", type=_UNITS, default="si", show_default=True)
@click.option(
    "--cone",
    default="asabe-large",
    show_default=True,
    help="Cone when the input does not name one (as predict --cone).",
)
@click.option("--format", "fmt", type=click.Choice(["csv", "sc900", "wide"]), default=None)
@_shared(*_wide_options)
@click.option("--depth-ref", type=click.Choice(["base", "tip"]), default="base", show_default=True)
@click.option(
    "--depth-range", default=None, help="Fit only LO:HI of the CI profiles (as for predict)."
)
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
@click.option(
    "--library",
    default=None,
    help="Terrain library path (default: $TERRACONE_LIBRARY or the user data dir).",
)
@click.option("--json", "as_json", is_flag=True)
def learn_cmd(
    ci_file,
    plates_file,
    model,
    bounds,
    units,
    cone,
    fmt,
    depth_ref,
    depth_range,
    r_min_range,
    terrain_name,
    save,
    save_as,
    library,
    as_json,
    depth_unit,
    ci_unit,
):
    """Learn r_min, cc, phic and the P-S parameters from CI and plate tests (section 3.3.1)."""
    from terracone.inverse import Bounds
    from terracone.inverse.learning.learn import learn
    from terracone.io import read_plate_tests

    profiles = _read_profiles(
        ci_file, cone, fmt, depth_ref, collect=False, depth_unit=depth_unit, ci_unit=ci_unit
    )
    profiles = _windowed(profiles, _depth_range(depth_range, units), units)
    plates = read_plate_tests(plates_file)
    rb = _r_min_range(r_min_range, units)
    if rb is not None and model != "rm1":
        raise click.BadParameter("--r-min-range: only with --model rm1")
    res = learn(profiles, plates, model=model, bounds=Bounds.parse(bounds, units), r_min_bounds=rb)
    label = save_as or terrain_name or Path(ci_file).stem
    cal = res.calibration(
        label, cone=profiles[0].cone.name, ci_file=str(ci_file), plates_file=str(plates_file)
    )
    if save:
        cal.save(save)
    if save_as:
        from terracone.apps.library import Library

        with Library(library) as lib:
            lib.add(save_as, "calibration", cal.library_params(), cal.provenance, replace=True)
    d = res.as_dict(units)
    d.update(
        {
            "terrain": label,
            "terracone": __version__,
            "command": "learn",
            "saved": save,
            "saved_as": save_as,
        }
    )
    if as_json:
        _emit_json(d)
        return
    click.echo(learn_text(d, units))


@cli.command("evaluate")
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
@click.option("--units", type=_UNITS, default="si", show_default=True)
@click.option("--json", "as_json", is_flag=True)
def evaluate_cmd(plates_file, kc, kphi, n, params_file, units, as_json):
    """R, R2, RMSD and CV of predicted against measured plate P-S curves (Tables 4-2, 4-4)."""
    from terracone.inverse.evaluate import cross_table, parameters_from_json
    from terracone.io import read_plate_tests

    if params_file and any(v is not None for v in (kc, kphi, n)):
        raise click.UsageError("give either --kc/--kphi/--n or --params, not both")
    if params_file:
        preds = parameters_from_json(params_file)
    else:
        if kc is None or kphi is None or n is None:
            raise click.UsageError("give --kc, --kphi and --n, or --params")
        preds = [
            ("given", TerrainParameters.from_dict({"kc": kc, "kphi": kphi, "n": n, "units": units}))
        ]
    plates = read_plate_tests(plates_file)
    rows = cross_table(preds, plates)
    if as_json:
        _emit_json({"plates": [r.as_dict(units) for r in rows], "units": units})
        return
    click.echo(evaluate_text(rows, units))


@cli.command("demo")
@click.option("--units", type=_UNITS, default="si", show_default=True)
@click.option(
    "--out",
    type=click.Path(file_okay=False),
    default=None,
    help="Also write the JSON results here.",
)
def demo_cmd(units, out):
    """Learn, predict and evaluate on the bundled synthetic LETE-sand example."""
    from terracone.apps.example import run_demo

    click.echo(run_demo(units=units, out=out))


# ---------------------------------------------------------------------------
# bevameter fits, terrain library, export
# ---------------------------------------------------------------------------


def _store(library: str | None, name: str, kind: str, params: dict, provenance: dict) -> None:
    from terracone.apps.library import Library

    with Library(library) as lib:
        lib.add(name, kind, params, provenance, replace=True)


@cli.command("fit-plates")
@click.argument("plates_file", type=click.Path(dir_okay=False))
@click.option(
    "--method",
    type=click.Choice(["wong", "loglog", "nonlinear"]),
    default="wong",
    show_default=True,
)
@click.option("--units", type=_UNITS, default="si", show_default=True)
@click.option(
    "--save-as", default=None, help="Store the fit in the terrain library under this name."
)
@click.option("--library", default=None, help="Terrain library path.")
@click.option("--json", "as_json", is_flag=True)
def fit_plates_cmd(plates_file, method, units, save_as, library, as_json):
    """Fit p = k z^n per plate test, and kc, kphi from k = kc/b + kphi (two or more sizes)."""
    from terracone.inverse.bevameter.plates import fit_plates
    from terracone.io import read_plate_tests

    fit = fit_plates(read_plate_tests(plates_file), method=method)
    if save_as:
        from terracone.apps.library import make_provenance

        _store(
            library,
            save_as,
            "bevameter-fit",
            fit.params(),
            make_provenance(source=str(plates_file), method=f"fit-plates ({method})"),
        )
    d = fit.as_dict(units)
    d["saved_as"] = save_as
    if as_json:
        _emit_json(d)
        return
    click.echo(plate_fit_text(d, units))


@cli.command("fit-shear")
@click.argument("shear_file", type=click.Path(dir_okay=False))
@click.option("--units", type=_UNITS, default="si", show_default=True)
@click.option(
    "--save-as", default=None, help="Store the fit in the terrain library under this name."
)
@click.option("--library", default=None, help="Terrain library path.")
@click.option("--json", "as_json", is_flag=True)
def fit_shear_cmd(shear_file, units, save_as, library, as_json):
    """Fit Janosi-Hanamoto tau = (c + sigma tan phi)(1 - exp(-j/K)) to shear tests."""
    from terracone.inverse.bevameter.shear import fit_shear
    from terracone.io import read_shear_tests

    fit = fit_shear(read_shear_tests(shear_file))
    if save_as:
        from terracone.apps.library import make_provenance

        _store(
            library,
            save_as,
            "bevameter-fit",
            fit.params(),
            make_provenance(source=str(shear_file), method="fit-shear"),
        )
    d = fit.as_dict(units)
    d["saved_as"] = save_as
    if as_json:
        _emit_json(d)
        return
    click.echo(shear_fit_text(d, units))


@cli.group("library", cls=_Group)
@click.option(
    "--library",
    "library_path",
    default=None,
    help="Library path (default: $TERRACONE_LIBRARY or the user data dir).",
)
@click.pass_context
def library_grp(ctx, library_path):
    """The terrain library: reference terrains, calibrations, bevameter fits."""
    ctx.obj = {"library": library_path}


@library_grp.command("list")
@click.option(
    "--kind", default=None, help="Only this kind (reference, calibration, bevameter-fit)."
)
@click.option("--json", "as_json", is_flag=True)
@click.pass_context
def library_list(ctx, kind, as_json):
    """List the stored terrains."""
    from terracone.apps.library import Library

    with Library(ctx.obj["library"]) as lib:
        recs = lib.list(kind)
    if as_json:
        _emit_json([r.to_dict() for r in recs])
        return
    click.echo(library_text(recs))


@library_grp.command("show")
@click.argument("name")
@click.pass_context
def library_show(ctx, name):
    """Show one terrain (JSON, SI)."""
    from terracone.apps.library import Library

    with Library(ctx.obj["library"]) as lib:
        _emit_json(lib.get(name).to_dict())


@library_grp.command("add")
@click.argument("name")
@click.option("--kind", default="user", show_default=True)
@click.option(
    "--param",
    "params",
    multiple=True,
    help="KEY=VALUE in SI (kc, kphi, n, c_kpa, phi_deg, K_m, cc, phic_deg, r_min, ...).",
)
@click.option(
    "--from-json",
    type=click.Path(dir_okay=False),
    default=None,
    help="Parameters from a JSON object (SI).",
)
@click.option("--source", default=None, help="Provenance: where the values come from.")
@click.option("--replace", is_flag=True)
@click.pass_context
def library_add(ctx, name, kind, params, from_json, source, replace):
    """Add a terrain."""
    from terracone.apps.library import Library, make_provenance

    p: dict[str, Any] = {}
    if from_json:
        try:
            doc = json.loads(Path(from_json).read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise ValueError(f"file {from_json}: cannot read JSON ({exc})") from None
        if not isinstance(doc, dict):
            raise ValueError(f"file {from_json}: expected a JSON object of parameters")
        p.update(doc)
    for kv in params:
        if "=" not in kv:
            raise click.BadParameter(f"--param: expected KEY=VALUE, got {kv!r}")
        k, v = kv.split("=", 1)
        try:
            p[k.strip()] = float(v)
        except ValueError:
            p[k.strip()] = v.strip()
    with Library(ctx.obj["library"]) as lib:
        rec = lib.add(
            name, kind, p, make_provenance(source=source, method="library add"), replace=replace
        )
    click.echo(f"added {rec.name!r} ({rec.kind})")


@library_grp.command("remove")
@click.argument("name")
@click.pass_context
def library_remove(ctx, name):
    """Remove a terrain (reference terrains cannot be removed)."""
    from terracone.apps.library import Library

    with Library(ctx.obj["library"]) as lib:
        lib.remove(name)
    click.echo(f"removed {name!r}")


@library_grp.command("import")
@click.argument("path", type=click.Path(dir_okay=False))
@click.option("--replace", is_flag=True)
@click.pass_context
def library_import(ctx, path, replace):
    """Import terrains from a JSON file written by `library export`."""
    from terracone.apps.library import Library

    with Library(ctx.obj["library"]) as lib:
        rep = lib.import_(path, replace=replace)
    click.echo(f"imported {len(rep.imported)}, skipped {len(rep.skipped)}")
    for name, why in rep.skipped:
        click.echo(f"  skipped {name!r}: {why}", err=True)


@library_grp.command("export")
@click.argument("path", type=click.Path(dir_okay=False))
@click.option("--include-builtin", is_flag=True, help="Also the packaged reference terrains.")
@click.pass_context
def library_export(ctx, path, include_builtin):
    """Export terrains to a JSON file."""
    from terracone.apps.library import Library

    with Library(ctx.obj["library"]) as lib:
        k = lib.export(path, include_builtin=include_builtin)
    click.echo(f"exported {k} terrains to {path}")


@cli.command("export")
@click.option("--terrain", default=None, help="Name of a terrain in the library.")
@click.option(
    "--results",
    "results_path",
    default=None,
    type=click.Path(exists=True),
    help="predict --json output (a file) or a batch output directory.",
)
@click.option("--profile", default=None, help="With --results: the profile to export.")
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["chrono-scm", "json", "csv", "geojson"]),
    required=True,
    help="geojson needs --results.",
)
@click.option(
    "--out",
    required=True,
    type=click.Path(),
    help="Output file (a directory with --samples).",
)
@click.option("--units", type=_UNITS, default="si", show_default=True, help="For json/csv.")
@click.option("--library", default=None, help="Terrain library path.")
@click.option(
    "--elastic-k",
    type=float,
    default=None,
    help="chrono-scm: SCM elastic stiffness [Pa/m], above Bekker Kphi "
    "(default 4e8, Chrono's scm_hard.json; not from data).",
)
@click.option(
    "--damping",
    type=float,
    default=None,
    help="chrono-scm: SCM damping R [Pa s/m] (default 3e4, Chrono's soil files; not from data).",
)
@click.option(
    "--cohesion", type=float, default=None, help="chrono-scm: Mohr cohesion [kPa or psi]."
)
@click.option("--friction", type=float, default=None, help="chrono-scm: Mohr friction [deg].")
@click.option(
    "--janosi", default=None, help="chrono-scm: Janosi shear modulus K (e.g. 0.01, 1cm, 0.4in)."
)
@click.option(
    "--samples",
    type=click.IntRange(1),
    default=None,
    help="chrono-scm: N files from N posterior draws (predict --uncertainty --json).",
)
@click.option("--seed", type=int, default=None, help="Seed of the --samples draw.")
def export_cmd(
    terrain,
    results_path,
    profile,
    fmt,
    out,
    units,
    library,
    elastic_k,
    damping,
    cohesion,
    friction,
    janosi,
    samples,
    seed,
):
    """Write a terrain or a result for a simulator (Chrono SCM JSON), as plain B-W
    parameters, or results as GeoJSON points.

    Chrono SCM files get all eight soil parameters: Elastic K and Dampening R
    are documented defaults unless given (said on stderr); Mohr cohesion,
    friction and Janosi shear come from the terrain (a cone prediction has
    none: give --cohesion, --friction, --janosi).
    """
    if (terrain is None) == (results_path is None):
        raise click.UsageError("give exactly one of --terrain and --results")
    if fmt == "geojson":
        return _export_geojson(results_path, out)
    if samples is not None and (fmt != "chrono-scm" or results_path is None):
        raise click.UsageError("--samples needs --results and --format chrono-scm")
    shear = {
        "cohesion_kpa": None if cohesion is None else float(u.pressure_to_si(cohesion, units)),
        "friction_deg": friction,
        "janosi_m": None if janosi is None else _length_si(janosi, units, "--janosi"),
    }
    if terrain is not None:
        from terracone.apps.library import Library

        with Library(library) as lib:
            rec = lib.get(terrain)
        name, params = terrain, rec
    else:
        from terracone.apps.export import load_results, pick_profile

        res = pick_profile(load_results(results_path), profile, str(results_path))
        name, params = res.id, res.params
    if fmt != "chrono-scm":
        from terracone.apps.export import export_terrain

        missing = export_terrain(params, fmt, out, units=units, name=name)
        if missing:
            click.echo(
                f"terracone: {name!r} lacks {', '.join(missing)}: left out of {out}", err=True
            )
        click.echo(f"wrote {out}")
        return None
    scm = {"elastic_k": elastic_k, "damping_r": damping, **shear}
    if samples is not None:
        return _export_samples(res, samples, seed, out, scm)
    from terracone.apps.export import chrono_scm

    doc = chrono_scm(params, name, **scm)
    doc.write(out)
    if doc.provenance_text():
        click.echo(f"terracone: {out}: {doc.provenance_text()}", err=True)
    click.echo(f"wrote {out}")
    return None


def _export_geojson(results_path: str | None, out: str) -> None:
    from terracone.apps.export import load_results, write_geojson

    if results_path is None:
        raise click.UsageError("--format geojson needs --results (predict JSON or batch directory)")
    results = load_results(results_path)
    unlocated = write_geojson(results, out)
    n = len(results) - len(unlocated)
    msg = f"terracone: {out}: {n} located profile{'s' if n != 1 else ''} of {len(results)}"
    if unlocated:
        shown = ", ".join(unlocated[:3]) + (", ..." if len(unlocated) > 3 else "")
        msg += f"; {len(unlocated)} without coordinates (no lat/lon in their metadata: {shown})"
    click.echo(msg, err=True)
    click.echo(f"wrote {out}")


def _export_samples(res, count: int, seed: int | None, out: str, scm: dict) -> None:
    """N Chrono SCM files from N posterior draws of one profile, and an index CSV."""
    from terracone.apps.export import write_scm_samples

    written = write_scm_samples(res, count, out, seed=seed, **scm)
    if written and written[-1].provenance_text():
        click.echo(f"terracone: {Path(out)}: {written[-1].provenance_text()}", err=True)
    click.echo(f"wrote {count} Chrono SCM files and draws.csv to {Path(out)}")


# ---------------------------------------------------------------------------
# batch
# ---------------------------------------------------------------------------


@cli.command("batch")
@click.argument("input_path", metavar="INPUT", type=click.Path(exists=True))
@_fit_options
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
    help="Prior with --uncertainty.",
)
def batch_cmd(
    input_path,
    out_dir,
    workers,
    scheduler,
    resume,
    quiet,
    model,
    r_min,
    terrain,
    calibration,
    library,
    bounds,
    units,
    cone,
    chunk_size,
    uncertainty,
    draws,
    prior,
    depth_ref,
    depth_range,
    layers,
    fmt,
    depth_unit,
    ci_unit,
):
    """Fit every profile of a CSV/Parquet file or directory on Dask; Parquet results per chunk."""
    from terracone.apps.batch import run_batch
    from terracone.inverse import Bounds

    cal = _load_calibration(calibration, terrain, library)
    if prior == "calibration" and cal is None:
        raise click.UsageError("--prior calibration needs --calibration or --terrain")
    rm = _length_si(r_min, units, "--r-min") if r_min else None
    s = run_batch(
        input_path,
        out_dir,
        workers=workers,
        scheduler=scheduler,
        resume=resume,
        quiet=quiet,
        model=model,
        r_min=rm,
        calibration=cal,
        bounds=Bounds.parse(bounds, units),
        units=units,
        cone=cone,
        chunk_size=chunk_size,
        uncertainty=uncertainty,
        draws=draws,
        prior=cal if prior == "calibration" else "bounds",
        depth_ref=depth_ref,
        depth_range=_depth_range(depth_range, units),
        layers=layers,
        format=fmt,
        depth_unit=depth_unit,
        ci_unit=ci_unit,
    )
    click.echo(
        f"{s.profiles} profiles: {s.profiles_ok} fitted, {s.profiles_error} with errors "
        f"({s.profiles_per_s:.0f} profiles/s, {s.wall_s:.1f} s); results in {s.out_dir}"
    )
    for p in s.problems:
        click.echo(f"terracone: {p}", err=True)
    if s.profiles and not s.profiles_ok:
        # as predict: error profiles are normal, but a run that fitted none is a failure
        click.echo("terracone: no profile could be fitted (see the error column)", err=True)
    if not s.success or (s.profiles and not s.profiles_ok):
        sys.exit(1)


# ---------------------------------------------------------------------------
# report and reproduce
# ---------------------------------------------------------------------------


@cli.command("report")
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
    from terracone.report import build_report

    click.echo(f"wrote {build_report(results, out, map_by=map_by)}")


@cli.command("reproduce")
@click.option(
    "--out", type=click.Path(file_okay=False), default="terracone-reproduce", show_default=True
)
@click.option("--quick", is_flag=True, help="Smaller grids and fewer draws (a smoke run).")
@click.option("--workers", type=int, default=None, help="Processes (default 2).")
def reproduce_cmd(out, quick, workers):
    """Re-create the paper's LETE sand and KRC case studies (synthetic data), with figures, tables and a report."""
    from terracone.apps.reproduce import reproduce

    s = reproduce(out, quick=quick, workers=workers)
    click.echo(f"report: {s.report}")
    click.echo(f"figures and tables in {s.out_dir} ({s.seconds:.0f} s)")


# ---------------------------------------------------------------------------
# sites and test planning
# ---------------------------------------------------------------------------


def _sites_doc(ci_file, by, L, cal, model, b, depth_range, target_cv, bootstrap, seed, units):
    """The head of the ``terracone sites --json`` document (command, input, settings)."""
    return {
        "terracone": __version__,
        "command": "sites",
        "input": str(ci_file),
        "settings": {
            "by": by,
            "radius": None if L is None else float(u.length_from_si(L, units)),
            "model": cal.model if cal else model,
            "calibration": cal.terrain if cal else None,
            "bounds": b.as_dict(units),
            "depth_range": depth_range,
            "target_cv": target_cv,
            "bootstrap": bootstrap if bootstrap is not None else (0 if cal else 40),
            "seed": seed,
            "units": units,
        },
    }


@cli.command("sites")
@click.argument("ci_file", type=click.Path(dir_okay=False))
@_fit_options
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
    type=_UNITS,
    default=None,
    help="Unit system of an input that does not state its units.",
)
@_shared(*_json_options)
def sites_cmd(
    ci_file, by, radius, plates, target_cv, bootstrap, seed, file_units, out, as_json, **opts
):
    """Site statistics: pushes pooled per site (median terrain, push-to-push CV, pushes needed)."""
    from terracone.inverse.sites.statistics import default_sinkages, site_statistics

    if by is None and radius is None:
        raise click.UsageError("give --by COLUMN or --radius L to group the profiles into sites")
    if opts["layers"] > 1:
        raise click.UsageError("sites pools one-layer fits; --layers is not supported here")
    if not target_cv > 0:
        raise click.BadParameter(f"--target-cv: must be > 0, got {target_cv}")
    a = _fit_args(opts)
    a.check_r_min(a.calibration)
    units, cal = a.units, a.calibration
    L = _length_si(radius, units, "--radius") if radius else None
    run = site_statistics(
        a.items(ci_file, file_units),
        by=by,
        radius=L,
        source=str(ci_file),
        model=a.model,
        r_min=a.r_min,
        calibration=cal,
        bounds=a.bounds,
        plates=_lengths_si(plates, units, "--plates") or [0.0375, 0.05],
        sinkage=default_sinkages(units),
        target_cv=target_cv,
        bootstrap=bootstrap,
        seed=seed,
    )
    doc = _sites_doc(
        ci_file, by, L, cal, a.model, a.bounds, a.depth_range, target_cv, bootstrap, seed, units
    )
    doc.update(run.as_dict(units))
    if out:
        _emit_json(doc, out)
    if as_json:
        _emit_json(doc)
    else:
        click.echo(sites_text(doc["sites"], units))
        for d in doc["unassigned"]:
            click.echo(f"not in a site: {d['id']}: {d['reason']}")
        for e in doc["errors"]:
            click.echo(f"not read: {e}")
    if not run.fitted_any:
        sys.exit(1)


@cli.command("design")
@click.argument("ci_file", type=click.Path(dir_okay=False))
@_fit_options
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
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
def design_cmd(ci_file, prior, plates, candidates, plate_noise, as_json, **opts):
    """Value of information: which one extra test narrows the predicted plate pressure most."""
    from terracone.inverse.sites.design import parse_candidates, plan_test

    if opts["layers"] > 1:
        raise click.UsageError("design works on one-layer fits; --layers is not supported here")
    if not plate_noise > 0:
        raise click.BadParameter(f"--plate-noise: must be > 0, got {plate_noise}")
    a = _fit_args(opts)
    units, cal = a.units, a.calibration
    if prior.startswith("terrain:"):
        if cal is not None:
            raise click.UsageError(
                "give the calibration once: --prior terrain:NAME or --calibration"
            )
        cal = _prior(prior, opts["library"])
    elif prior != "bounds":
        raise click.BadParameter(f"--prior: expected bounds or terrain:NAME, got {prior!r}")
    a.check_r_min(cal)
    radii = _lengths_si(plates, units, "--plates")
    try:
        cands = parse_candidates(candidates, units)
    except ValueError as exc:
        raise click.BadParameter(str(exc)) from None
    designs = []
    for it in a.items(ci_file):
        if isinstance(it, InputError):
            designs.append({"id": str(it.profile), "status": "error", "error": str(it)})
            continue
        r = plan_test(
            it,
            candidates=cands,
            plates=radii,
            prior=cal if cal is not None else "bounds",
            bounds=a.bounds,
            model=a.model,
            r_min=a.r_min,
            plate_noise=plate_noise,
        )
        designs.append(r.as_dict(units))
    doc = {
        "terracone": __version__,
        "command": "design",
        "input": str(ci_file),
        "settings": {"candidates": candidates, "plate_noise": plate_noise, "units": units},
        "designs": designs,
    }
    if as_json:
        _emit_json(doc)
    else:
        click.echo(design_text(designs, units))
    if not any(d["status"] == "ok" for d in designs):
        sys.exit(1)


if __name__ == "__main__":  # pragma: no cover
    main()
