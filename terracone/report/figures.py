"""Figures of the paper's section 4, re-drawn from terracone results.

Every function takes plain data in SI (m, kPa, kN/m^(n+1), kN/m^(n+2)) and
returns a :class:`matplotlib.figure.Figure` drawn on the Agg canvas (no
pyplot, no global backend state); :func:`save_figure` writes PNG and SVG and
:func:`png_bytes` gives the PNG for embedding.  Axes carry units (cm and kPa,
or in and psi with ``units="us"``), every figure has a legend, and series
differ by line style and marker as well as by colour, so the figures read in
black and white.  Which figure of [1]_ each re-draws: ``docs/report.md``.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Section 4, Figures 2-1 and 4-1 to 4-10.
"""

from __future__ import annotations

import io
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from terracone.inverse.bounds import Bounds
from terracone.inverse.solver.ridge import ridge_profile
from terracone.physics import units as u
from terracone.physics.cone import cone_index

__all__ = [
    "SYNTHETIC_NOTE",
    "fig_janosi",
    "fig_ci_fit",
    "fig_plate_fit",
    "fig_site",
    "fig_ridge",
    "fig_bars",
    "fig_histograms",
    "fig_ci_multiples",
    "fig_map",
    "save_figure",
    "png_bytes",
]

#: Printed on every figure drawn from synthetic data.
SYNTHETIC_NOTE = "SYNTHETIC DATA: generated from published parameters, not measurements"

# Okabe-Ito colours (colour-blind safe) with a marker each; line styles tell
# measured (dashed) from predicted (solid), as in the paper's figures.
_COLOURS = [
    "#0072B2",
    "#D55E00",
    "#009E73",
    "#CC79A7",
    "#E69F00",
    "#56B4E9",
    "#000000",
    "#882255",
    "#117733",
    "#999933",
    "#44AA99",
    "#661100",
]
_MARKERS = ["o", "s", "^", "D", "v", "P", "X", "*", "h", "<", ">", "p"]
_PLATE_STYLES = ["-", "--", "-.", ":"]


def _style(i: int) -> tuple[str, str]:
    return _COLOURS[i % len(_COLOURS)], _MARKERS[i % len(_MARKERS)]


class _Disp:
    """Display units: cm and kPa (si) or in and psi (us)."""

    def __init__(self, units: str) -> None:
        self.units = u.check_system(units)
        if self.units == "us":
            self.L, self.lf, self.P, self.pf = "in", 1.0 / u.INCH, "psi", 1.0 / u.PSI
        else:
            self.L, self.lf, self.P, self.pf = "cm", 100.0, "kPa", 1.0

    def length(self, v: Any) -> np.ndarray:
        return np.asarray(v, dtype=float) * self.lf

    def pressure(self, v: Any) -> np.ndarray:
        return np.asarray(v, dtype=float) * self.pf

    def radius_label(self, r: float) -> str:
        """Plate label: radius in cm (and in)."""
        return f"r = {r * 100:.4g} cm ({r / u.INCH:.3g} in)"


def _new(width: float = 7.2, height: float = 4.6, ncols: int = 1, nrows: int = 1):
    fig = Figure(figsize=(width, height), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, ncols, squeeze=False)
    for ax in axes.flat:
        ax.grid(True, color="#d0d0d0", linewidth=0.6)
        ax.set_axisbelow(True)
    return fig, axes


def _finish(fig: Figure, title: str | None, synthetic: bool) -> Figure:
    if title:
        fig.suptitle(("SYNTHETIC - " if synthetic else "") + title, fontsize=11)
    if synthetic:
        fig.text(
            0.5,
            0.0,
            SYNTHETIC_NOTE,
            ha="center",
            va="bottom",
            fontsize=8,
            color="#7a4d00",
            fontweight="bold",
        )
        fig.get_layout_engine().set(rect=(0, 0.035, 1, 0.965))
    fig._terracone_synthetic = synthetic  # type: ignore[attr-defined]
    return fig


def _markevery(n: int) -> int:
    return max(1, n // 10)


def _measured(ax, x, y, colour, marker, label: str, size: float = 3.5) -> None:
    """A measured curve: dashed, open markers."""
    n = np.size(x)
    ax.plot(x, y, linestyle="--", marker=marker, markersize=size, markerfacecolor="white",
            markevery=_markevery(n), color=colour, linewidth=1.1, label=label)  # fmt: skip


def _modelled(ax, x, y, colour, marker, label: str) -> None:
    """A model curve: solid, filled markers between the measured ones."""
    k = _markevery(np.size(x))
    ax.plot(x, y, linestyle="-", marker=marker, markersize=4, markevery=(k // 2 or 1, k),
            color=colour, linewidth=2.0, label=label)  # fmt: skip


# ---------------------------------------------------------------------------
# Figure 2-1: the Janosi equation
# ---------------------------------------------------------------------------


def fig_janosi(
    profiles: Sequence[Mapping[str, Any]],
    janosi_params: Mapping[str, float],
    *,
    improved_params: Mapping[str, Any] | None = None,
    units: str = "si",
    title: str | None = "Measured CI and the Janosi equation (2-1)",
    synthetic: bool = False,
    params_label: str | None = None,
) -> Figure:
    """Figure 2-1 analogue: measured CI against CI from eq. (2-1).

    Parameters
    ----------
    profiles : sequence of mappings
        Each with ``id``, ``depth`` [m] (cone-base depth) and ``ci`` [kPa].
    janosi_params : mapping
        ``kc`` [kN/m^(n+1)], ``kphi`` [kN/m^(n+2)], ``n`` for the Janosi
        equation (the standard 30 deg, 0.5 in^2 cone).
    improved_params : mapping, optional
        Also draw the improved model (eq. (2-7)) with these parameters
        (``kc, kphi, n, cc, phic_deg`` and optional ``model``, ``r_min``).
    units : {"si", "us"}
    params_label : str, optional
        How the parameters are described in the legend.
    """
    d = _Disp(units)
    fig, axes = _new()
    ax = axes[0, 0]
    zmax = 0.0
    for i, p in enumerate(profiles):
        c, m = _style(i)
        z = np.asarray(p["depth"], float)
        zmax = max(zmax, float(np.max(z)) if z.size else 0.0)
        ax.plot(
            d.length(z),
            d.pressure(p["ci"]),
            linestyle="--",
            marker=m,
            markersize=4,
            markevery=_markevery(z.size),
            color=c,
            linewidth=1.2,
            label=f"{p['id']} measured",
        )
    zz = np.linspace(0.0, max(zmax, 0.05), 121)
    k = janosi_params
    ci_j = cone_index(zz, kc=k["kc"], kphi=k["kphi"], n=k["n"], model="janosi")
    lab = params_label or (
        f"kc={k['kc']:.4g} kN/m^(n+1), kphi={k['kphi']:.4g} kN/m^(n+2), n={k['n']:.3g}"
    )
    ax.plot(
        d.length(zz),
        d.pressure(ci_j),
        color="black",
        linewidth=2.4,
        linestyle="-",
        label=f"Janosi eq. (2-1): {lab}",
    )
    if improved_params is not None:
        q = improved_params
        ci_i = cone_index(
            zz,
            kc=q["kc"],
            kphi=q["kphi"],
            n=q["n"],
            cc=q.get("cc", 0.0) or 0.0,
            phic_deg=q.get("phic_deg", 0.0) or 0.0,
            model=q.get("model", "rm0") or "rm0",
            r_min=q.get("r_min"),
            plate_pair=q.get("plate_pair"),
        )
        ax.plot(
            d.length(zz),
            d.pressure(ci_i),
            color="#555555",
            linewidth=2.0,
            linestyle=":",
            label=q.get("label", "improved model eq. (2-7), same kc, kphi, n"),
        )
    ax.set_xlabel(f"cone-base depth z [{d.L}]")
    ax.set_ylabel(f"cone index CI [{d.P}]")
    ax.set_xlim(left=0)
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=7.5, loc="upper left")
    return _finish(fig, title, synthetic)


# ---------------------------------------------------------------------------
# Figure 4-1: CI fits
# ---------------------------------------------------------------------------


def _ci_axes(ax, profiles, d: _Disp, *, measured_label="measured", model_label="predicted"):
    for i, p in enumerate(profiles):
        c, m = _style(i)
        z = d.length(p["depth"])
        _measured(ax, z, d.pressure(p["ci"]), c, m, f"{p['id']} {measured_label}", size=4)
        if p.get("ci_model") is not None:
            _modelled(ax, z, d.pressure(p["ci_model"]), c, m, f"{p['id']} {model_label}")
    ax.set_xlabel(f"cone-base depth z [{d.L}]")
    ax.set_ylabel(f"cone index CI [{d.P}]")
    ax.set_ylim(bottom=0)


def fig_ci_fit(
    profiles: Sequence[Mapping[str, Any]],
    *,
    units: str = "si",
    title: str | None = "Measured and predicted cone index-sinkage curves",
    synthetic: bool = False,
    measured_label: str = "measured",
    model_label: str = "predicted",
) -> Figure:
    """Figure 4-1 analogue: measured (dashed) and predicted (solid) CI.

    ``profiles``: mappings with ``id``, ``depth`` [m], ``ci`` [kPa] and
    optionally ``ci_model`` [kPa].
    """
    d = _Disp(units)
    fig, axes = _new()
    _ci_axes(axes[0, 0], profiles, d, measured_label=measured_label, model_label=model_label)
    axes[0, 0].legend(fontsize=7.5, ncol=2 if len(profiles) > 3 else 1, loc="upper left")
    return _finish(fig, title, synthetic)


# ---------------------------------------------------------------------------
# Figures 4-2 and 4-3(b): plate pressure-sinkage
# ---------------------------------------------------------------------------


def _radius_key(r: float) -> float:
    return round(float(r), 6)


def _plate_axes(ax, d: _Disp, measured, predicted, bands, *, by_series: bool):
    """Draw plate curves on one axis.

    by_series: colour/marker per series id (one plate size per axis, as in
    Figure 4-2); else per plate size (both sizes on one axis, Figure 4-3(b)).
    """
    ids: list[str] = []
    for s in list(measured) + list(predicted):
        if s["id"] not in ids:
            ids.append(s["id"])
    radii = sorted({_radius_key(s["radius"]) for s in list(measured) + list(predicted)})
    for b in bands:
        key = ids.index(b["id"]) if (by_series and b.get("id") in ids) else 0
        if not by_series:
            key = radii.index(_radius_key(b["radius"])) if _radius_key(b["radius"]) in radii else 0
        c, _ = _style(key)
        ax.fill_between(
            d.length(b["sinkage"]),
            d.pressure(b["lo"]),
            d.pressure(b["hi"]),
            color=c,
            alpha=0.18,
            hatch="///",
            edgecolor=c,
            linewidth=0.0,
            label=b.get("label", f"{b.get('id', '')} band").strip(),
        )
    for curves, kind, draw in (
        (measured, "measured", _measured),
        (predicted, "predicted", _modelled),
    ):
        for s in curves:
            i = ids.index(s["id"]) if by_series else radii.index(_radius_key(s["radius"]))
            c, m = _style(i)
            z = np.asarray(s["sinkage"], float)
            lab = f"{s['id']} {kind}" if by_series else f"{kind} {d.radius_label(s['radius'])}"
            draw(ax, d.length(z), d.pressure(s["pressure"]), c, m, s.get("label", lab))
    ax.set_xlabel(f"sinkage z [{d.L}]")
    ax.set_ylabel(f"plate pressure p [{d.P}]")
    ax.set_xlim(left=0)
    ax.set_ylim(bottom=0)


def fig_plate_fit(
    measured: Sequence[Mapping[str, Any]] = (),
    predicted: Sequence[Mapping[str, Any]] = (),
    bands: Sequence[Mapping[str, Any]] = (),
    *,
    units: str = "si",
    title: str | None = "Measured and predicted plate pressure-sinkage curves",
    synthetic: bool = False,
    one_panel: bool = False,
) -> Figure:
    """Figure 4-2 analogue: one panel per plate size, measured dashed, predicted solid.

    Parameters
    ----------
    measured, predicted : sequences of mappings
        Each with ``id``, ``radius`` [m], ``sinkage`` [m], ``pressure`` [kPa]
        (optional ``label``).
    bands : sequence of mappings
        Uncertainty bands ``radius``, ``sinkage``, ``lo``, ``hi`` (and
        ``median``, ``id``, ``label``) as in ``plate_bands`` of
        ``predict --uncertainty``; drawn as hatched areas.
    one_panel : bool
        All plate sizes on one axis, coloured by size (Figure 4-3(b)).
    """
    d = _Disp(units)
    allc = list(measured) + list(predicted) + list(bands)
    radii = sorted({_radius_key(s["radius"]) for s in allc})
    if not radii:
        raise ValueError("no plate curves to draw")
    if one_panel:
        fig, axes = _new()
        _plate_axes(axes[0, 0], d, measured, predicted, bands, by_series=False)
        axes[0, 0].legend(fontsize=7.5, loc="upper left")
        return _finish(fig, title, synthetic)
    fig, axes = _new(width=5.0 * len(radii) + 0.6, height=4.8, ncols=len(radii))
    for j, r in enumerate(radii):
        ax = axes[0, j]

        def pick(seq, r=r):
            return [s for s in seq if _radius_key(s["radius"]) == r]

        _plate_axes(ax, d, pick(measured), pick(predicted), pick(bands), by_series=True)
        ax.set_title(f"({chr(97 + j)}) plate {d.radius_label(r)}", fontsize=10)
        nleg = len(pick(measured)) + len(pick(predicted)) + len(pick(bands))
        ax.legend(fontsize=6.8, ncol=2 if nleg > 6 else 1, loc="upper left")
    return _finish(fig, title, synthetic)


def fig_site(
    profile: Mapping[str, Any],
    measured: Sequence[Mapping[str, Any]],
    predicted: Sequence[Mapping[str, Any]],
    bands: Sequence[Mapping[str, Any]] = (),
    *,
    units: str = "si",
    title: str | None = None,
    synthetic: bool = False,
) -> Figure:
    """Figures 4-3 to 4-10 analogue: (a) CI-sinkage, (b) P-S of both plates of one site."""
    d = _Disp(units)
    fig, axes = _new(width=10.4, height=4.6, ncols=2)
    _ci_axes(axes[0, 0], [profile], d)
    axes[0, 0].set_title(f"(a) CI-sinkage, {profile['id']}", fontsize=10)
    axes[0, 0].legend(fontsize=7.5, loc="upper left")
    _plate_axes(axes[0, 1], d, measured, predicted, bands, by_series=False)
    axes[0, 1].set_title("(b) plate pressure-sinkage", fontsize=10)
    axes[0, 1].legend(fontsize=7.5, loc="upper left")
    return _finish(fig, title or f"{profile['id']}: measured and predicted", synthetic)


# ---------------------------------------------------------------------------
# The ridge of equally good fits (not in the paper)
# ---------------------------------------------------------------------------


def fig_ridge(
    depth: Any,
    ci: Any,
    *,
    profile_id: str = "profile",
    cone: str = "asabe-large",
    model: str = "rm0",
    r_min: float | None = None,
    plate_pair: tuple[float, float] | None = None,
    bounds: Bounds | None = None,
    reference: Mapping[str, float] | None = None,
    reference_label: str = "reference",
    units: str = "si",
    title: str | None = None,
    synthetic: bool = False,
) -> Figure:
    """The ridge of equally good fits for one CI profile.

    (a) RMSD of the best fit over (phic, n), kc, kphi and cc re-fitted at
    every point: flat along phic (fully mobilised shear: phic trades
    exactly against a common scale of kc and kphi).  (b) RMSD over (phic,
    common scale of kc and kphi) at the best n: a curved valley along
    scale * (1 + tan(phic)/tan(a)) = const.  (c) Profile of the RMSD over n
    and (d) over phic, with the 95% threshold.

    ``depth`` [m], ``ci`` [kPa]; ``reference``: a parameter set (``n``,
    ``phic_deg``) to mark, e.g. the published one.
    """
    d = _Disp(units)
    r = ridge_profile(
        depth, ci, cone=cone, model=model, r_min=r_min, plate_pair=plate_pair, bounds=bounds
    )
    fig, axes = _new(width=10.4, height=8.2, ncols=2, nrows=2)
    best = r["best"]
    # an exact fit has RMSD 0: ratios are then taken to a floor of 1% of the mean CI,
    # the noise floor that predict assumes when it judges what the data leave free
    rmin = max(float(best["rmsd"]), 0.01 * float(np.mean(ci)))
    ratio = r["rmsd"] / rmin
    levels = [1.01, 1.1, 1.5, 2.0, 3.0]
    _ridge_map_n(axes[0, 0], r, ratio, levels, reference, reference_label)
    _ridge_map_scale(axes[0, 1], r, rmin, levels)
    _ridge_profiles(axes, r, d)
    return _finish(
        fig,
        title or f"{profile_id}: the ridge of equally good fits ({model.upper()})",
        synthetic,
    )


def _ratio_map(ax: Any, x: Any, y: Any, ratio: Any, levels: list[float]) -> None:
    """Grey bands and labelled contours of an RMSD ratio (capped at 10)."""
    fill = np.minimum(ratio, 10.0)
    ax.contourf(x, y, fill, levels=[1.0] + levels + [10.0], cmap="Greys_r", alpha=0.55)
    cs = ax.contour(x, y, ratio, levels=levels, colors="black", linewidths=0.8)
    ax.clabel(cs, fmt=lambda v: f"x{v:g}", fontsize=7)


def _ridge_map_n(
    ax: Any,
    r: dict[str, Any],
    ratio: Any,
    levels: list[float],
    reference: Mapping[str, float] | None,
    reference_label: str,
) -> None:
    """Panel (a) of :func:`fig_ridge`: RMSD ratio over (phic, n)."""
    best = r["best"]
    _ratio_map(ax, r["phic"], r["n"], ratio, levels)
    ax.plot(best["phic"], best["n"], "o", color="#D55E00", markersize=8, label="best fit (middle)")
    if reference is not None:
        ax.plot(
            reference.get("phic_deg", np.nan),
            reference.get("n", np.nan),
            "*",
            color="#0072B2",
            markersize=12,
            markeredgecolor="black",
            label=reference_label,
        )
    ax.set_xlabel("cone-terrain friction angle phic [deg]")
    ax.set_ylabel("exponent n [-]")
    ax.set_title("(a) RMSD / min RMSD over (phic, n); kc, kphi, cc re-fitted", fontsize=9.5)
    ax.legend(fontsize=7.5, loc="upper right")


def _ridge_map_scale(ax: Any, r: dict[str, Any], rmin: float, levels: list[float]) -> None:
    """Panel (b) of :func:`fig_ridge`: RMSD ratio over (phic, common scale of kc and kphi)."""
    best = r["best"]
    _ratio_map(ax, r["phic"], r["scale"], r["rmsd_scale"] / rmin, levels)
    ta = math.tan(r["half_angle"])
    ridge = (1 + math.tan(math.radians(best["phic"])) / ta) / (
        1 + np.tan(np.radians(r["phic"])) / ta
    )
    label = "scale (1 + tan phic / tan 15 deg) = const"
    ax.plot(r["phic"], ridge, linestyle="--", color="#D55E00", linewidth=2, label=label)
    ax.set_yscale("log")
    ax.set_ylim(r["scale"][0], r["scale"][-1])
    ticks = [0.4, 0.5, 0.7, 1.0, 1.4, 2.0, 2.5]
    ax.set_yticks(ticks, [f"{t:g}" for t in ticks])
    ax.minorticks_off()
    ax.set_xlabel("cone-terrain friction angle phic [deg]")
    ax.set_ylabel("common scale of kc and kphi [-]")
    ax.set_title(f"(b) RMSD / min over (phic, kc & kphi scale), n = {best['n']:.3g}", fontsize=9.5)
    ax.legend(fontsize=7.5, loc="upper right")


def _ridge_profiles(axes: Any, r: dict[str, Any], d: Any) -> None:
    """Panels (c) and (d) of :func:`fig_ridge`: profiles of the RMSD over n and over phic."""
    prof_n, prof_p = r["rmsd"].min(axis=1), r["rmsd"].min(axis=0)
    # (c) over n, (d) over phic: the best RMSD at each value, and the 95% threshold
    for ax, x, prof, fmt, colour in (
        (axes[1, 0], "n", prof_n, "-o", "#0072B2"),
        (axes[1, 1], "phic", prof_p, "-s", "#CC79A7"),
    ):
        label = f"best RMSD at {x}"
        ax.plot(r[x], d.pressure(prof), fmt, color=colour, markersize=3, label=label)
        thr = d.pressure(r["threshold"])
        ax.axhline(thr, color="black", linestyle="--", label="approx. 95% threshold")
        ax.set_ylabel(f"RMSD of CI [{d.P}]")
    ax = axes[1, 0]
    inside = r["n"][prof_n <= r["threshold"]]
    if inside.size:
        ax.axvspan(
            inside.min(), inside.max(), color="#009E73", alpha=0.2, hatch="\\\\", label="n inside"
        )
    top = float(np.quantile(prof_n, 0.6))
    ax.set_ylim(0, max(top, 3 * r["threshold"]) * d.pf)
    ax.set_xlabel("exponent n [-]")
    ax.set_title("(c) profile over n (all else re-fitted)", fontsize=9.5)
    ax.legend(fontsize=7.5)
    ax = axes[1, 1]
    ax.set_ylim(0, max(float(prof_p.max()), 2 * r["threshold"]) * d.pf * 1.1)
    ax.set_xlabel("cone-terrain friction angle phic [deg]")
    flat = float(prof_p.max() - prof_p.min()) <= 0.01 * float(prof_p.min())
    ax.set_title(
        "(d) profile over phic" + (" (flat: CI alone leaves phic free)" if flat else ""),
        fontsize=9.5,
    )
    ax.legend(fontsize=7.5)


# ---------------------------------------------------------------------------
# summaries
# ---------------------------------------------------------------------------


def fig_bars(
    labels: Sequence[str],
    series: Mapping[str, Sequence[float]],
    *,
    ylabel: str,
    title: str | None = None,
    hline: float | None = None,
    hline_label: str | None = None,
    synthetic: bool = False,
) -> Figure:
    """Grouped bars (one group per label, one hatched bar per series)."""
    fig, axes = _new(width=max(6.0, 0.45 * len(labels) * max(1, len(series)) + 2.5), height=4.4)
    ax = axes[0, 0]
    k = max(1, len(series))
    w = 0.8 / k
    x = np.arange(len(labels))
    hatches = ["", "///", "...", "xx", "\\\\", "oo"]
    for i, (name, vals) in enumerate(series.items()):
        c, _ = _style(i)
        ax.bar(
            x + (i - (k - 1) / 2) * w,
            np.asarray(vals, float),
            width=w,
            color=c,
            edgecolor="black",
            hatch=hatches[i % len(hatches)],
            alpha=0.85,
            label=name,
        )
    if hline is not None:
        ax.axhline(hline, color="black", linestyle="--", label=hline_label)
    ax.set_xticks(x, labels, rotation=45 if len(labels) > 6 else 0, ha="right", fontsize=8)
    ax.set_ylabel(ylabel)
    ax.legend(fontsize=8)
    return _finish(fig, title, synthetic)


def fig_histograms(
    columns: Mapping[str, Sequence[float]],
    *,
    title: str | None = None,
    synthetic: bool = False,
) -> Figure:
    """One histogram per named column (labels carry the units)."""
    names = [k for k, v in columns.items() if len(v)]
    if not names:
        raise ValueError("nothing to draw")
    ncols = min(3, len(names))
    nrows = math.ceil(len(names) / ncols)
    fig, axes = _new(width=3.6 * ncols + 0.4, height=3.0 * nrows + 0.5, ncols=ncols, nrows=nrows)
    for k, ax in enumerate(axes.flat):
        if k >= len(names):
            ax.set_visible(False)
            continue
        v = np.asarray(columns[names[k]], float)
        v = v[np.isfinite(v)]
        c, _ = _style(k)
        bins: Any = min(30, max(5, int(math.sqrt(v.size)) + 1))
        rng = None
        if v.size and np.ptp(v) <= 1e-9 * max(1.0, float(np.abs(v).max())):
            # (nearly) one value: one bar around it, not bins narrower than rounding
            w = max(0.05 * abs(float(v.mean())), 1e-6)
            bins, rng = 1, (float(v.mean()) - w, float(v.mean()) + w)
        ax.hist(
            v,
            bins=bins,
            range=rng,
            color=c,
            edgecolor="black",
            hatch="//",
            alpha=0.8,
            label=f"{v.size} profiles",
        )
        ax.set_xlabel(names[k])
        ax.set_ylabel("profiles")
        ax.legend(fontsize=7.5)
    return _finish(fig, title, synthetic)


# ---------------------------------------------------------------------------
# fields of many profiles: small multiples and a map
# ---------------------------------------------------------------------------


def _multiple_panel(ax, p: Mapping[str, Any], d: _Disp) -> None:
    z = d.length(p["depth"])
    ax.plot(d.pressure(p["ci"]), z, "o", ms=2.6, mfc="white", mec="#333333", mew=0.7)
    if p.get("ci_model") is not None:
        ax.plot(d.pressure(p["ci_model"]), z, "-", color=_COLOURS[0], lw=1.3)
    if p.get("ci_layered") is not None:
        zl = d.length(p.get("depth_layered", p["depth"]))
        ax.plot(d.pressure(p["ci_layered"]), zl, "--", color=_COLOURS[1], lw=1.4)
    for zi in p.get("interfaces") or ():
        ax.axhline(float(d.length(zi)), color=_COLOURS[1], lw=0.8, ls=":")
    flag = "!" if p.get("flagged") else ""
    ax.set_title(
        f"{p.get('label', p['id'])}{' ' + flag if flag else ''}",
        fontsize=6.5,
        pad=1.5,
        color="#a00000" if flag else "black",
    )
    ax.tick_params(labelsize=5.5, length=2, pad=1)


def fig_ci_multiples(
    profiles: Sequence[Mapping[str, Any]],
    *,
    ncols: int = 6,
    units: str = "si",
    title: str | None = None,
    synthetic: bool = False,
) -> Figure:
    """Small multiples: one compact panel per CI profile, depth downwards.

    ``profiles``: mappings with ``id`` (or a shorter ``label``), ``depth``
    [m], ``ci`` [kPa] (drawn as open circles), optionally ``ci_model``
    [kPa] (the one-layer fit, solid), ``ci_layered`` [kPa] with
    ``depth_layered`` [m] (the layered fit, dashed), ``interfaces`` [m]
    (its interfaces, dotted) and ``flagged`` (lack of fit: a "!" and a red
    title).  All panels of a figure share their axes, so profiles compare at
    a glance.
    """
    if not profiles:
        raise ValueError("nothing to draw")
    d = _Disp(units)
    ncols = max(1, min(ncols, len(profiles)))
    nrows = math.ceil(len(profiles) / ncols)
    # a fixed layout in inches: constrained layout costs twice the time with 30 panels
    W = 1.55 * ncols + 0.6
    n_keys = 2 + sum(
        any(p.get(k) is not None and p.get(k) is not False for p in profiles)
        for k in ("ci_layered", "interfaces", "flagged")
    )
    key_cols = max(1, min(n_keys, int(W // 2.1)))
    key_h = 0.2 * math.ceil(n_keys / key_cols)  # legend height [in]
    head = (0.38 if title else 0.04) + key_h + 0.12
    H = 1.45 * nrows + 0.5 + head
    fig = Figure(figsize=(W, H), dpi=110)
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, ncols, squeeze=False, sharex=True, sharey=True)
    top = 1.0 - head / H
    fig.subplots_adjust(
        left=0.55 / W, right=1 - 0.12 / W, bottom=0.5 / H, top=top, wspace=0.22, hspace=0.36
    )
    for k, ax in enumerate(axes.flat):
        ax.grid(True, color="#e0e0e0", linewidth=0.5)
        ax.set_axisbelow(True)
        if k >= len(profiles):
            ax.set_visible(False)
            if k >= ncols:  # the panel above ends its column: give it the CI labels
                axes.flat[k - ncols].xaxis.set_tick_params(labelbottom=True)
            continue
        _multiple_panel(ax, profiles[k], d)
    ax0 = axes[0, 0]
    ax0.invert_yaxis()
    ax0.set_xlim(left=0)
    fig.supxlabel(f"cone index CI [{d.P}]", fontsize=8, y=0.08 / H, va="bottom")
    fig.supylabel(f"cone-base depth z [{d.L}]", fontsize=8, x=0.06 / W, ha="left")
    from matplotlib.lines import Line2D  # legend keys, not drawn in any panel

    handles = [
        Line2D([], [], ls="", marker="o", ms=3, mfc="white", mec="#333333", label="measured"),
        Line2D([], [], ls="-", color=_COLOURS[0], label="one-layer fit"),
    ]
    if any(p.get("ci_layered") is not None for p in profiles):
        handles.append(
            Line2D([], [], ls="--", color=_COLOURS[1], label="layered fit (wins by BIC)")
        )
    if any(p.get("interfaces") is not None for p in profiles):
        handles.append(
            Line2D([], [], ls=":", color=_COLOURS[1], label="interface (layered fit wins)")
        )
    if any(p.get("flagged") for p in profiles):
        handles.append(Line2D([], [], ls="", label="! lack of fit flagged"))
    fig.legend(
        handles=handles,
        loc="upper center",
        bbox_to_anchor=(0.5, 1.0 - (0.38 if title else 0.04) / H),
        ncol=key_cols,
        fontsize=7,
        frameon=False,
    )
    if title:
        fig.suptitle(("SYNTHETIC - " if synthetic else "") + title, fontsize=11, y=1 - 0.06 / H)
    if synthetic:
        fig.text(0.99, 0.01, SYNTHETIC_NOTE, ha="right", va="bottom", fontsize=7, color="#7a4d00")
    fig._terracone_synthetic = synthetic  # type: ignore[attr-defined]
    return fig


def _scale_bar(ax, x: np.ndarray, y: np.ndarray, coslat: float) -> None:
    """A bar of a round number of metres in the lower right corner (spherical earth)."""
    m_per_deg = 111_320.0 * coslat  # metres per degree of longitude at the mean latitude
    span_m = max(float(np.ptp(x)) * m_per_deg, float(np.ptp(y)) * 111_320.0, 1.0)
    raw = span_m / 5.0
    mag = 10 ** math.floor(math.log10(raw))
    length = next(k * mag for k in (5, 2, 1) if k * mag <= raw) if raw >= 1 else 1.0
    dx = length / m_per_deg
    pad_x = 0.05 * max(float(np.ptp(x)), dx)
    pad_y = 0.05 * max(float(np.ptp(y)), dx * coslat)
    x1, y0 = float(x.max()) + pad_x, float(y.min()) - pad_y
    ax.plot([x1 - dx, x1], [y0, y0], color="black", lw=2.5, solid_capstyle="butt")
    label = f"{length / 1000:g} km" if length >= 1000 else f"{length:g} m"
    ax.annotate(label, (x1 - dx / 2, y0), xytext=(0, 4), textcoords="offset points",
                ha="center", fontsize=7)  # fmt: skip


def fig_map(
    lon: Sequence[float],
    lat: Sequence[float],
    values: Sequence[float],
    *,
    label: str,
    layered: Sequence[bool] | None = None,
    flagged: Sequence[bool] | None = None,
    names: Sequence[str] | None = None,
    title: str | None = None,
    synthetic: bool = False,
) -> Figure:
    """Profiles at their longitude and latitude, coloured by a parameter.

    Plain axes in decimal degrees (no tiles, no network), with the aspect
    set so that a metre east is as long as a metre north at the mean
    latitude.  Squares: two layers win; circles: one layer; a red ring:
    lack of fit flagged; grey crosses: no value (not fitted).
    """
    x, y = np.asarray(lon, float), np.asarray(lat, float)
    v = np.asarray(values, float)
    if x.size == 0:
        raise ValueError("nothing to draw")
    two = np.zeros(x.size, bool) if layered is None else np.asarray(layered, bool)
    bad = np.zeros(x.size, bool) if flagged is None else np.asarray(flagged, bool)
    fig, axes = _new(width=7.6, height=6.0)
    ax = axes[0, 0]
    ok = np.isfinite(v)
    vmin, vmax = (float(v[ok].min()), float(v[ok].max())) if ok.any() else (0.0, 1.0)
    sc = None
    for mask, marker, name in ((~two, "o", "one layer"), (two, "s", "two layers win")):
        m = mask & ok
        if m.any():
            sc = ax.scatter(
                x[m], y[m], c=v[m], cmap="viridis", vmin=vmin, vmax=vmax, marker=marker, s=46,
                edgecolors="black", linewidths=0.5, label=name, zorder=3,
            )  # fmt: skip
    if (bad & ok).any():
        ax.scatter(
            x[bad & ok], y[bad & ok], s=120, facecolors="none", edgecolors="#c00000",
            linewidths=1.2, label="lack of fit flagged", zorder=2,
        )  # fmt: skip
    if (~ok).any():
        ax.scatter(x[~ok], y[~ok], marker="x", color="#777777", s=30, label="not fitted")
    if sc is not None:
        fig.colorbar(sc, ax=ax, label=label, shrink=0.85)
    if names is not None and x.size <= 60:
        for xi, yi, nm in zip(x, y, names, strict=False):
            ax.annotate(str(nm), (xi, yi), xytext=(3, 3), textcoords="offset points", fontsize=6)
    coslat = max(0.05, math.cos(math.radians(float(np.mean(y)))))
    ax.set_aspect(1.0 / coslat)
    ax.ticklabel_format(useOffset=False, style="plain")
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(4))
    ax.tick_params(axis="x", labelrotation=25)
    _scale_bar(ax, x, y, coslat)
    ax.set_xlabel("longitude [deg]")
    ax.set_ylabel("latitude [deg]")
    ax.legend(fontsize=7, loc="best")
    return _finish(fig, title, synthetic)


# ---------------------------------------------------------------------------
# output
# ---------------------------------------------------------------------------


def png_bytes(fig: Figure) -> bytes:
    """The figure as PNG bytes."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    return buf.getvalue()


def save_figure(
    fig: Figure,
    directory: str | Path,
    stem: str,
    formats: Sequence[str] = ("png", "svg"),
) -> dict[str, Path]:
    """Write the figure as ``directory/stem.png`` and ``.svg``; return the paths.

    The SVG of a synthetic figure carries the word SYNTHETIC in its
    ``<title>`` too.
    """
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    paths: dict[str, Path] = {}
    meta_title = ("SYNTHETIC - " if getattr(fig, "_terracone_synthetic", False) else "") + stem
    for fmt in formats:
        if fmt not in ("png", "svg"):
            raise ValueError(f"unknown figure format {fmt!r}")
        paths[fmt] = p = out / f"{stem}.{fmt}"
        dpi = {"dpi": 110} if fmt == "png" else {}
        fig.savefig(p, format=fmt, metadata={"Title": meta_title}, **dpi)
        # the layout is settled by the first draw: keep it for the other formats
        fig.set_layout_engine("none")
    return paths
