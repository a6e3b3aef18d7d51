"""Validation on real profiles: one layer against two, on the 224 Marsden Farm pushes.

Usage: python benchmarks/marsden_layers.py [OUT_DIR] [--limit N]

Fits every profile of ../shared/data/marsden-penetrometer/ci_profiles.csv
(FieldScout SC900, small 0.2 in^2 cone, base depths as recorded) with the
homogeneous model (exact solver) and with two layers (terracone.physics.layers),
then prints the distribution of R^2, the fraction flagged for lack of fit,
how often two layers win by BIC, and draws a typical profile with both fits.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from terracone.inverse import predict
from terracone.inverse.layered import fit_layered
from terracone.io import read_ci_profiles

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "marsden-penetrometer" / "ci_profiles.csv"


def main() -> None:
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    out = Path(args[0]) if args else Path("/tmp/marsden")
    limit = int(sys.argv[sys.argv.index("--limit") + 1]) if "--limit" in sys.argv else None
    out.mkdir(parents=True, exist_ok=True)
    if not DATA.exists():
        sys.exit(f"{DATA} not found: the real profiles live in ../shared beside the repository")
    items = read_ci_profiles(DATA, cone="asabe-small", on_error="collect")
    items = items[:limit] if limit else items
    rows = []
    t0 = time.perf_counter()
    for p in items:
        if not hasattr(p, "depth"):
            rows.append({"id": p.profile, "status": "error", "error": str(p)})
            continue
        one = predict(p)
        two = fit_layered(p, layers=2)
        rows.append(
            {
                "id": p.id,
                "status": one.status,
                "error": one.error,
                "r2_one": one.r2_ci,
                "lack_of_fit_one": one.lack_of_fit,
                "r2_two": two.r2_ci if two.ok else None,
                "lack_of_fit_two": two.lack_of_fit if two.ok else two.error,
                "bic_one": two.bic_single if two.ok else None,
                "bic_two": two.bic if two.ok else None,
                "interface_m": two.interfaces[0] if two.ok else None,
                "n_one": one.params.n if one.ok else None,
                "n_two": [q.n for q in two.layers] if two.ok else None,
            }
        )
        if two.ok and one.ok:
            rows[-1]["_curves"] = (p.depth, p.ci, one.ci_model, two.ci_model)
    wall = time.perf_counter() - t0
    ok = [r for r in rows if r["status"] == "ok" and r["r2_two"] is not None]
    r1 = np.array([r["r2_one"] for r in ok])
    r2 = np.array([r["r2_two"] for r in ok])
    flag1 = np.mean([r["lack_of_fit_one"] is not None for r in ok])
    flag2 = np.mean([r["lack_of_fit_two"] is not None for r in ok])
    wins = np.mean([r["bic_two"] < r["bic_one"] for r in ok])
    q = [5, 25, 50, 75, 95]
    print(f"profiles: {len(rows)} read, {len(ok)} fitted with both models, wall {wall:.0f} s")
    print("R2 one layer, percentiles 5/25/50/75/95:", np.round(np.percentile(r1, q), 3).tolist())
    print("R2 two layers, percentiles 5/25/50/75/95:", np.round(np.percentile(r2, q), 3).tolist())
    print(f"flagged for lack of fit: one layer {flag1:.1%}, two layers {flag2:.1%}")
    print(f"two layers win by BIC: {wins:.1%}")
    ifs = np.array([r["interface_m"] for r in ok]) * 100
    print(
        "interface depth [cm], percentiles 5/25/50/75/95:",
        np.round(np.percentile(ifs, q), 1).tolist(),
    )
    # a typical profile: the median R2 improvement
    gain = r2 - r1
    k = int(np.argsort(gain)[len(gain) // 2])
    z, y, m1, m2 = ok[k]["_curves"]
    fig, ax = plt.subplots(figsize=(5, 6))
    ax.plot(y, z * 100, "ko", ms=4, label="measured (SC900)")
    ax.plot(m1, z * 100, "b--", label=f"one layer, R$^2$={r1[k]:.2f}")
    ax.plot(m2, z * 100, "r-", label=f"two layers, R$^2$={r2[k]:.2f}")
    ax.axhline(ok[k]["interface_m"] * 100, color="r", ls=":", lw=1, label="fitted interface")
    ax.invert_yaxis()
    ax.set_xlabel("cone index [kPa]")
    ax.set_ylabel("cone-base depth [cm]")
    ax.set_title(f"Marsden Farm {ok[k]['id']}")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "marsden_typical_profile.png", dpi=120)
    for r in rows:
        r.pop("_curves", None)
    (out / "marsden_layers.json").write_text(json.dumps(rows, indent=1, default=float))
    print(f"figure: {out / 'marsden_typical_profile.png'}; table: {out / 'marsden_layers.json'}")


if __name__ == "__main__":
    main()
