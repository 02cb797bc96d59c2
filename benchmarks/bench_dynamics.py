"""Throughput of the compiled batched RK4 against peers timed in the same run.

    python benchmarks/bench_dynamics.py [--quick] [--json FILE]

For the planar and the 3D model, and batches of 1, 64, 1024 and 16384 trajectories, prints RK4
steps per second of ``lunar_env.integrators.integrate`` (cubic thrust-angle law, as in paper
000; no events), of a plain vectorised NumPy RK4 over the same ``rhs`` functions, and of scipy
``solve_ivp`` one trajectory at a time (RK45, rtol 1e-9: its steps are not RK4 steps, so it is
compared per trajectory over the same time span), and the ratios. A bare numba RK4 loop over
the planar equations (no control segments, no events) is timed as the ceiling to approach.
First-call compile time and cached load time are measured in fresh subprocesses.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from numba import njit, prange

from lunar_env import dynamics, get_scenario
from lunar_env.integrators import MOON3D, PLANAR, PiecewisePolynomial, integrate

BATCHES = (1, 64, 1024, 16384)
_planar_eom_jit = njit(cache=True, inline="always")(dynamics.planar_eom)
T_SPAN_S = 600.0


def _problem(model_name: str, n: int, rng: np.random.Generator):
    if model_name == "planar":
        sc = get_scenario("zhu2007")
        model = PLANAR
        coef = np.zeros((n, 2, 4))
        coef[:, 0] = rng.uniform(0.0, 0.3, (n, 4))
        coef[:, 1, 0] = 1.0
    else:
        sc = get_scenario("peng2012")
        model = MOON3D
        coef = np.zeros((n, 3, 4))
        coef[:, 0] = rng.uniform(0.0, 0.3, (n, 4))
        coef[:, 1, 0] = np.pi
        coef[:, 2, 0] = 1.0
    tf = float(sc.scaling().time_nd(T_SPAN_S))
    y0 = np.tile(sc.state_nd(), (n, 1))
    return model, sc.params(), y0, PiecewisePolynomial.polynomial(coef, 0.0, tf), tf


def _best_time(fn, repeat: int) -> float:
    best = np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def _numpy_rk4(model, y0, ctrl, params, tf, n_steps):
    h = tf / n_steps
    y = y0.copy()
    for s in range(n_steps):
        t = s * h
        u = ctrl(np.array([[t, t + 0.5 * h, t + h]]))
        k1 = model.rhs(y, u[:, 0], params)
        k2 = model.rhs(y + 0.5 * h * k1, u[:, 1], params)
        k3 = model.rhs(y + 0.5 * h * k2, u[:, 1], params)
        k4 = model.rhs(y + h * k3, u[:, 2], params)
        y = y + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return y


@njit(parallel=True, cache=True)
def _bare_planar_rk4(y0, coef, h, n_steps, p):
    """The ceiling: RK4 over the shared planar equations, nothing else."""
    out = np.empty_like(y0)
    for i in prange(y0.shape[0]):
        a, b, c, d, e = y0[i, 0], y0[i, 1], y0[i, 2], y0[i, 3], y0[i, 4]
        c0, c1, c2, c3 = coef[i, 0], coef[i, 1], coef[i, 2], coef[i, 3]
        for s in range(n_steps):
            t = s * h
            tm = t + 0.5 * h
            te = t + h
            p0 = c0 + t * (c1 + t * (c2 + t * c3))
            p1 = c0 + tm * (c1 + tm * (c2 + tm * c3))
            p2 = c0 + te * (c1 + te * (c2 + te * c3))
            k1 = _planar_eom_jit(a, b, d, e, p0, 1.0, p[0], p[1])
            k2 = _planar_eom_jit(a + 0.5 * h * k1[0], b + 0.5 * h * k1[1], d + 0.5 * h * k1[3],
                                 e + 0.5 * h * k1[4], p1, 1.0, p[0], p[1])
            k3 = _planar_eom_jit(a + 0.5 * h * k2[0], b + 0.5 * h * k2[1], d + 0.5 * h * k2[3],
                                 e + 0.5 * h * k2[4], p1, 1.0, p[0], p[1])
            k4 = _planar_eom_jit(a + h * k3[0], b + h * k3[1], d + h * k3[3], e + h * k3[4], p2,
                                 1.0, p[0], p[1])
            a += h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
            b += h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
            c += h / 6 * (k1[2] + 2 * k2[2] + 2 * k3[2] + k4[2])
            d += h / 6 * (k1[3] + 2 * k2[3] + 2 * k3[3] + k4[3])
            e += h / 6 * (k1[4] + 2 * k2[4] + 2 * k3[4] + k4[4])
        out[i, 0], out[i, 1], out[i, 2], out[i, 3], out[i, 4] = a, b, c, d, e
    return out


def _scipy_per_trajectory(model, y0, ctrl, params, tf, n_traj: int) -> float:
    from scipy.integrate import solve_ivp

    def f(t, y, i):
        return model.rhs(y[None], _u(ctrl, i, t)[None], params)[0]

    t = time.perf_counter()
    for i in range(n_traj):
        solve_ivp(f, (0.0, tf), y0[i], method="RK45", rtol=1e-9, atol=1e-12, args=(i,))
    return (time.perf_counter() - t) / n_traj


def _u(ctrl, i, t):
    c = ctrl.coefs[i, 0]
    return c[:, 0] + t * (c[:, 1] + t * (c[:, 2] + t * c[:, 3]))


def _compile_times(fresh: bool = True) -> dict[str, float]:
    """First-call compile and cached-load time of the planar kernels, in fresh processes."""
    here = os.path.dirname(os.path.abspath(__file__))
    code = "\n".join([
        "import time; t = time.perf_counter()",
        f"import sys; sys.path.insert(0, {here!r})",
        "import numpy as np, bench_dynamics as b",
        "for name in ('planar', 'moon3d'):",
        "    m, p, y0, c, tf = b._problem(name, 2, np.random.default_rng(0))",
        "    b._note_load_compile(m, p, y0, c, tf)",
        "print(time.perf_counter() - t)",
    ])
    out = {}
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache) if fresh else dict(os.environ)
        labels = ("first_call_compile_s", "cached_load_s") if fresh else ("cached_load_s",)
        for label in labels:
            r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                               text=True, check=True)
            out[label] = float(r.stdout.strip().splitlines()[-1])
    return out


def _note_load_compile(model, params, y0, ctrl, tf):
    """Compile/load both kernels outside the timings."""
    for par in (False, True):
        integrate(model, y0[:2], t0_nd=0.0, dt_nd=tf / 4, n_steps=4, params=params, parallel=par,
                  control=PiecewisePolynomial(ctrl.breaks[:2], ctrl.coefs[:2]))


def run(quick: bool) -> dict:
    rng = np.random.default_rng(0)
    batches = (1, 64, 1024) if quick else BATCHES
    n_steps = 200 if quick else 600
    repeat = 2 if quick else 3
    results: dict = {"n_steps": n_steps, "t_span_s": T_SPAN_S, "rows": []}
    print(f"RK4 steps/s over {T_SPAN_S:.0f} s in {n_steps} steps (cubic thrust-angle law)")
    print(f"{'model':7s} {'batch':>6s} {'ours':>12s} {'numpy':>12s} {'ours/numpy':>11s} "
          f"{'scipy s/traj':>13s} {'ours/scipy per traj':>20s}")
    for model_name in ("planar", "moon3d"):
        model, params, y0_all, ctrl_all, tf = _problem(model_name, max(batches), rng)
        _note_load_compile(model, params, y0_all, ctrl_all, tf)
        scipy_s = _scipy_per_trajectory(model, y0_all, ctrl_all, params, tf, 2 if quick else 10)
        for n in batches:
            y0 = y0_all[:n]
            ctrl = PiecewisePolynomial(ctrl_all.breaks[:n], ctrl_all.coefs[:n])
            def ours(y0=y0, ctrl=ctrl, model=model, params=params, tf=tf):
                integrate(model, y0, t0_nd=0.0, dt_nd=tf / n_steps, n_steps=n_steps,
                          control=ctrl, params=params)

            # NumPy is timed over fewer steps at the largest batch (it is linear in steps)
            np_steps = n_steps if n <= 1024 else 60

            def peer(y0=y0, ctrl=ctrl, model=model, params=params, tf=tf, np_steps=np_steps):
                _numpy_rk4(model, y0, ctrl, params, tf, np_steps)

            t_ours = _best_time(ours, repeat)
            t_np = _best_time(peer, 1) * n_steps / np_steps
            ours_sps = n * n_steps / t_ours
            np_sps = n * n_steps / t_np
            ratio_scipy = scipy_s / (t_ours / n)
            row = dict(model=model_name, batch=n, ours_steps_per_s=ours_sps,
                       numpy_steps_per_s=np_sps, ours_over_numpy=ours_sps / np_sps,
                       scipy_s_per_trajectory=scipy_s,
                       ours_over_scipy_per_trajectory=ratio_scipy)
            results["rows"].append(row)
            print(f"{model_name:7s} {n:6d} {ours_sps:12.3e} {np_sps:12.3e} "
                  f"{ours_sps / np_sps:11.1f} {scipy_s:13.4f} {ratio_scipy:20.0f}")
    # ceiling: bare loop, planar, biggest batch
    model, params, y0, ctrl, tf = _problem("planar", max(batches), rng)
    c = np.ascontiguousarray(ctrl.coefs[:, 0, 0, :])
    p = params.as_array()
    _bare_planar_rk4(y0[:2], c[:2], tf / n_steps, 2, p)
    t_bare = _best_time(lambda: _bare_planar_rk4(y0, c, tf / n_steps, n_steps, p), repeat)
    bare = len(y0) * n_steps / t_bare
    ours = [r for r in results["rows"] if r["model"] == "planar" and r["batch"] == max(batches)]
    results["bare_numba_planar_steps_per_s"] = bare
    results["ours_over_bare"] = ours[0]["ours_steps_per_s"] / bare
    print(f"bare numba planar RK4 loop (ceiling) at batch {len(y0)}: {bare:.3e} steps/s; "
          f"ours/bare = {results['ours_over_bare']:.2f}")
    # --quick skips the fresh-cache compile (two extra processes compiling four kernels)
    results.update(_compile_times(fresh=not quick))
    if "first_call_compile_s" in results:
        print(f"first call incl. compile (4 kernels): {results['first_call_compile_s']:.1f} s")
    print(f"first call from the on-disk cache (4 kernels): {results['cached_load_s']:.2f} s")
    results["targets"] = {"planar_steps_per_s_at_16384": 3e7,
                          "ours_over_scipy_per_trajectory": 50}
    results["cpu_count"] = os.cpu_count()
    return results


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller batches, fewer repeats")
    ap.add_argument("--json", metavar="FILE", help="write results as JSON")
    args = ap.parse_args(argv)
    res = run(args.quick)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(res, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
