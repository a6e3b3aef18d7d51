"""Plot the Cullinan sand plate tests (loading branches) and their Bekker fits.

Usage::

    python benchmarks/cullinan_plot.py /tmp/cullinan.png [--method wong|loglog|nonlinear]
        [--data DIR]

Reads ``plate_sinkage.csv`` of the Cullinan sand data set (Kruger, Els &
Hamersma, J. Terramechanics 109 (2023) 45-62; CC BY 4.0) from
``<repo>/../shared/data/cullinan-sand`` unless ``--data`` is given, fits
``p = k z^n`` to each test's loading branch (:func:`terracone.bevameter.fit_plate_test`)
and draws measured points and fitted curves, one panel per preparation
method, plus a table of k and n in the terminal.  Nothing is written inside
the repository: the PNG goes to the path given.

References
----------
.. [1] Kruger, R., Els, P.S., Hamersma, H.A. (2023). Experimental investigation
   of factors affecting the characterisation of soil strength properties using
   a Bevameter in-situ plate sinkage and shear test apparatus. Journal of
   Terramechanics 109, 45-62.
.. [2] Wong, J.Y. (1980). Data processing methodology in the characterization
   of the mechanical properties of terrain. Journal of Terramechanics 17(1),
   13-41.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from terracone.data import PlateTest  # noqa: E402
from terracone.inverse.bevameter.plates import METHODS, fit_plate_test  # noqa: E402

DEFAULT_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "cullinan-sand"


def load_plate_tests(path: Path) -> list[PlateTest]:
    """Plate tests of a CSV, with terracone.io when available."""
    try:
        from terracone.io import read_plate_tests
    except ImportError:
        read_plate_tests = None
    if read_plate_tests is not None:
        out = read_plate_tests(path)
        return [t for t in out if isinstance(t, PlateTest)]
    import pandas as pd  # fallback reader for this file's columns only

    d = pd.read_csv(path)
    return [
        PlateTest(
            str(t),
            float(g["plate_diameter_mm"].iloc[0]) / 2000.0,
            "circular",
            g["sinkage_mm"].to_numpy() / 1000.0,
            g["pressure_kpa"].to_numpy(),
            metadata={"method": g["method"].iloc[0]},
        )
        for t, g in d.groupby("test", sort=False)
    ]


def _group(test_id: str) -> str:
    # "method_2_test_3" -> "method 2"
    parts = test_id.split("_")
    return " ".join(parts[:2]) if len(parts) >= 2 else test_id


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path, help="PNG file to write")
    ap.add_argument("--method", choices=METHODS, default="wong")
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="cullinan-sand folder")
    args = ap.parse_args(argv)

    csv = args.data / "plate_sinkage.csv"
    if not csv.exists():
        print(f"no data at {csv}", file=sys.stderr)
        return 2
    tests = load_plate_tests(csv)
    groups: dict[str, list[PlateTest]] = {}
    for t in tests:
        groups.setdefault(_group(t.id), []).append(t)
    names = sorted(groups)

    fig, axes = plt.subplots(1, len(names), figsize=(4.2 * len(names), 4.4), sharey=False)
    axes = np.atleast_1d(axes)
    print(f"{'test':18s} {'b [mm]':>7s} {'k [kN/m^(n+2)]':>15s} {'n':>6s} {'pts':>5s} {'R2':>6s}")
    for ax, name in zip(axes, names):
        for i, t in enumerate(groups[name]):
            br = t.loading_branch()
            fit = fit_plate_test(t, args.method)
            colour = f"C{i}"
            ax.plot(br.sinkage * 1e3, br.pressure, ".", ms=1.5, color=colour, alpha=0.35)
            zz = np.linspace(0.0, br.sinkage.max(), 200)
            ax.plot(
                zz * 1e3,
                fit.pressure(zz),
                "-",
                color=colour,
                lw=1.6,
                label=f"{t.id.split('_')[-1]}: k={fit.k:.0f}, n={fit.n:.2f}",
            )
            print(
                f"{t.id:18s} {t.b * 2e3:7.1f} {fit.k:15.1f} {fit.n:6.3f} "
                f"{fit.points_used:5d} {fit.r2:6.3f}"
            )
        ax.set_title(f"Cullinan sand, {name}")
        ax.set_xlabel("sinkage z [mm]")
        ax.set_ylabel("pressure p [kPa]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, title=f"test: k [kN/m^(n+2)], n ({args.method})", title_fontsize=7)
    fig.suptitle(
        "Plate loading branches (points) and p = k z^n fits (lines); "
        f"{tests[0].b * 2e3:.1f} mm plate"
        if tests
        else "",
        fontsize=10,
    )
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
