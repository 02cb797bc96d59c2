"""Pontryagin multi-arc shooting of the touchdown optimum: the indirect method that certifies the
collocation of :mod:`optimizers.transcription.phased_gpm`.

The problem is :class:`~optimizers.problems.touchdown.TouchdownOCP` (minimum propellant to
touchdown, throttle in [Γ_min, 1], free final time). Necessary conditions, H = λ·f (λ0 = 1,
Mayer cost −m(tf)):

- costate λ' = −∂H/∂x, by CasADi's derivative of the *shared* right-hand side
  (:func:`lunar_env.dynamics.moon3d_eom_terms`, through ``TouchdownOCP.rhs_engine``) with the
  control held, then the optimal control substituted;
- direction: ê = −λ_v/|λ_v| (the minimiser of λ_v·ê on the sphere; the elevation bound must be
  inactive, checked along the extremal), given to the model by its orbital-frame components;
- throttle: the minimiser of Γ·S with the switching function S = −|λ_v|/m − λ_m/c: Γ = 1 where
  S < 0, Γ_min where S > 0. On a fixed arc structure the throttle is the arc's level, each
  switch between arcs is a zero of S, and the certification checks the sign of S on every arc
  (at every integration node): a structure that misses an arc, or has one too many, fails;
- transversality: λ_m(tf) = −1 (the mass is free), H(tf) = 0 (free final time; H is constant
  along the extremal, the dynamics being autonomous); λ_r(tf), λ_v(tf) free (position and
  velocity fixed at touchdown).

Solved backwards from touchdown (the terminal state is known up to the mass): unknowns
λ_r(tf), λ_v(tf), m(tf) and the arc durations; residuals x(0) − x0 (7), H(tf) and S at each
switch. Each arc is integrated by RK4 with a fixed number of uniform steps (:data:`ARC_STEPS`,
its length the arc's duration over them: the switch times are unknowns, so every step stays
inside one arc and RK4 keeps its order); Levenberg–Marquardt (scipy) with CasADi's exact
Jacobian. The guess is the collocation's: its durations, final mass and the costate at
touchdown from its terminal multipliers.

The certified solution is replayed forwards by DOP853 (:func:`replay`): state and costate from
the start with λ(0) from the shooting, the throttle of each arc held over its duration, the
direction from the costate; the replay must land on the target within the problem's
tolerances.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import least_squares

from ..common.casadi_tools import casadi as _casadi
from ..common.result import OptimResult

__all__ = ["TouchdownShooting", "TouchdownExtremal", "replay", "ARC_STEPS"]

#: RK4 steps per arc: (every arc but the last, the last). With [001]'s start's arcs (7.4 s,
#: 23.6 s, 531.9 s) the steps are 0.15 s, 0.47 s and 0.66 s long; the DOP853 replay of the
#: extremal lands within 1e-7 m of the target, and doubling the steps changes the propellant
#: by 7e-14 of it (measured).
ARC_STEPS = (50, 800)


@dataclass
class TouchdownExtremal(OptimResult):
    """:class:`~optimizers.common.result.OptimResult` of :class:`TouchdownShooting`.

    ``fuel_kg`` = m0 − m(tf) of the extremal; ``terminal_errors`` the shooting's mismatch at
    the start (``initial_position_m``, ``initial_velocity_m_s``, ``initial_mass_kg``) and the
    residuals of H(tf) and the switching conditions; ``success``: converged, mismatch within
    1 mm, 1e-6 m/s and 1 mg, and the conditions of the minimum principle hold along it (the
    switching function's sign on each arc, the elevation bound inactive).

    Attributes
    ----------
    levels : tuple of float
    durations_nd : ndarray, shape (n_arcs,)
    costate_0 : ndarray, shape (7,)
        λ at the start (the backward integration's end): with x0 it is the extremal.
    costate_tf : ndarray, shape (7,)
    switching_ok : bool
        S < 0 on every full-thrust arc and S > 0 on every minimum-throttle arc, at every node.
    min_alpha_rad : float
        Lowest thrust elevation along the extremal.
    engine : (float, float)
        The engine solved for: thrust and exhaust velocity (normalised).
    """

    levels: tuple = ()
    durations_nd: np.ndarray = field(default_factory=lambda: np.zeros(0))
    costate_0: np.ndarray = field(default_factory=lambda: np.zeros(7))
    costate_tf: np.ndarray = field(default_factory=lambda: np.zeros(7))
    switching_ok: bool = False
    min_alpha_rad: float = math.nan
    engine: tuple = ()


class TouchdownShooting:
    """Backward multi-arc Pontryagin shooting (see the module docstring).

    Parameters
    ----------
    arc_steps : (int, int)
        RK4 steps of every arc but the last, and of the last. Default :data:`ARC_STEPS`.
    max_nfev : int
        Levenberg–Marquardt evaluations. Default 60.
    """

    def __init__(self, arc_steps: tuple[int, int] = ARC_STEPS, max_nfev: int = 60) -> None:
        if len(arc_steps) != 2 or any(int(n) < 1 for n in arc_steps):
            raise ValueError(f"arc_steps = {arc_steps!r} must be two integers >= 1")
        self.arc_steps = (int(arc_steps[0]), int(arc_steps[1]))
        self.max_nfev = int(max_nfev)
        self._cache: dict = {}

    def __repr__(self) -> str:
        return f"TouchdownShooting(arc_steps={self.arc_steps})"

    def steps(self, n_arcs: int) -> tuple[int, ...]:
        return (self.arc_steps[0],) * (n_arcs - 1) + (self.arc_steps[1],)

    def _canonical(self, ocp) -> dict:
        """State–costate functions of the problem (built once per problem geometry)."""
        key = ("canon", ocp.params.spin_rate_nd, ocp.params.plane_normal)
        if key in self._cache:
            return self._cache[key]
        ca = _casadi()
        x = ca.SX.sym("x", 7)
        lam = ca.SX.sym("lam", 7)
        u = ca.SX.sym("u", 4)
        T = ca.SX.sym("T")
        c = ca.SX.sym("c")
        f = ocp.rhs_engine(x, u, T, c)
        H = ca.dot(lam, f)
        dlam = -ca.jacobian(H, x).T
        p = ca.vertcat(*ocp.orbital_components(x, lam[3:6]))
        e = -p / ca.norm_2(p)
        gam = u[3]
        ustar = ca.vertcat(e, gam)
        sub = ca.Function("canon", [x, lam, gam, T, c],
                          [ca.substitute(ca.vertcat(f, dlam), u, ustar)])
        ham = ca.Function("ham", [x, lam, gam, T, c], [ca.substitute(H, u, ustar)])
        sw = ca.Function("switch", [x, lam, c], [-ca.norm_2(lam[3:6]) / x[6] - lam[6] / c])
        elev = ca.Function("elevation", [x, lam], [e[0]])
        # one classical RK4 step of the canonical system at a held throttle level
        y = ca.SX.sym("y", 14)
        h = ca.SX.sym("h")
        g = ca.SX.sym("g")

        def F(yy):
            return sub(yy[:7], yy[7:], g, T, c)

        k1 = F(y)
        k2 = F(y + h / 2 * k1)
        k3 = F(y + h / 2 * k2)
        k4 = F(y + h * k3)
        step_fn = ca.Function("step", [y, h, g, T, c], [y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)])
        out = dict(canon=sub, ham=ham, switch=sw, elevation=elev, step=step_fn)
        self._cache[key] = out
        return out

    def _shooting(self, ocp, levels: tuple) -> dict:
        key = ("shoot", levels, ocp.params.spin_rate_nd, ocp.params.plane_normal,
               tuple(ocp.target_position_nd), tuple(ocp.target_uvw_nd))
        if key in self._cache:
            return self._cache[key]
        ca = _casadi()
        k = self._canonical(ocp)
        n = len(levels)
        steps = self.steps(n)
        z = ca.MX.sym("z", 7 + n)        # λ_r(tf), λ_v(tf), m(tf), durations
        par = ca.MX.sym("p", 9)          # x0, thrust, exhaust velocity
        T, c = par[7], par[8]
        vf = self._target_velocity(ocp)
        xf = ca.vertcat(ca.DM(ocp.target_position_nd), ca.DM(vf), z[6])
        lf = ca.vertcat(z[:6], -1.0)
        res = [k["ham"](xf, lf, levels[-1], T, c)]
        yk = ca.vertcat(xf, lf)
        paths = []
        for arc in range(n - 1, -1, -1):
            acc = k["step"].mapaccum(f"arc{arc}", steps[arc])
            hs = ca.repmat(-z[7 + arc] / steps[arc], 1, steps[arc])
            traj = acc(yk, hs, levels[arc], T, c)
            paths.append(traj)
            yk = traj[:, -1]
            if arc > 0:
                res.append(k["switch"](yk[:7], yk[7:], c))
        res.append(yk[:7] - par[:7])
        r = ca.vertcat(*res)
        out = dict(G=ca.Function("G", [z, par], [r]),
                   J=ca.Function("J", [z, par], [ca.jacobian(r, z)]),
                   path=ca.Function("path", [z, par], [ca.horzcat(*paths)]),
                   start=ca.Function("start", [z, par], [yk]), steps=steps)
        self._cache[key] = out
        return out

    @staticmethod
    def _target_velocity(ocp) -> np.ndarray:
        """The target's Moon-fixed velocity (orbital-frame (u, v, w) rotated back)."""
        n = ocp.params.plane_normal
        from lunar_env import dynamics as dyn

        f = np.array(dyn.orbital_frame(*ocp.target_position_nd, *n)).reshape(3, 3)
        return f.T @ np.asarray(ocp.target_uvw_nd, float)

    def solve(self, ocp, structure, *, guess_durations_nd, guess_final_mass_nd: float,
              guess_costate_tf, initial_state=None, thrust_nd: float | None = None,
              exhaust_velocity_nd: float | None = None) -> TouchdownExtremal:
        """The extremal with the arc ``structure`` from a guess (the collocation's).

        Parameters
        ----------
        ocp : TouchdownOCP
        structure : tuple of throttle levels (``None`` = the minimum throttle)
        guess_durations_nd : array_like, shape (n_arcs,)
        guess_final_mass_nd : float
        guess_costate_tf : array_like, shape (7,) or (6,)
            λ_r(tf), λ_v(tf) (a seventh entry, λ_m, is ignored: it is −1).
        initial_state : ndarray, shape (7,), optional
        thrust_nd, exhaust_velocity_nd : float, optional
            The engine (default the nominal one).

        Returns
        -------
        TouchdownExtremal
            ``success`` False (never an exception) when the shooting does not converge or the
            extremal breaks a condition of the minimum principle.
        """
        t_start = time.perf_counter()
        levels = ocp.levels(structure)
        sh = self._shooting(ocp, levels)
        k = self._canonical(ocp)
        x0 = np.asarray(ocp.initial_state if initial_state is None else initial_state, float)
        T = ocp.params.thrust_nd if thrust_nd is None else float(thrust_nd)
        c = ocp.params.exhaust_velocity_nd if exhaust_velocity_nd is None \
            else float(exhaust_velocity_nd)
        par = np.concatenate([x0, [T, c]])
        lam = np.asarray(guess_costate_tf, float)[:6]
        z0 = np.concatenate([lam, [float(guess_final_mass_nd)],
                             np.asarray(guess_durations_nd, float)])
        if z0.shape != (7 + len(levels),) or not np.all(np.isfinite(z0)):
            raise ValueError(f"the guess must be finite: 6 costates, a mass and {len(levels)} "
                             "durations")
        G, J = sh["G"], sh["J"]
        n_eval = [0]

        def fun(q):
            n_eval[0] += 1
            return np.asarray(G(q, par)).ravel()

        def jac(q):
            return np.asarray(J(q, par))

        try:
            sol = least_squares(fun, z0, jac=jac, method="lm", xtol=1e-15, ftol=1e-15,
                                gtol=1e-15, max_nfev=self.max_nfev)
            z, msg = sol.x, str(sol.message)
        except (ValueError, FloatingPointError) as exc:  # a diverging iterate: a value
            z, msg = z0, f"shooting failed: {exc}"
        res = fun(z)
        s = ocp.scaling
        finite = bool(np.all(np.isfinite(res)))
        n = len(levels)
        mism = res[-7:] if finite else np.full(7, np.inf)
        pos_m = float(np.linalg.norm(mism[:3]) * s.length_m)
        vel_m_s = float(np.linalg.norm(mism[3:6]) * s.velocity_m_s)
        mass_kg = float(abs(mism[6]) * s.mass_kg)
        cond = np.abs(res[:n]) if finite else np.full(n, np.inf)
        durs = z[7:]
        switching_ok, min_alpha = False, math.nan
        if finite and np.all(durs > 0):
            Y = np.asarray(sh["path"](z, par))      # arcs from the last backwards
            switching_ok, min_alpha = self._check(Y, levels, sh["steps"], k, c,
                                                  ocp.throttle_min)
        y0 = np.asarray(sh["start"](z, par)).ravel() if finite else np.full(14, np.nan)
        converged = finite and pos_m < 1e-3 and vel_m_s < 1e-6 and mass_kg < 1e-6 \
            and bool(np.all(cond < 1e-9)) and bool(np.all(durs > 0))
        alpha_ok = not (min_alpha < math.asin(ocp.sin_alpha_min) - 1e-9)
        ok = converged and switching_ok and alpha_ok
        why = "converged" if converged else "did not converge"
        if converged and not switching_ok:
            why = "converged, but the switching function changes sign inside an arc"
        if converged and not alpha_ok:
            why = "converged, but the thrust elevation leaves its bound"
        fuel = float((x0[6] - z[6]) * s.mass_kg)
        return TouchdownExtremal(
            x=z.copy(), fuel_kg=fuel, tf_s=float(durs.sum() * s.time_s),
            terminal_errors={"initial_position_m": pos_m, "initial_velocity_m_s": vel_m_s,
                             "initial_mass_kg": mass_kg,
                             "hamiltonian_residual": float(cond[0]),
                             "switching_residual": float(cond[1:].max(initial=0.0))},
            history=np.array([fuel]), n_fevals=n_eval[0], n_iter=n_eval[0],
            wall_s=time.perf_counter() - t_start, success=bool(ok),
            message=f"{why} ({msg})", fun=-float(z[6]), feasible=bool(ok),
            algorithm=repr(self), problem=type(ocp).__name__, levels=levels,
            durations_nd=durs.copy(), costate_0=y0[7:].copy(), costate_tf=np.concatenate(
                [z[:6], [-1.0]]), switching_ok=bool(switching_ok),
            min_alpha_rad=float(min_alpha), engine=(T, c))

    @staticmethod
    def _check(Y: np.ndarray, levels: tuple, steps: tuple, k: dict, c: float,
               throttle_min: float) -> tuple[bool, float]:
        """Sign of S on each arc (its nodes but the switch points) and the lowest elevation."""
        ok = True
        lo = math.inf
        col = 0
        for arc in range(len(levels) - 1, -1, -1):
            seg = Y[:, col:col + steps[arc]]
            col += steps[arc]
            # the last node of an arc after the first is the switch (S = 0 there)
            inner = seg[:, :-1] if arc > 0 else seg
            S = np.asarray(k["switch"].map(inner.shape[1])(inner[:7], inner[7:], c)).ravel()
            full = levels[arc] >= 1.0
            if full and not np.all(S < 0.0):
                ok = False
            if not full and levels[arc] <= throttle_min and not np.all(S > 0.0):
                ok = False
            el = np.asarray(k["elevation"].map(seg.shape[1])(seg[:7], seg[7:])).ravel()
            lo = min(lo, float(np.arcsin(np.clip(el, -1.0, 1.0)).min()))
        return ok, lo


def replay(ocp, extremal: TouchdownExtremal, shooting: TouchdownShooting, *,
           initial_state=None, rtol: float = 1e-12, atol: float = 1e-14) -> dict:
    """Forward DOP853 replay of an extremal (state and costate from x0, λ(0); the arcs' throttle
    held over their durations; the direction from the costate).

    Returns
    -------
    dict
        ``terminal_errors`` (the problem's, SI), ``fuel_kg`` (from the replayed final mass),
        ``final_state`` (7,), ``success`` (the problem's verdict on the replay: terminal
        tolerances, above the surface before touchdown, within the propellant budget).
    """
    k = shooting._canonical(ocp)
    x0 = np.asarray(ocp.initial_state if initial_state is None else initial_state, float)
    T, c = extremal.engine
    y = np.concatenate([x0, extremal.costate_0])
    canon = k["canon"]
    states = [x0[None]]
    for gam, d in zip(extremal.levels, extremal.durations_nd, strict=True):
        sol = solve_ivp(lambda t, yy, g=gam: np.asarray(canon(yy[:7], yy[7:], g, T, c)).ravel(),
                        (0.0, float(d)), y, method="DOP853", rtol=rtol, atol=atol)
        y = sol.y[:, -1]
        states.append(sol.y[:7, 1:].T)
    traj = np.vstack(states)
    errors = ocp.terminal_errors(y[:7])
    ok, why = ocp.success_from(errors, ocp.path_quantities(traj))
    return {"terminal_errors": errors, "fuel_kg": float((x0[6] - y[6]) * ocp.scaling.mass_kg),
            "final_state": y[:7].copy(), "success": bool(ok), "message": why}
