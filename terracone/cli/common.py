"""Shared pieces of the command line: option groups, argument parsing in units, errors."""

from __future__ import annotations

import functools
import math
import os
import re
from pathlib import Path
from typing import Any

import click
import numpy as np

from terracone.apps.workflow import Reading
from terracone.inverse.bounds import Bounds
from terracone.inverse.predict import RunSettings
from terracone.inverse.problem import Calibration, Problem
from terracone.physics import units as u
from terracone.report.text import curve_text

UNITS = click.Choice(["si", "us"])


LEN_RE = re.compile(r"^\s*([-+0-9.eE]+)\s*(m|cm|mm|in)?\s*$")


def parse_floats(text: str, what: str) -> np.ndarray:
    try:
        vals = [float(s) for s in text.split(",") if s.strip()]
    except ValueError as exc:
        raise click.BadParameter(f"{what}: expected comma-separated numbers, got {text!r}") from exc
    if not vals:
        raise click.BadParameter(f"{what}: no values given")
    return np.array(vals)


def parse_length(text: str, units: str, what: str, *, positive: bool = False) -> float:
    """'1.5in' or '3.75cm' or a bare number in the unit system's length unit -> m.

    A length is finite and not negative; with ``positive`` (a radius, a spacing) above 0.
    """
    m = LEN_RE.match(text)
    try:
        v = float(m.group(1)) if m else math.nan
    except ValueError:
        v = math.nan
    if not m or math.isnan(v):
        raise click.BadParameter(
            f"{what}: expected a length such as 0.05, 5cm or 2in, got {text!r}"
        )
    if not math.isfinite(v) or v < 0 or (positive and v == 0):
        raise click.BadParameter(
            f"{what}: must be a finite length {'> 0' if positive else '>= 0'}, got {text!r}"
        )
    if m.group(2):
        return v * u.LENGTH_UNITS[m.group(2)]
    return float(u.length_to_si(v, units))


def parse_lengths(
    text: str | None, units: str, what: str, *, positive: bool = False
) -> list[float]:
    """Comma-separated lengths (:func:`parse_length`) -> m."""
    if not text:
        return []
    return [parse_length(s, units, what, positive=positive) for s in text.split(",") if s.strip()]


def _length_range(text: str, units: str, what: str, both: bool = False) -> list[float | None]:
    """'LO:HI' -> [lo, hi] in m, None for an empty side (an error when ``both``)."""
    if ":" not in text:
        raise click.BadParameter(f"{what}: expected LO:HI, got {text!r}")
    sides = text.split(":", 1)
    if both and not all(s.strip() for s in sides):
        raise click.BadParameter(f"{what}: give both LO and HI, got {text!r}")
    return [parse_length(s, units, what) if s.strip() else None for s in sides]


def parse_depth_range(text: str | None, units: str) -> tuple[float | None, float | None]:
    """'LO:HI' (either side may be empty; numbers with a unit suffix or in --units) -> m."""
    if not text:
        return None, None
    lo, hi = _length_range(text, units, "--depth-range")
    if lo is not None and hi is not None and lo >= hi:
        raise click.BadParameter(f"--depth-range: LO must be below HI, got {text!r}")
    return lo, hi


def parse_r_min_range(text: str | None, units: str) -> tuple[float, float] | None:
    """'LO:HI' of r_min (numbers with a unit suffix or in --units) -> m."""
    if not text:
        return None
    lo, hi = _length_range(text, units, "--r-min-range", both=True)
    if not (0 < lo <= hi):
        raise click.BadParameter(f"--r-min-range: need 0 < LO <= HI, got {text!r}")
    return lo, hi


def emit_json(obj: Any, out: str | None = None) -> None:
    """Print a JSON document, or write it to ``out`` (terracone.result's one JSON writer)."""
    from terracone.result import dumps

    text = dumps(obj)
    if out:
        Path(out).write_text(text + "\n")
    else:
        click.echo(text)


def emit_document(doc: dict, *, out: str | None, as_json: bool, text: Any) -> None:
    """Write ``doc`` to ``out`` when given, then print it as JSON or as ``text(doc)``."""
    if out:
        emit_json(doc, out)
    if as_json:
        emit_json(doc)
    else:
        click.echo(text(doc))


def echo_curve(xkey, x, ykey, y, units: str, as_json: bool) -> None:
    """A length-pressure curve as JSON ``{x, y, "units"}`` or as a two-column table."""
    if as_json:
        emit_json(
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


class Group(click.Group):
    """Turns every error into one message and a non-zero exit."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except (click.exceptions.ClickException, click.exceptions.Exit, click.exceptions.Abort):
            raise
        except KeyError as exc:
            raise click.ClickException(str(exc.args[0]) if exc.args else repr(exc)) from None
        except OSError as exc:
            raise click.ClickException(os_error_text(exc)) from None
        except ValueError as exc:  # InputError too
            raise click.ClickException(str(exc)) from None
        except Exception as exc:  # pragma: no cover - a bug, but no traceback for users
            if os.environ.get("TERRACONE_DEBUG"):
                raise
            raise click.ClickException(
                f"internal error ({type(exc).__name__}: {exc}); set TERRACONE_DEBUG=1 for a traceback"
            ) from None


def shared(*decorators):
    """Apply several click decorators as one (options common to predict and batch)."""
    return lambda f: functools.reduce(lambda g, d: d(g), reversed(decorators), f)


#: --out and --json of a command that writes one JSON document.
json_options = (
    click.option(
        "--out", type=click.Path(dir_okay=False), default=None, help="Write the JSON here too."
    ),
    click.option("--json", "as_json", is_flag=True, help="Print JSON."),
)


def check_cone(ctx: click.Context, param: click.Parameter, value: str | None) -> str | None:
    """Click callback of --cone: a cone terracone knows, or one in the range of penetrometer
    cones (:data:`terracone.physics.cone.CONE_ANGLE_RANGE`, ``CONE_DIAMETER_RANGE``)."""
    from terracone.physics.cone import get_cone

    if value is not None:
        try:
            get_cone(value)
        except ValueError as exc:
            raise click.BadParameter(str(exc), ctx=ctx, param=param) from None
    return value


#: How CI files are read: --cone, --format, a wide table's units, --depth-ref, --depth-range.
reading_options = (
    click.option(
        "--cone",
        default="asabe-large",
        show_default=True,
        callback=check_cone,
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
)

library_option = click.option(
    "--library",
    default=None,
    help="Terrain library path (default: $TERRACONE_LIBRARY or the user data dir).",
)

fit_options = shared(
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
        help="Terrain library path (default: $TERRACONE_LIBRARY or the user data dir) of "
        "--terrain and --prior terrain:NAME.  On predict and sites, given without them: the "
        "library's calibrations as the prior (docs/library.md).",
    ),
    click.option(
        "--bounds", default=None, help="kc=LO:HI,kphi=LO:HI,n=LO:HI,cc=LO:HI,phic=LO:HI in --units."
    ),
    click.option("--units", type=UNITS, default="si", show_default=True),
    *reading_options,
    click.option(
        "--layers",
        type=click.IntRange(1, 4),
        default=1,
        show_default=True,
        help="Also fit a terrain of this many layers (interfaces fitted) and compare by BIC.",
    ),
)


def reading_from(opts: dict[str, Any], file_units: str | None = None) -> Reading:
    """How a command reads its CI files, from the reading options of ``fit_options``."""
    return Reading(
        cone=opts["cone"],
        format=opts["fmt"],
        depth_ref=opts["depth_ref"],
        depth_range=parse_depth_range(opts["depth_range"], opts["units"]),
        depth_unit=opts["depth_unit"],
        ci_unit=opts["ci_unit"],
        file_units=file_units,
    )


def problem_from(
    opts: dict[str, Any], prior: Any = "bounds", library_prior: bool = False
) -> Problem:
    """The one :class:`Problem` of a command's ``fit_options`` (lengths in --units).

    ``prior``: "bounds", "calibration", or a calibration given as the prior
    (``--prior terrain:NAME``, :func:`load_prior`).  ``library_prior``: the
    command takes ``--library DB`` given on its own (no --calibration,
    --terrain or --prior terrain:NAME) as the library as a prior
    (:func:`load_library_prior`); ``$TERRACONE_LIBRARY`` never is.
    """
    units = opts["units"]
    cal = load_calibration(opts["calibration"], opts["terrain"], opts["library"])
    lib = None
    if library_prior and opts["library"] and cal is None and prior in ("bounds", None):
        lib = load_library_prior(opts["library"])
    r_min = parse_length(opts["r_min"], units, "--r-min", positive=True) if opts["r_min"] else None
    if opts["model"] == "rm1" and r_min is None and cal is None and isinstance(prior, str):
        raise click.UsageError("--model rm1 needs --r-min (or a --calibration / --terrain)")
    return Problem(
        model=opts["model"],
        r_min=r_min,
        calibration=cal,
        bounds=Bounds.parse(opts["bounds"], units),
        prior=prior,
        library=lib,
    )


def load_library_prior(path: str) -> Any:
    """The calibrations of a library file as a prior (:class:`~terracone.inverse.problem.LibraryPrior`).

    Every record of kind "calibration" is a candidate; the packaged
    reference terrains are not (they hold no learned phic, cc).  The file
    must exist (a library is not created here) and be a terracone library.
    """
    from terracone.apps.library import Library
    from terracone.inverse.problem import LibraryPrior

    p = Path(path).expanduser()
    if not p.is_file():
        raise click.UsageError(
            f"--library {path}: no such library file (store calibrations with `terracone "
            f"library --library {path} add --from cal.json` or `... seed-paper`)"
        )
    with Library(p) as lib:  # a corrupt or foreign file: the library's own message, naming it
        recs = lib.list("calibration", include_builtin=False)
    try:
        cals = tuple(Calibration.from_library_record(r) for r in recs)
        return LibraryPrior(cals, source=str(path))
    except ValueError as exc:
        raise click.UsageError(str(exc)) from None


def run_from(opts: dict[str, Any], **fields: Any) -> RunSettings:
    """The :class:`RunSettings` of a command: ``--layers`` and ``fields`` (solver, seed, ...)."""
    return RunSettings(layers=opts["layers"], **fields)


def load_calibration(calibration: str | None, terrain: str | None, library: str | None):
    """The calibration of --calibration FILE or --terrain NAME (from the library), or None."""
    from terracone.apps.library import Library

    if calibration and terrain:
        raise click.UsageError("give at most one of --calibration and --terrain")
    if calibration:
        return Calibration.load(calibration)
    if terrain:
        with Library(library) as lib:
            return Calibration.from_library_record(lib.get(terrain))
    return None


def load_prior(prior: str, library: str | None):
    """--prior: "bounds", or the calibration stored in the library as terrain:NAME."""
    if prior == "bounds":
        return "bounds"
    if prior.startswith("terrain:"):
        return load_calibration(None, prior.split(":", 1)[1], library)
    raise click.BadParameter(f"--prior: expected bounds or terrain:NAME, got {prior!r}")
