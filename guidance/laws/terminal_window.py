"""The pinpoint terminal window: the last seconds flown so that an unknown altitude error at the
gate still crosses it below the success speed.

Why. Under ``standard`` the navigated altitude at ``LunarPinpointLanding-v2``'s gate
carries a bias of 3.3 m (1σ) that nothing in the navigation reveals. A law that stops above the
navigated gate and falls (the engine cuts off at the speed minimum) crosses the true gate below
5 m/s only if the stop is 0-7.7 m above it: a window of 7.7 m, at most 75 % of the cases. With
the throttle a wider window exists: steps whose speed never has a minimum inside them (so the
engine stays on), at 5 m/s or less, descending throughout. The env's thrust box (elevation
<= 40°, azimuth within 40° of braking) forbids a hover, since holding the lander up pushes it
backwards, so the window is a weave: full elevation, the azimuth swung from one side to the
other, a third of the thrust. By optimal control it spans 15 m in 4 s, 19 m in 6 s and 19.9 m in
8 s: 99.7 % at 3.35 m.

:class:`TerminalWindow` re-plans that window at every decision from the navigation solution
(receding horizon): the controls of the next ``steps`` decisions that keep the navigated gate
(height 0) deepest inside the band of heights crossed at <= ``speed_limit_m_s``, with the
speed monotone inside every step (with margins for the navigation and engine errors the plan
does not know: ``velocity_error_m_s``, ``accel_error_m_s2``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from optimizers.common.casadi_tools import casadi, ipopt_options

__all__ = ["TerminalWindow", "WindowPlan"]

#: a stand-in for "no bound" on the window's top in the NLP's parameters (m)
_FREE_TOP_M = 1.0e6


@dataclass(frozen=True)
class WindowPlan:
    """One solved window.

    Attributes
    ----------
    margin_m : float
        The navigated gate's distance inside the band of heights crossed under the limit (m).
    controls : ndarray (steps + 1, 3)
        Elevation α (rad), azimuth β (rad), throttle, one row per decision: the plan's
        ``n_steps``, then throttle 0 (the fall).
    n_steps : int
        Planned steps: ``approach`` (0 or 1), then the window's.
    approach : int
        Steps before the window's first node (node ``approach + 1``, its top).
    """

    margin_m: float
    controls: np.ndarray
    n_steps: int
    approach: int


class TerminalWindow:
    """Receding-horizon window planner for one vehicle (local flat frame at the lander).

    Parameters
    ----------
    thrust_n, exhaust_velocity_m_s : float
        The nominal engine.
    alpha_bounds_rad, beta_bounds_rad : (float, float)
        The env's thrust box (elevation; azimuth, π = braking along-track).
    dt_s : float
        The decision interval (controls are held over it).
    steps : int
        Horizon in decisions (4: 8 s at 2 s, where the widest window stops growing).
    success_speed_m_s : float
        The env's success speed at the gate (``LunarPinpointLanding``: 5 m/s).
    speed_margin_m_s : float
        The window keeps under ``success_speed_m_s`` less this (:attr:`speed_limit`): a margin
        for the navigated velocity's bias (0.1 m/s at 1σ at the gate under ``standard``) and
        the engine's errors over the horizon.
    velocity_error_m_s, accel_error_m_s2 : float
        Margins of the speed's monotony inside a step (a minimum of the true speed inside a
        step cuts the engine off): the planned v·a, at the start of a speeding-up step and at
        the end of a slowing one, exceeds ``velocity_error_m_s`` |a| + ``accel_error_m_s2``
        |v| either way. The defaults: 3σ of the navigated velocity's error at the gate under
        ``standard`` (0.1 m/s an axis), and ~2σ of the thrust estimate's error on ~2.5 m/s²
        (measured: with a margin on the rate alone, a 0.2 m/s velocity error at 1 m/s made a
        minimum 9 m up and the lander fell).
    """

    def __init__(self, thrust_n: float, exhaust_velocity_m_s: float,
                 alpha_bounds_rad: tuple[float, float], beta_bounds_rad: tuple[float, float],
                 dt_s: float, steps: int = 4, success_speed_m_s: float = 5.0,
                 speed_margin_m_s: float = 0.25, velocity_error_m_s: float = 0.3,
                 accel_error_m_s2: float = 0.1) -> None:
        if not (isinstance(steps, int) and 1 <= steps <= 10):
            raise ValueError(f"steps = {steps!r} must be an integer in [1, 10]")
        for name, value in (("dt_s", dt_s), ("success_speed_m_s", success_speed_m_s)):
            if not (math.isfinite(float(value)) and float(value) > 0.0):
                raise ValueError(f"{name} = {value!r} must be a finite number > 0")
        if not 0.0 <= float(speed_margin_m_s) < float(success_speed_m_s):
            raise ValueError(f"speed_margin_m_s = {speed_margin_m_s!r} must be in [0, "
                             f"success_speed_m_s = {success_speed_m_s!r})")
        for name, value in (("velocity_error_m_s", velocity_error_m_s),
                            ("accel_error_m_s2", accel_error_m_s2)):
            if not (math.isfinite(float(value)) and float(value) >= 0.0):
                raise ValueError(f"{name} = {value!r} must be a finite number >= 0")
        self.thrust_n = float(thrust_n)
        self.exhaust_velocity_m_s = float(exhaust_velocity_m_s)
        self.alpha_bounds = tuple(map(float, alpha_bounds_rad))
        self.beta_bounds = tuple(map(float, beta_bounds_rad))
        self.dt_s = float(dt_s)
        self.steps = steps
        self.success_speed = float(success_speed_m_s)
        self.speed_limit = self.success_speed - float(speed_margin_m_s)
        self.velocity_error = float(velocity_error_m_s)
        self.accel_error = float(accel_error_m_s2)
        self.n_solves = 0
        # one NLP per structure: ``approach`` steps (0 or 1) that only slow the lander down
        # (node 1 may be over the limit), then a window of n steps (after them the lander
        # falls) whose first j slow down and the rest speed up (the widest switch at 1 or 2)
        self._solvers = [self._build(approach, n, j) for approach in (0, 1)
                         for n in range(1, steps + 1) for j in range(min(n, 2) + 1)]

    def _build(self, approach: int, n_window: int, j: int):
        ca = casadi()
        dt = self.dt_s
        n = approach + n_window
        # parameters: velocity (3, along, cross, up), height above the navigated gate (m),
        # mass (kg), known acceleration (3), thrust-acceleration scale, the window's top if
        # already flown (or _FREE_TOP_M), and 1 if the top is the window's first node (else 0)
        p = ca.SX.sym("p", 11)
        v, h, m, g = p[0:3], p[3], p[4], p[5:8]
        scale, top_fixed, top_free = p[8], p[9], p[10]
        x = ca.SX.sym("x", 3 * n + 1)  # (α, β, throttle) per step, then the margin δ
        delta = x[3 * n]
        g_list, lbg, ubg = [], [], []
        z = h
        heights = []
        for k in range(n):
            al, be, th = x[3 * k], x[3 * k + 1], x[3 * k + 2]
            d = ca.vertcat(ca.cos(al) * ca.cos(be), ca.cos(al) * ca.sin(be), ca.sin(al))
            a = th * self.thrust_n * scale / m * d + g
            v_next = v + a * dt
            # monotone speed inside the step (it is convex in time at constant acceleration):
            # ±v·a (v at the end of a slowing step, at the start of a speeding-up one) kept
            # over the navigated velocity's error along a and the acceleration's along v
            norm_a = ca.sqrt(ca.dot(a, a) + 1e-8)
            v_judged = v_next if k < approach + j else v
            sign = 1.0 if k < approach + j else -1.0
            g_list.append(sign * ca.dot(v_judged, a) + self.velocity_error * norm_a
                          + self.accel_error * ca.sqrt(ca.dot(v_judged, v_judged) + 1e-8))
            lbg.append(-ca.inf)
            ubg.append(0.0)
            z = z + v[2] * dt + 0.5 * a[2] * dt * dt
            m = m - th * self.thrust_n * scale / self.exhaust_velocity_m_s * dt
            v = v_next
            heights.append(z)
            if k >= approach:  # the window's nodes: under the limit, descending
                g_list += [ca.dot(v, v), v[2]]
                lbg += [-ca.inf, -ca.inf]
                ubg += [self.speed_limit ** 2, 0.0]
        # δ <= the window's top above the gate, δ <= its bottom below it: the last node, then
        # the fall from it (throttle 0 or cut off: the same free fall, descending, so the speed
        # grows by energy) down to the speed limit
        bottom = -heights[-1] + (self.speed_limit ** 2 - ca.dot(v, v)) / (2.0 * (-g[2]))
        g_list += [delta - heights[approach] - (1 - top_free) * _FREE_TOP_M,
                   delta - top_fixed, delta - bottom]
        lbg += [-ca.inf] * 3
        ubg += [0.0] * 3
        nlp = {"x": x, "p": p, "f": -delta, "g": ca.vertcat(*g_list)}
        # infeasible structures end at max_iter: keep it short (feasible ones take ~30)
        solver = ca.nlpsol(f"terminal_window_{approach}_{n_window}_{j}", "ipopt", nlp,
                           ipopt_options(tol=1e-7, max_iter=60))
        lbx = [self.alpha_bounds[0], self.beta_bounds[0], 0.0] * n + [-_FREE_TOP_M]
        ubx = [self.alpha_bounds[1], self.beta_bounds[1], 1.0] * n + [_FREE_TOP_M]
        return (approach, n, solver, np.asarray(lbx), np.asarray(ubx), np.asarray(lbg),
                np.asarray(ubg))

    def _guesses(self, previous: np.ndarray | None) -> list[np.ndarray]:
        """Starts: the previous plan shifted by a step, and the weave of the widest window."""
        n = self.steps
        a_hi, (b_lo, b_hi) = self.alpha_bounds[1], self.beta_bounds
        weave = np.array([[a_hi, b_hi if k % 2 == 0 else b_lo, 0.35] for k in range(n + 1)])
        out = []
        if previous is not None:
            shifted = np.vstack([previous[1:], previous[-1:]])
            out.append(shifted)
        out.append(weave)
        return out

    def plan(self, velocity_m_s: np.ndarray, height_m: float, mass_kg: float,
             accel_m_s2: np.ndarray, thrust_scale: float = 1.0, top_m: float | None = None,
             previous: np.ndarray | None = None) -> WindowPlan | None:
        """The window from one navigated state (local frame: along, cross, up), or None when no
        start converges to a feasible plan.

        ``height_m``: above the navigated gate; ``accel_m_s2``: the known non-thrust
        acceleration (gravity, frame terms); ``top_m``: the window's top if the lander is
        already inside it (under the speed limit), else None (the top is the next node);
        ``previous``: the last plan's controls, a warm start.
        """
        p = np.r_[np.asarray(velocity_m_s, float), float(height_m), float(mass_kg),
                  np.asarray(accel_m_s2, float), float(thrust_scale),
                  _FREE_TOP_M if top_m is None else float(top_m),
                  1.0 if top_m is None else 0.0]
        if not np.all(np.isfinite(p)):
            raise ValueError(f"terminal window parameters {p!r} must be finite")
        best: WindowPlan | None = None
        for guess in self._guesses(previous):
            for approach, n, solver, lbx, ubx, lbg, ubg in self._solvers:
                if approach and top_m is not None:
                    continue  # inside the window: every node is in it
                x0 = np.r_[np.clip(guess[:n].ravel(), lbx[:-1], ubx[:-1]), 0.0]
                self.n_solves += 1
                sol = solver(x0=x0, p=p, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
                if not solver.stats()["success"]:
                    continue
                x = np.asarray(sol["x"]).ravel()
                if best is None or x[-1] > best.margin_m:
                    # then the fall: throttle 0 (the attitude is held)
                    u = np.vstack([x[:-1].reshape(n, 3), np.zeros((self.steps + 1 - n, 3))])
                    u[n:, :2] = u[n - 1, :2]
                    best = WindowPlan(float(x[-1]), u, n, approach)
            if best is not None and previous is not None:
                break  # the warm start converged: the other starts rarely do better
        return best
