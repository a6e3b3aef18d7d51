"""Global sensitivity of the cone index to the terrain parameters (Sobol indices).

Does Kc matter (section 3.3 of [1]_)?  :func:`sobol_ci` gives first-order and
total Sobol indices [2]_ of the CI over a box of parameters (:data:`BOXES`),
by Saltelli's scheme in SALib [3]_; ``docs/uncertainty.md`` has the results.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Sections 2 and 3.3.
.. [2] Saltelli, A., Annoni, P., Azzini, I., Campolongo, F., Ratto, M.,
   Tarantola, S. (2010). Variance based sensitivity analysis of model output.
   Design and estimator for the total sensitivity index. Computer Physics
   Communications 181(2), 259-270.
.. [3] Herman, J., Usher, W. (2017). SALib: an open-source Python library for
   sensitivity analysis. Journal of Open Source Software 2(9), 97.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from SALib.analyze import sobol as sobol_analyze
from SALib.sample import sobol as sobol_sample

from terracone.data import TerrainParameters
from terracone.physics.cone import Cone, cone_index_huang, get_cone
from terracone.physics.plate import pressure_law

__all__ = ["BOXES", "SOBOL_NAMES", "SobolBox", "SobolResult", "sobol_ci"]

#: Parameter order of the Sobol analysis (the keys of a box; ``phic`` is
#: :attr:`TerrainParameters.phic_deg`, ``Kc`` is :attr:`TerrainParameters.K_cone`).
SOBOL_NAMES = ("kc", "kphi", "n", "cc", "phic", "Kc")
_FIELDS = ("kc", "kphi", "n", "cc", "phic_deg", "K_cone")
_INDICES = ("S1", "S1_conf", "ST", "ST_conf")  # SALib's keys and SobolResult's fields


@dataclass(frozen=True, eq=False)
class SobolBox(Mapping):
    """A box of terrain parameters: lower and upper corners (TerrainParameters, SI).

    Reads as a dict of ranges, ``box["kc"] == (lo, hi)``, keys :data:`SOBOL_NAMES`.
    """

    lo: TerrainParameters
    hi: TerrainParameters

    def __getitem__(self, name: str) -> tuple[float, float]:
        if name not in SOBOL_NAMES:
            raise KeyError(name)
        f = _FIELDS[SOBOL_NAMES.index(name)]
        return (getattr(self.lo, f), getattr(self.hi, f))

    def __iter__(self) -> Iterator[str]:
        return iter(SOBOL_NAMES)

    def __len__(self) -> int:
        return len(SOBOL_NAMES)

    @classmethod
    def from_ranges(cls, ranges: Mapping[str, tuple[float, float]]) -> SobolBox:
        """Box from ``{name: (lo, hi)}`` with the keys of :data:`SOBOL_NAMES` (SI)."""
        missing = [k for k in SOBOL_NAMES if k not in ranges]
        if missing:
            raise ValueError(f"box lacks {missing}")
        corner = [{f: float(ranges[k][i]) for k, f in zip(SOBOL_NAMES, _FIELDS)} for i in (0, 1)]
        return cls(TerrainParameters(**corner[0]), TerrainParameters(**corner[1]))


#: Named boxes (SI: kc kN/m^(n+1), kphi kN/m^(n+2), cc kPa, phic deg, Kc m);
#: Kc is log-uniform.
BOXES: dict[str, SobolBox] = {
    "bounds": SobolBox(
        TerrainParameters(kc=0.0, kphi=0.0, n=0.05, cc=0.0, phic_deg=0.0, K_cone=1e-4),
        TerrainParameters(kc=1000.0, kphi=20000.0, n=2.0, cc=100.0, phic_deg=45.0, K_cone=0.1),
    ),
    # LETE sand (Wong: kc 102, kphi 5301, n 0.79) +-50 %; n, cc, phic around the paper's fit
    "lete": SobolBox(
        TerrainParameters(kc=51.0, kphi=2650.0, n=0.5, cc=0.0, phic_deg=5.0, K_cone=1e-4),
        TerrainParameters(kc=153.0, kphi=7950.0, n=1.1, cc=2.0, phic_deg=20.0, K_cone=0.1),
    ),
}


@dataclass
class SobolResult:
    """Sobol indices of CI outputs.

    Attributes
    ----------
    names : tuple of str
        Parameters (:data:`SOBOL_NAMES`).
    outputs : tuple of str
        Output labels, e.g. "mean CI 0-30 cm", "CI at 15 cm".
    S1, S1_conf, ST, ST_conf : dict
        ``{output: {parameter: value}}``: first-order and total indices and
        the half widths of their 95% bootstrap confidence intervals [-].
    box : dict
        The sampled box (SI; Kc log-uniform).
    log : bool
        Whether the outputs were analysed as ln(CI).
    n_base : int
        Base sample size N of Saltelli's scheme.
    n_evals : int
        Model evaluations, N (D + 2).
    time_s : float
    """

    names: tuple[str, ...]
    outputs: tuple[str, ...]
    S1: dict[str, dict[str, float]]
    S1_conf: dict[str, dict[str, float]]
    ST: dict[str, dict[str, float]]
    ST_conf: dict[str, dict[str, float]]
    box: dict[str, tuple[float, float]]
    log: bool
    n_base: int
    n_evals: int
    time_s: float

    def as_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self) | {"names": list(self.names), "outputs": list(self.outputs)}
        box = {k: list(v) for k, v in self.box.items()}
        return d | {"box": box, "Kc_distribution": "log-uniform"}

    def table(self, digits: int = 3) -> str:
        """Plain-text table: one row per output, S1 / ST per parameter."""
        head = f"{'output':22s} " + " ".join(f"{nm:>13s}" for nm in self.names)
        lines = [head, " " * 23 + " ".join(f"{'S1 / ST':>13s}" for _ in self.names)]
        for o in self.outputs:
            cells = [
                f"{self.S1[o][nm]:6.{digits}f}/{self.ST[o][nm]:6.{digits}f}" for nm in self.names
            ]
            lines.append(f"{o:22s} " + " ".join(f"{c:>13s}" for c in cells))
        return "\n".join(lines)


def _evaluate(
    X: np.ndarray,
    depths: np.ndarray,
    *,
    cone: Cone,
    model: str,
    r_min: float | None,
    chunk: int,
) -> np.ndarray:
    """CI (S, Z) of parameter rows (kc, kphi, n, cc, phic, Kc), in chunks."""
    law = pressure_law(model, r_min=r_min)
    out = np.empty((X.shape[0], depths.size))
    for a in range(0, X.shape[0], chunk):
        cols = {f: X[a : a + chunk, j : j + 1] for j, f in enumerate(_FIELDS)}
        out[a : a + chunk] = cone_index_huang(depths, **cols, law=law, cone=cone)
    return out


def sobol_ci(
    *,
    box: str | dict[str, tuple[float, float]] = "bounds",
    depths: Sequence[float] = (0.05, 0.15, 0.30),
    mean_range: tuple[float, float] = (0.0, 0.30),
    mean_step: float = 0.01,
    n_base: int = 1024,
    seed: int | None = 0,
    log: bool = False,
    model: str = "rm0",
    r_min: float | None = None,
    cone: str | Cone = "asabe-large",
    chunk: int = 256,
    num_resamples: int = 100,
) -> SobolResult:
    """First-order and total Sobol indices of the cone index.

    Parameters
    ----------
    box : "bounds", "lete", SobolBox or dict
        Ranges (SI) of kc [kN/m^(n+1)], kphi [kN/m^(n+2)], n [-], cc [kPa],
        phic [deg] (uniform) and Kc [m] (log-uniform); see :data:`BOXES`
        and :class:`SobolBox`.
    depths : sequence of float
        Cone-base depths [m] of the point outputs.
    mean_range : (float, float)
        Depth range [m] of the mean-CI output.
    mean_step : float
        Depth step [m] of the mean-CI output.
    n_base : int
        Base sample size of Saltelli's scheme (a power of 2); the model runs
        n_base * 8 times.
    seed : int, optional
        Seed of the (scrambled Sobol) sample and of the bootstrap.
    log : bool
        Analyse ln(CI) instead of CI.
    model : {"rm0", "rm1"}
    r_min : float, optional
        RM1 transition radius [m].
    cone : str or Cone
    chunk : int
        Parameter sets per vectorised model call (memory: the finite-Kc
        quadrature holds ~ chunk * depths * 120 values).
    num_resamples : int
        Bootstrap resamples of the confidence intervals.

    Returns
    -------
    SobolResult
    """
    t0 = time.perf_counter()
    b = BOXES[box] if isinstance(box, str) else SobolBox.from_ranges(box)
    problem, X = _sample(b, n_base, seed)
    mean_z = np.arange(mean_range[0], mean_range[1] + mean_step / 2, mean_step)
    z = np.concatenate([mean_z, np.asarray(depths, dtype=float)])
    ci = _evaluate(X, z, cone=get_cone(cone), model=model, r_min=r_min, chunk=chunk)
    mean = f"mean CI {100 * mean_range[0]:g}-{100 * mean_range[1]:g} cm"
    outs = {mean: ci[:, : mean_z.size].mean(axis=1)}
    outs |= {f"CI at {100 * d:g} cm": ci[:, mean_z.size + j] for j, d in enumerate(depths)}
    return SobolResult(
        names=SOBOL_NAMES,
        outputs=tuple(outs),
        **_analyse(problem, outs, log, num_resamples, seed),
        box={k: tuple(float(v) for v in b[k]) for k in SOBOL_NAMES},
        log=log,
        n_base=n_base,
        n_evals=int(X.shape[0]),
        time_s=time.perf_counter() - t0,
    )


def _sample(
    b: Mapping[str, tuple[float, float]], n_base: int, seed: int | None
) -> tuple[dict[str, Any], np.ndarray]:
    """SALib problem and Saltelli sample (S, 6) of a box; Kc log-uniform."""
    if b["Kc"][0] <= 0:
        raise ValueError("Kc range must be > 0 (log-uniform)")
    bounds = [list(b[k]) for k in SOBOL_NAMES[:5]] + [list(np.log10(b["Kc"]))]
    problem = {"num_vars": 6, "names": list(SOBOL_NAMES), "bounds": bounds}
    X = np.array(sobol_sample.sample(problem, n_base, calc_second_order=False, seed=seed), float)
    X[:, 5] = 10.0 ** X[:, 5]
    return problem, X


def _analyse(problem: dict[str, Any], outs: dict[str, np.ndarray], log, num_resamples, seed):
    """{S1, S1_conf, ST, ST_conf: {output: {parameter: value}}} (Saltelli)."""
    indices: dict[str, dict[str, dict[str, float]]] = {k: {} for k in _INDICES}
    for name, Y in outs.items():
        Yv = np.log(np.maximum(Y, 1e-300)) if log else Y
        res = sobol_analyze.analyze(
            problem,
            Yv,
            calc_second_order=False,
            num_resamples=num_resamples,
            seed=seed,
            print_to_console=False,
        )
        for k in _INDICES:
            indices[k][name] = {p: float(v) for p, v in zip(SOBOL_NAMES, res[k])}
    return indices
