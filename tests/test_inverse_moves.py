"""The fits moved to terracone.inverse (issue 13): old import paths are aliases of the new ones.

layers.py, shear.py, bevameter.py and uncertainty.py keep every public name
they had; these tests check that each old name is the very object of its
new home, that the moved modules do not import the fits back from the old
paths (nor private names from each other), and that they stay short.
"""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import numpy as np
import pytest

import terracone
from terracone import inverse

PKG = Path(terracone.__file__).parent

#: old module -> (new module, names it re-exports)
MOVES = {
    "terracone.layers": ("terracone.inverse.layered", ["LayeredResult", "fit_layered"]),
    "terracone.bevameter": (
        "terracone.inverse.plates",
        ["METHODS", "PlateFit", "PlatesFit", "fit_plate_test", "fit_plates"],
    ),
    "terracone.shear": (
        "terracone.inverse.shear",
        ["ShearFit", "ShearTestFit", "fit_shear", "fit_shear_test"],
    ),
}

#: Every public name terracone.uncertainty defined before the move, and its new home.
UNCERTAINTY = {
    "PARAM_NAMES": "priors",
    "LABELS": "uncertainty",
    "DETERMINED_BELOW": "uncertainty",
    "WEAKLY_BELOW": "uncertainty",
    "DEFAULT_PLATES": "uncertainty",
    "DEFAULT_SINKAGES": "uncertainty",
    "RHO_MAX": "noise",
    "identifiability_label": "uncertainty",
    "PlateBand": "uncertainty",
    "NoiseModel": "noise",
    "SamplerDiagnostics": "uncertainty",
    "PosteriorResult": "uncertainty",
    "CalibrationPrior": "priors",
    "ar1_coefficients": "noise",
    "ar1_noise": "noise",
    "estimate_correlation": "noise",
    "spline_sse": "likelihood",
    "spline_sse_compiled": "likelihood",
    "Likelihood": "likelihood",
    "posterior": "uncertainty",
    "integrated_time": "sampler",
    "plate_bands": "uncertainty",
    "posterior_for_result": "uncertainty",
    "LayeredPosterior": "layered",
    "layered_posterior": "layered",
}

#: Modules this move wrote; the aliases are the four old modules.
MOVED = ["layered", "plates", "shear", "uncertainty", "noise", "priors", "likelihood", "sampler"]
OWNED = [PKG / "inverse" / f"{m}.py" for m in MOVED] + [PKG / "layers.py", PKG / "shear.py"]
ALIASES = {"terracone.layers", "terracone.shear", "terracone.bevameter", "terracone.uncertainty"}


@pytest.mark.parametrize("old", sorted(MOVES))
def test_old_names_are_the_new_objects(old):
    new, names = MOVES[old]
    old_mod, new_mod = importlib.import_module(old), importlib.import_module(new)
    for name in names:
        assert getattr(old_mod, name) is getattr(new_mod, name), name
        assert name in old_mod.__all__
        assert name in dir(old_mod)


def test_uncertainty_keeps_every_public_name():
    unc = importlib.import_module("terracone.uncertainty")
    for name, home in UNCERTAINTY.items():
        new = importlib.import_module(f"terracone.inverse.{home}")
        assert getattr(unc, name) is getattr(new, name), name
    assert set(unc.__all__) == set(UNCERTAINTY)


def test_uncertainty_jit_switch_reaches_the_likelihood(monkeypatch):
    """``terracone.uncertainty.JIT_ENABLED = False`` (benchmarks/uncertainty.py) still switches."""
    unc = importlib.import_module("terracone.uncertainty")
    from terracone.inverse import likelihood

    assert unc.JIT_ENABLED is likelihood.JIT_ENABLED
    # set and restored by hand: pytest >= 9.2's monkeypatch restores through the
    # instance __dict__, which a forwarded module attribute does not live in
    old = likelihood.JIT_ENABLED
    try:
        unc.JIT_ENABLED = False
        assert likelihood.JIT_ENABLED is False and unc.JIT_ENABLED is False
        calls = []
        monkeypatch.setattr(likelihood, "spline_sse", lambda *a: calls.append(a) or np.zeros(1))
        lik = likelihood.Likelihood(
            np.array([0.0, 0.01, 0.02]),
            np.array([100.0, 200.0, 300.0]),
            cone=terracone.get_cone("asabe-large"),
            law=terracone.plate.pressure_law("rm0"),
            Kc=None,
            n_range=(0.5, 0.5),
            weights=np.ones(3),
            phi=np.zeros(2),
        )
        lik.sse(np.array([[1.0, 1.0, 0.5, 0.0, 0.0]]))
        assert len(calls) == 1
    finally:
        likelihood.JIT_ENABLED = old
    assert likelihood.JIT_ENABLED is old


def test_inverse_exports_the_fits():
    for home in ("layered", "plates", "uncertainty", "shear"):
        mod = importlib.import_module(f"terracone.inverse.{home}")
        for name in mod.__all__:
            if name in inverse.__all__:
                assert getattr(inverse, name) is getattr(mod, name)
    for name in ("fit_layered", "fit_plates", "fit_shear", "posterior", "layered_posterior"):
        assert name in inverse.__all__ and callable(getattr(inverse, name))


def test_star_import_and_unknown_names():
    ns: dict = {}
    exec("from terracone.shear import *", ns)
    assert ns["fit_shear"] is inverse.fit_shear and "janosi_hanamoto" in ns
    exec("from terracone.layers import *", ns)
    assert ns["fit_layered"] is inverse.fit_layered and "layered_basis" in ns
    import terracone.layers as layers

    with pytest.raises(AttributeError, match="module 'terracone.layers' has no attribute 'nope'"):
        layers.nope  # noqa: B018


def _imports(path: Path) -> list[tuple[str, str]]:
    """(absolute module, name) of every ``from X import name`` in a file of terracone."""
    rel = path.relative_to(PKG.parent).with_suffix("")
    package = list(rel.parts[:-1])
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            base = package[: len(package) - node.level + 1] if node.level else []
            mod = ".".join(base + ([node.module] if node.module else []))
            out += [(mod, a.name) for a in node.names]
    return out


@pytest.mark.parametrize("path", OWNED, ids=lambda p: p.name)
def test_moved_modules_do_not_use_the_old_paths(path):
    fits = {n for _, names in MOVES.values() for n in names} | set(UNCERTAINTY)
    for mod, name in _imports(path):
        assert not (mod in ALIASES and name in fits), f"{path.name} imports {name} from {mod}"
        assert not name.startswith("_"), f"{path.name} imports the private {mod}.{name}"


@pytest.mark.parametrize("path", OWNED, ids=lambda p: p.name)
def test_moved_modules_are_short(path):
    text = path.read_text()
    assert len(text.splitlines()) < 900
    tree = ast.parse(text)
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef):
            assert node.end_lineno - node.lineno < 100, f"{path.name}: {node.name}"
    # a move is a cut, not a copy: every top-level function and class is defined once
    defs = [n.name for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))]
    assert sorted(defs) == sorted(set(defs)), path.name


def test_whiten_ar1_is_the_inverse_cholesky_factor():
    """whiten_ar1 maps AR(1) noise to white noise: W S W^T = I (S_ij = rho^|i-j| / phi)."""
    from terracone.inverse.noise import ar1_coefficients, whiten_ar1

    z = np.array([0.0, 0.01, 0.02, 0.035, 0.05, 0.06, 0.08])  # irregular spacing
    rho, dz0 = 0.6, 0.01
    phi = ar1_coefficients(z, rho, dz0)
    S = rho ** (np.abs(z[:, None] - z[None, :]) / dz0)
    W = whiten_ar1(np.eye(z.size), phi).T  # row k of the call whitens the unit vector e_k
    np.testing.assert_allclose(W @ S @ W.T, np.eye(z.size), atol=1e-12)
