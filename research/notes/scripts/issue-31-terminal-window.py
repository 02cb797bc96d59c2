"""Issue 31: the widest band of gate heights a pinpoint lander can cross below 5 m/s, by optimal
control, and the success it allows under an unobservable altitude error.

``python research/notes/scripts/issue-31-terminal-window.py [--mass-kg 321] [--max-steps 6]``

Why. Under ``standard`` the navigated altitude at ``LunarPinpointLanding-v2``'s gate (2 km up)
carries a bias of 100 m × the radar weight 0.05 × 2000/3000 = 3.33 m (1σ) that no sensor of the
model reveals (its velocity errors are independent). A law flies the same trajectory relative
to the *navigated* gate whatever the bias, so it lands iff the *true* gate lies in the band of
heights its trajectory crosses at <= 5 m/s: the window. Success is then at most
P(|bias| <= w/2) = 2Φ(w / 2σ) − 1, with the window centred. 99 % needs w >= 2 × 2.576 σ.

What limits w is the env, not a law: the thrust elevation α is boxed in [−50°, 40°] and the
azimuth within 40° of braking (``sc.alpha_bounds_rad``, ``sc.beta_bounds_rad``), so holding
the lander up pushes it backwards (at least cot 40° = 1.19 m/s² per m/s² of support), and the
engine cuts off at any speed minimum inside a 2 s step (a minimum at a step boundary, caused
by the new action, is not a cut-off), after which the lander falls freely.

Method. Over the last N steps of dt (constant α, β, throttle per step, uniform gravity μ/r²
at the gate, mass m at the gate, exact constant-acceleration steps; the Moon's rotation, 10⁻⁵
m/s² here, neglected) maximise the height descended from node 0 to node N with:

- speed <= 5 m/s at every node (the speed is convex in time within a step of constant
  acceleration, so the nodes bound it);
- vertical speed <= 0 at every node (each height is crossed once);
- steps 0..j−1 slowing throughout (v_{k+1}·a_k <= 0), steps j..N−1 speeding up throughout
  (v_k·a_k >= 0): no speed minimum inside a step, so no cut-off (the one minimum at node j);
- optionally (``tail``) the engine cut off at node N at a speed minimum, the lander falling
  from there: + (25 − |v_N|²)/(2g) m of heights crossed below 5 m/s (energy).

Every (N, j) is solved from several starts (IPOPT via CasADi); the best is kept. The stop and
fall the reserve law flies is the case N = 0 with tail: 25/(2g) = 7.7 m. Measured
(2026-11-27): 8.7 m in one step, 15.4 in two, 19.0 in three, 19.9 in four (8 s); no window of
five to seven steps was found (the speed cannot stay under 5 m/s for 10 s of descent). This is
the ideal band: the law's planner (:mod:`agents.experts.pinpoint.terminal`) keeps margins
for the navigation and engine errors and spans ~15 m.
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np
from scipy.stats import norm

LIMIT_M_S = 5.0


def gate_constants():
    import gymnasium as gym

    import lunar_env  # noqa: F401  (registers the envs)

    env = gym.make("LunarPinpointLanding-v2", dt_s=2.0, throttle_channel=True).unwrapped
    sc = env.scenario
    r_gate = sc.body.radius_m + sc.target.altitude_m
    return (sc.body.mu_m3_s2 / r_gate ** 2, sc.vehicle.thrust_n,
            sc.vehicle.exhaust_velocity_m_s, sc.alpha_bounds_rad, sc.beta_bounds_rad)


def solve_window(n_steps: int, j: int, tail: bool, mass_kg: float, dt_s: float, consts,
                 seed: int) -> tuple[float, np.ndarray | None]:
    """(window m, controls (N, 3): α, β rad, throttle) of the best of a few starts; (−inf,
    None) if none converged."""
    import casadi as ca

    g, thrust_n, ve, (a_lo, a_hi), (b_lo, b_hi) = consts
    rng = np.random.default_rng(seed)
    best, best_u = -math.inf, None
    for _ in range(6):
        opti = ca.Opti()
        U = opti.variable(3, n_steps)
        v0 = opti.variable(3)
        v, p, m = v0, ca.MX.zeros(3), ca.MX(mass_kg)
        opti.subject_to(ca.sumsqr(v0) <= LIMIT_M_S ** 2)
        opti.subject_to(v0[2] <= 0)
        for k in range(n_steps):
            al, be, th = U[0, k], U[1, k], U[2, k]
            opti.subject_to(opti.bounded(a_lo, al, a_hi))
            opti.subject_to(opti.bounded(b_lo, be, b_hi))
            opti.subject_to(opti.bounded(0.0, th, 1.0))
            d = ca.vertcat(ca.cos(al) * ca.cos(be), ca.cos(al) * ca.sin(be), ca.sin(al))
            a = th * thrust_n / m * d + ca.DM([0.0, 0.0, -g])
            v_next = v + a * dt_s
            if k < j:
                opti.subject_to(ca.dot(v_next, a) <= 0)
            else:
                opti.subject_to(ca.dot(v, a) >= 0)
            p = p + v * dt_s + 0.5 * a * dt_s ** 2
            m = m - th * thrust_n / ve * dt_s
            v = v_next
            opti.subject_to(ca.sumsqr(v) <= LIMIT_M_S ** 2)
            opti.subject_to(v[2] <= 0)
        window = -p[2]
        if tail:
            window = window + (LIMIT_M_S ** 2 - ca.sumsqr(v)) / (2.0 * g)
        opti.minimize(-window)
        opti.set_initial(U[0, :], rng.uniform(0.0, a_hi, n_steps))
        opti.set_initial(U[1, :], rng.uniform(b_lo, b_hi, n_steps))
        opti.set_initial(U[2, :], rng.uniform(0.2, 0.8, n_steps))
        opti.set_initial(v0, rng.uniform(-3.0, 3.0, 3) * np.array([1.0, 1.0, 0.0])
                         + np.array([0.0, 0.0, -1.0]))
        opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "max_iter": 3000,
                                                      "tol": 1e-9})
        try:
            sol = opti.solve()
        except RuntimeError:
            continue
        w = float(sol.value(window))
        if w > best:
            best, best_u = w, np.atleast_2d(sol.value(U)).reshape(3, n_steps).T
    return best, best_u


def success_bound(window_m: float, sigma_m: float) -> float:
    """P(|bias| <= w/2) for a centred window of width w under a N(0, σ²) altitude error."""
    return float(2.0 * norm.cdf(window_m / (2.0 * sigma_m)) - 1.0)


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mass-kg", type=float, default=321.0,
                    help="mass at the gate (nominal flights of the reserve law: 600 − 279 kg)")
    ap.add_argument("--max-steps", type=int, default=6)
    ap.add_argument("--dt-s", type=float, default=2.0)
    ap.add_argument("--sigma-m", type=float, default=3.35,
                    help="1σ altitude error at the gate (standard: 3.33 m bias, 0.33 m noise)")
    args = ap.parse_args(argv)
    consts = gate_constants()
    g = consts[0]
    print(f"g at the gate {g:.4f} m/s², T/m {consts[1] / args.mass_kg:.3f} m/s², "
          f"dt {args.dt_s:g} s, σ {args.sigma_m:g} m; 99 % needs a window of "
          f"{2 * norm.ppf(0.995) * args.sigma_m:.1f} m")
    fall = LIMIT_M_S ** 2 / (2.0 * g)
    print(f"stop and fall (N = 0): window {fall:.2f} m, success bound "
          f"{100 * success_bound(fall, args.sigma_m):.1f} %")
    overall = (fall, 0, 0, True, None)
    for n in range(1, args.max_steps + 1):
        row = []
        for tail in (False, True):
            best = (-math.inf, None, None)
            for j in range(0, n + 1):
                w, u = solve_window(n, j, tail, args.mass_kg, args.dt_s, consts, seed=n * 100 + j)
                if w > best[0]:
                    best = (w, j, u)
            row.append(best)
            if best[0] > overall[0]:
                overall = (best[0], n, best[1], tail, best[2])
        text = [f"{w:6.2f} m (j = {j})" if math.isfinite(w) else "none found"
                for w, j, _ in row]
        print(f"N = {n:2d} ({n * args.dt_s:4.0f} s): powered {text[0]}, + fall {text[1]}",
              flush=True)
    w, n, j, tail, u = overall
    print(f"\nwidest window {w:.2f} m (N = {n}, j = {j}, {'with' if tail else 'no'} fall): "
          f"success bound {100 * success_bound(w, args.sigma_m):.1f} % at σ {args.sigma_m:g} m")
    if u is not None:
        print("controls (α deg, β deg, throttle):")
        for k, (a, b, t) in enumerate(u):
            print(f"  step {k}: {math.degrees(a):7.2f} {math.degrees(b):7.2f} {t:6.3f}")


if __name__ == "__main__":
    main(sys.argv[1:])
