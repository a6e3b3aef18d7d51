"""Forward-model benchmark: terracone.cone_index against quadrature and a plain closed form.

Run as ``python benchmarks/forward.py``.  One batch is 64 parameter sets x 61
depths (params shaped (64, 1), depths (61,)), fully mobilised shear, for the
RM0 and the RM1 (tangent) pressure laws.  Three ways of computing eq. (2-7)
of Huang et al. are timed:

* terracone.cone_index on the whole batch;
* scipy.integrate.quad of eqs. (2-5)/(2-6), written in the paper's variable
  h, on a subset of 200 (parameter set, depth) pairs, extrapolated per
  evaluation;
* a plain numpy closed form of eqs. (2-5)/(2-6) written straightforwardly
  with powers ((z+H)^(n+1) - z^(n+1) and so on).

Timings use time.perf_counter and the best of several repeats.  Printed:
evaluations per second of each, the ratios terracone/quad and
terracone/plain, and the largest relative errors of terracone against
quad (on the 200 pairs) and against the plain form (on the whole batch).

Targets: terracone >= 1000x quad, >= 1x the plain closed form, error <= 1e-9.
With ``--profile`` the time spent inside terracone.physics.cone.cone_index_basis is
broken down line by line (by timing its steps on the same batch).
"""

from __future__ import annotations

import argparse
import importlib.util
import inspect
import math
import sys
import time
import warnings
from pathlib import Path

# run as a script, benchmarks/ heads sys.path: keep it off, so no script here can shadow an
# installed package (a benchmark named coverage.py once hid the one numba probes, silently
# turning the compiled kernels off)
_HERE = Path(__file__).resolve().parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _HERE]

import numpy as np  # noqa: E402
from scipy.integrate import IntegrationWarning, quad  # noqa: E402

import terracone  # noqa: E402
from terracone.physics.cone import cone_index_basis, get_cone  # noqa: E402
from terracone.physics.plate import pressure_law  # noqa: E402

INCH = 0.0254
AREA = 0.5 * INCH**2  # asabe-large, 0.5 in^2, 30 deg
R = math.sqrt(AREA / math.pi)
TAN15 = math.tan(math.radians(15.0))
H = R / TAN15

P, Z = 64, 61
N_QUAD = 200


def make_batch(seed: int = 20201):
    rng = np.random.default_rng(seed)
    params = dict(
        kc=rng.uniform(0.0, 200.0, (P, 1)),
        kphi=rng.uniform(300.0, 6000.0, (P, 1)),
        n=rng.uniform(0.3, 1.4, (P, 1)),
        cc=rng.uniform(0.0, 5.0, (P, 1)),
        phic_deg=rng.uniform(5.0, 25.0, (P, 1)),
    )
    r_min = rng.uniform(0.001, 0.02, (P, 1))  # some below R = 8 mm, some above
    depth = np.linspace(0.0, 0.6, Z)  # 0 to 600 mm every 10 mm
    return params, r_min, depth


# ---------------------------------------------------------------------------
# (a) quadrature of eqs. (2-5) and (2-6) in h, fully mobilised shear
# ---------------------------------------------------------------------------


def ci_quad(z, kc, kphi, n, cc, phic_deg, r_min=None):
    tan_phic = math.tan(math.radians(phic_deg))

    def integrand(h):
        u = z + h
        r = R * (H - h) / H
        if r_min is None or r >= r_min:
            p = (kc / r + kphi) * u**n
        else:
            p = (kc / r_min + kphi) * u**n + (r_min - r) * kc / r_min**2 * u**n
        return TAN15 * p * r + (cc + p * tan_phic) * r

    points = None
    if r_min is not None and r_min < R:
        points = [H * (1.0 - r_min / R)]
    val, _ = quad(integrand, max(0.0, -z), H, points=points, epsabs=0.0, epsrel=1e-13, limit=500)
    return 2.0 * math.pi * val / (math.pi * R * R)


# ---------------------------------------------------------------------------
# (b) plain closed form, fully mobilised shear, z >= 0
# ---------------------------------------------------------------------------


def ci_plain_rm0(z, kc, kphi, n, cc, phic_deg):
    """eqs. (2-5)-(2-7) integrated by hand: u = z + h, r = R (z + H - u) / H."""
    zH = z + H
    i0 = (zH ** (n + 1) - z ** (n + 1)) / (n + 1)  # int (z+h)^n dh
    i1 = (zH ** (n + 2) - z ** (n + 2)) / (n + 2)  # int (z+h)^(n+1) dh
    # int (kc + kphi r)(z+h)^n dh, r = R/H (z + H - u)
    ipr = kc * i0 + kphi * (R / H) * (zH * i0 - i1)
    icc = 0.5 * R * H  # int r dh
    return 2.0 * ((TAN15 + np.tan(np.radians(phic_deg))) * ipr + cc * icc) / (R * R)


def ci_plain_rm1(z, kc, kphi, n, cc, phic_deg, r_min):
    """RM1 tangent: Bekker for u < ub = z + H - r_min H / R, the tangent line below."""
    t = R / H
    zH = z + H
    ub = np.clip(zH - r_min / t, z, zH)
    a, b = 2.0 / r_min, 1.0 / r_min**2  # p r = [kc (a r - b r^2) + kphi r] u^n

    def m(k, lo, hi):  # int_lo^hi u^(n+k) du
        return (hi ** (n + k + 1) - lo ** (n + k + 1)) / (n + k + 1)

    bek = kc * m(0, z, ub) + kphi * t * (zH * m(0, z, ub) - m(1, z, ub))
    # r = t (zH - u): polynomial in u
    c0 = kc * (a * t * zH - b * t * t * zH * zH) + kphi * t * zH
    c1 = kc * (-a * t + 2.0 * b * t * t * zH) - kphi * t
    c2 = -kc * b * t * t
    lin = c0 * m(0, ub, zH) + c1 * m(1, ub, zH) + c2 * m(2, ub, zH)
    icc = 0.5 * R * H
    return 2.0 * ((TAN15 + np.tan(np.radians(phic_deg))) * (bek + lin) + cc * icc) / (R * R)


# ---------------------------------------------------------------------------


def best_of(fn, repeat: int, number: int) -> float:
    """Best time of one call [s] over `repeat` runs of `number` calls."""
    best = math.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        best = min(best, (time.perf_counter() - t0) / number)
    return best


def max_rel(a, b) -> float:
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    return float(np.max(np.abs(a - b) / np.abs(b)))


def run(model: str, params, r_min, depth, quad_repeat: int = 5):
    rm = r_min if model == "rm1" else None
    kw = dict(params, model=model, r_min=rm)

    def tc():
        return terracone.cone_index(depth, **kw)

    if model == "rm0":

        def plain():
            return ci_plain_rm0(depth, **params)
    else:

        def plain():
            return ci_plain_rm1(depth, **params, r_min=r_min)

    ci_tc = tc()
    ci_plain = plain()
    assert ci_tc.shape == (P, Z) and ci_plain.shape == (P, Z)

    t_tc = best_of(tc, repeat=15, number=20)
    t_plain = best_of(plain, repeat=15, number=20)

    # the quadrature subset: 200 (parameter set, depth) pairs spread over the batch
    idx = [(i % P, (i * 7) % Z) for i in range(N_QUAD)]
    scal = [{k: float(v[i, 0]) for k, v in params.items()} for i, _ in idx]
    rms = [float(r_min[i, 0]) if model == "rm1" else None for i, _ in idx]
    zs = [float(depth[j]) for _, j in idx]

    def quad_all():
        return [ci_quad(z, **s, r_min=q) for z, s, q in zip(zs, scal, rms)]

    with warnings.catch_warnings():
        warnings.simplefilter("error", IntegrationWarning)
        ci_q = np.array(quad_all())
        t_quad = best_of(quad_all, repeat=quad_repeat, number=1)

    ev_tc = P * Z / t_tc
    ev_plain = P * Z / t_plain
    ev_quad = N_QUAD / t_quad
    sub_tc = np.array([ci_tc[i, j] for i, j in idx])
    return dict(
        model=model,
        ev_tc=ev_tc,
        ev_plain=ev_plain,
        ev_quad=ev_quad,
        err_quad=max_rel(sub_tc, ci_q),
        err_plain=max_rel(ci_tc, ci_plain),
        err_plain_vs_quad=max_rel(np.array([ci_plain[i, j] for i, j in idx]), ci_q),
    )


def line_times(fn, functions, calls: int, rounds: int = 7):
    """Inclusive wall time per source line of `functions`, per call of fn.

    A small sys.settrace line timer (no extra dependency): fn is called
    `calls` times under the tracer, `rounds` times over, and each line keeps
    its best round (so a preempted round does not count).  The tracer's own
    overhead, about a microsecond per traced line, is small beside the numpy
    work of a line on the (64, 61) arrays.
    """
    import linecache
    import sys
    from collections import defaultdict

    codes = {f.__code__ for f in functions}
    best: dict = {}
    for _ in range(rounds):
        acc = defaultdict(float)
        last = {}

        def local(frame, event, arg, acc=acc, last=last):
            now = time.perf_counter()
            if frame in last:
                lineno, t = last[frame]
                acc[(frame.f_code.co_filename, frame.f_code.co_name, lineno)] += now - t
            if event == "return":
                last.pop(frame, None)
            else:
                last[frame] = (frame.f_lineno, time.perf_counter())
            return local

        def tracer(frame, event, arg, local=local):
            if frame.f_code in codes:
                return local(frame, event, arg)
            return None

        sys.settrace(tracer)
        try:
            for _ in range(calls):
                fn()
        finally:
            sys.settrace(None)
        for key, t in acc.items():
            best[key] = min(best.get(key, math.inf), t / calls)
    rows = sorted(best.items(), key=lambda kv: -kv[1])
    return [
        (name, lineno, t, linecache.getline(fname, lineno).strip())
        for (fname, name, lineno), t in rows
    ]


def profile(params, r_min, depth, model: str = "rm0", top: int = 14):
    """Where the time of cone_index goes: the wrapper and the lines of cone_index_basis."""
    from terracone.physics import cone as cone_mod

    rm = r_min if model == "rm1" else None
    law = pressure_law(model, r_min=rm)
    kw = dict(params, model=model, r_min=rm)
    t_all = best_of(lambda: terracone.cone_index(depth, **kw), 15, 20)
    t_basis = best_of(
        lambda: cone_index_basis(depth, n=params["n"], phic_deg=params["phic_deg"], law=law), 15, 20
    )
    t_plain = best_of(
        (lambda: ci_plain_rm0(depth, **params))
        if model == "rm0"
        else (lambda: ci_plain_rm1(depth, **params, r_min=r_min)),
        15,
        20,
    )
    print(f"    cone_index, whole call          {t_all * 1e6:8.1f} us per batch")
    print(f"    of which cone_index_basis       {t_basis * 1e6:8.1f} us")
    print(f"    wrapper (checks, units, kc*A..) {(t_all - t_basis) * 1e6:8.1f} us")
    print(f"    plain closed form, whole call   {t_plain * 1e6:8.1f} us")
    # every function defined in terracone.physics.cone (cone_index_basis and its helpers)
    funcs = [
        f
        for f in vars(cone_mod).values()
        if inspect.isfunction(f) and f.__module__ == cone_mod.__name__
    ]
    rows = line_times(
        lambda: cone_index_basis(depth, n=params["n"], phic_deg=params["phic_deg"], law=law),
        funcs,
        calls=30,
    )
    total = sum(t for name, _, t, _ in rows if name == "cone_index_basis")
    print(
        f"    lines of terracone.physics.cone under cone_index_basis (traced total {total * 1e6:.0f} us;"
    )
    print("    inclusive: a line that calls a helper also counts the helper's lines):")
    for name, lineno, t, src in rows[:top]:
        print(f"    {t * 1e6:7.1f} us  {name}:{lineno:<4d} {src[:70]}")


def kernel_vs_numpy(params, r_min, depth) -> None:
    """Basis columns of the compiled kernel against cone_index_basis (the numpy reference).

    The exact solver evaluates the basis for one profile at one n at a time
    (a few dozen depths), where numpy's per-call overhead dominates; both are
    timed that way (one n per call, every n of the batch) and on the whole
    batch at once.
    """
    from terracone import jit

    if not jit.enabled():
        print("\n[compiled basis kernel] numba is off (TERRACONE_NUMBA=0): skipped")
        return
    from terracone.inverse.solver.kernels import basis_columns

    ns = params["n"][:, 0].copy()
    print("\n[compiled basis kernel vs numpy cone_index_basis, RM0 and RM1]")
    for model in ("rm0", "rm1"):
        _kernel_case(model, ns, depth, basis_columns)


def _kernel_case(model, ns, depth, basis_columns) -> None:
    cone = get_cone("asabe-large")
    law = pressure_law(model, r_min=0.004 if model == "rm1" else None)
    c = [float(np.asarray(v)) for v in law.coefficients()]
    geo = (cone.height, cone.radius, model == "rm1", *c)
    A, B, C = cone_index_basis(depth, n=ns[:, None], law=law, cone=cone)
    Ak, Bk, Ck = basis_columns(depth, ns, *geo)
    err = max(max_rel(Ak, A), max_rel(Bk, B), max_rel(Ck, C[0] if C.ndim > 1 else C))
    t_np_all = best_of(lambda: cone_index_basis(depth, n=ns[:, None], law=law, cone=cone), 7, 10)
    t_k_all = best_of(lambda: basis_columns(depth, ns, *geo), 7, 10)
    one = np.empty(1)

    def np_each():
        for v in ns:
            cone_index_basis(depth, n=v, law=law, cone=cone)

    def k_each():
        for v in ns:
            one[0] = v
            basis_columns(depth, one, *geo)

    t_np_each = best_of(np_each, 5, 2)
    t_k_each = best_of(k_each, 5, 2)
    print(
        f"  {model}: whole batch numpy {P * Z / t_np_all:12,.0f} /s, kernel "
        f"{P * Z / t_k_all:12,.0f} /s, ratio {t_np_all / t_k_all:6.1f}; one n per call "
        f"numpy {P * Z / t_np_each:12,.0f} /s, kernel {P * Z / t_k_each:12,.0f} /s, "
        f"ratio {t_np_each / t_k_each:6.1f}; max rel difference {err:.1e}"
    )


def startup() -> None:
    spec = importlib.util.spec_from_file_location("terracone_bench_startup", _HERE / "startup.py")
    st = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(st)
    print("\nstart-up (fresh processes; cold = empty numba cache, warm = cached kernels)")
    st.report("terracone --help", st.cli_help())
    st.report(
        "terracone ci (a forward curve: no kernel, numba not imported)",
        st.measure(
            "import sys\nfrom click.testing import CliRunner\nfrom terracone.cli import cli",
            "CliRunner().invoke(cli, ['ci', '--kc', '100', '--kphi', '5000', '--n', '0.8', "
            "'--depths', '0,0.1,0.2'])\n"
            "assert 'numba' not in sys.modules",
        ),
    )


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--profile", action="store_true", help="profile cone_index_basis")
    ap.add_argument("--no-startup", action="store_true", help="skip the start-up measurements")
    args = ap.parse_args(argv)

    params, r_min, depth = make_batch()
    print(
        f"terracone {terracone.__version__}: {P} parameter sets x {Z} depths "
        f"= {P * Z} evaluations per batch, fully mobilised shear, asabe-large cone"
    )
    print(f"quadrature: {N_QUAD} evaluations, scipy.integrate.quad epsrel=1e-13; best of repeats")
    ok = True
    for model in ("rm0", "rm1"):
        res = run(model, params, r_min, depth)
        r_quad = res["ev_tc"] / res["ev_quad"]
        r_plain = res["ev_tc"] / res["ev_plain"]
        print(f"\n[{model}]")
        print(f"  terracone.cone_index   {res['ev_tc']:14,.0f} evaluations/s")
        print(f"  scipy quad (2-5)/(2-6) {res['ev_quad']:14,.0f} evaluations/s")
        print(f"  plain numpy closed form{res['ev_plain']:14,.0f} evaluations/s")
        print(f"  ratio terracone/quad   {r_quad:14,.1f}   (target >= 1000)")
        print(f"  ratio terracone/plain  {r_plain:14,.2f}   (target >= 1)")
        print(f"  max rel error vs quad  {res['err_quad']:14.2e}   (target <= 1e-9)")
        print(f"  max rel error vs plain {res['err_plain']:14.2e}   (target <= 1e-9)")
        print(f"  (plain vs quad         {res['err_plain_vs_quad']:14.2e})")
        ok &= r_quad >= 1000 and res["err_quad"] <= 1e-9 and res["err_plain"] <= 1e-9
        if r_plain < 1:
            ok = False
            print("  terracone is slower than the plain closed form; profile of cone_index_basis:")
        if r_plain < 1 or args.profile:
            profile(params, r_min, depth, model)
    kernel_vs_numpy(params, r_min, depth)
    if not args.no_startup:
        startup()
    print("\nall targets met" if ok else "\nsome targets missed")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
