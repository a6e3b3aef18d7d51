"""Sobol indices of the cone index w.r.t. kc, kphi, n, cc, phic and Kc.

Usage::

    python benchmarks/sensitivity.py [--n-base 4096] [--seed 0] [--json OUT.json]
        [--model rm1 --r-min 0.008]

Tests quantitatively the remark of Huang et al. (section 3.3) that the
cone-terrain shear deformation parameter Kc has little effect: first-order
(S1) and total (ST) Sobol indices of the mean CI over 0-30 cm and of the CI
at 5, 15 and 30 cm, with each parameter drawn independently (uniform; Kc
log-uniform 0.1 mm to 10 cm) over two boxes:

* ``bounds``: the prediction's search bounds (kc 0-1000 kN/m^(n+1), kphi
  0-20000 kN/m^(n+2), n 0.05-2, cc 0-100 kPa, phic 0-45 deg);
* ``lete``: LETE sand +-50% (kc 51-153, kphi 2650-7950, n 0.5-1.1, cc 0-2
  kPa, phic 5-20 deg),

for CI and for ln(CI).  RM0 (or RM1 with --model rm1 --r-min R [m]),
asabe-large cone.  The model runs n_base * 8 times per box.
"""

from __future__ import annotations

import argparse
import json
import sys

from terracone.apps.sensitivity import sobol_ci


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n-base", type=int, default=4096)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", default=None, help="write all indices here")
    ap.add_argument("--model", choices=("rm0", "rm1"), default="rm0")
    ap.add_argument("--r-min", type=float, default=None, help="RM1 transition radius [m]")
    args = ap.parse_args(argv)
    out = []
    for box in ("bounds", "lete"):
        for log in (False, True):
            r = sobol_ci(
                box=box,
                n_base=args.n_base,
                seed=args.seed,
                log=log,
                model=args.model,
                r_min=args.r_min,
            )
            what = "ln(CI)" if log else "CI"
            print(f"\nbox {box!r}, {what}, {args.model}: {r.n_evals} model runs, {r.time_s:.1f} s")
            print(r.table())
            conf = max(max(c.values()) for c in r.ST_conf.values())
            print(f"(largest 95% bootstrap half width of ST: {conf:.3f})")
            out.append({"box": box, "model": args.model, "r_min": args.r_min, **r.as_dict()})
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
