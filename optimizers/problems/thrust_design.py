"""Minimum-fuel landing with the thrust magnitude as a design variable ([003] Wang et al. 2003).

[000]'s planar two-body model (:mod:`lunar_env.dynamics`, one shared copy) with the engine at a
constant thrust T for the whole of [0, tf]; T itself is optimised, ``T ∈ [0, 4] kN``, beside the
final time and a cubic thrust angle ψ(t) = a0 + a1·t + a2·t² + a3·t³ ([003] eq. 10). The
propellant is ``T·tf/(Isp·g0)`` ([003] eq. 9) until the dry mass is reached.

How the paper's 14 variables and 6 boundary equalities enter (decision)
-----------------------------------------------------------------------
[003] lists 14 variables — the 4 states (r, θ, v_r, v_θ) at t0 and at tf, tf, T and a0..a3 —
and 6 boundary equalities (eq. 7: r, v_r, v_θ at t0 and at tf). Integrating the dynamics from
t0 ties the 8 boundary states to the other 6 variables, so only 6 are free; we use the standard
single-shooting reading of the paper:

- the **state at t0** is the given initial state: the integration starts there, so the 3
  initial equalities (and θ0 = 0) hold by construction instead of being searched for;
- the **state at tf** is the integrated state (an output): the 3 terminal equalities
  r(tf) = r_L, v_r(tf) = 0, v_θ(tf) = 0 are the problem's equality constraints; θ(tf) is free
  (the downrange angle);
- the 2 thrust inequalities ``T_min ≤ T ≤ T_max`` are box bounds.

:meth:`ThrustDesignProblem.paper_variables` returns the paper's full 14-vector of a decision
vector and :meth:`ThrustDesignProblem.boundary_residuals` its 6 boundary equalities, so a
result reads in the paper's terms.

Decision vector (``dim = 6``)
-----------------------------

=====  ===========================  ====  ==============================================
index  meaning                      unit  bounds
=====  ===========================  ====  ==============================================
0      final time tf                s     scenario ``tf_bounds_s`` (wang2003: 100–800)
1      thrust magnitude T           kN    [0, 4] ([003] eq. 8, "0–4 kN")
2–5    ψ at τ = t/tf = 0, ⅓, ⅔, 1   deg   [−90, 90]
=====  ===========================  ====  ==============================================

The cubic is coded by its values at four equally spaced times (the interpolating cubic,
:class:`~optimizers.parameterisations.NodePolynomial` (4, 3)): the same family as a0..a3 (a
linear bijection, :meth:`ThrustDesignProblem.decode` reports a0..a3 in rad and seconds), but
every variable is a thrust angle with a physical range, which the paper leaves unstated for
a0..a3. The range [−90°, 90°] is every direction whose horizontal component brakes
(cos ψ ≥ 0) — downward thrust is allowed ([003]: the radial component points down for the
first quarter of the flight).

Thrust. The scenario's vehicle thrust is the upper bound T_max (4 kN for ``wang2003``); T is
flown as the throttle T/T_max of the shared dynamics (mass flow scales with it).

Fitness ``[fuel_kg, ceq_vr, ceq_vt, ceq_r]`` (pygmo order, the objective minimised): the
propellant used (kg, from the integrated mass), the radial and tangential velocity errors
(m/s) and the radius error (m) at tf. Integration: one call of the compiled batched RK4 for the
whole population (``n_steps`` equal steps of tf/n_steps, default 100: ≈2.2 s steps at the
optimum; the RK4 error there is checked against DOP853 in the tests). A candidate whose path
dives to half the lunar radius (the model is singular at r = 0) is stopped there: its end
state is that point, finite and heavily penalised.

Penalty units. The GAs maximise ``−fuel − w·(5·|ΔV| + |Δr|)`` in kg, m/s and m
(:meth:`penalty_groups`, [000] eq. (11)'s grouping and factor 5). With w ≥ 1 this is an *exact*
penalty: the Lagrange multipliers of the terminal constraints at the optimum are 0.040 kg per
m/s of v_r, 0.092 kg per m/s of v_θ and 3.2e-4 kg per m of r (measured by re-solving the
Pontryagin problem at T = 2.989 kN with each target moved), far below 5 kg per m/s and 1 kg
per m, so the penalised maximum is the constrained minimum. (In [000]'s normalised units the
radius multiplier is 1.13 against a weight of 1: a normalised penalty would pay to land high.)
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from lunar_env import get_scenario
from lunar_env.integrators import (
    PLANAR,
    RadiusCrossing,
    integrate,
    integrate_prepared,
    params_rows,
)
from lunar_env.scenarios import PlanarScenario

from ..common.problem import PenaltyGroup, Problem, central_difference_jacobian
from ..common.result import ControlLaw, Trajectory
from ..parameterisations import NodePolynomial

__all__ = ["ThrustDesignProblem", "scenario_at_thrust"]


def scenario_at_thrust(scenario: PlanarScenario | str, thrust_n: float,
                       tf_bounds_s: tuple[float, float] | None = None) -> PlanarScenario:
    """The same scenario with the vehicle's (constant) thrust set to ``thrust_n``.

    The fixed-thrust problem of [003] at one T, for the certifiers (Pontryagin, collocation),
    which fly the vehicle at full thrust. ``tf_bounds_s`` optionally widens the final-time
    bounds (a low thrust needs a longer burn than the GA's bounds allow).

    Raises
    ------
    ValueError
        ``thrust_n`` not a finite number > 0.
    """
    sc = get_scenario(scenario) if isinstance(scenario, str) else scenario
    if not (np.isfinite(thrust_n) and thrust_n > 0):
        raise ValueError(f"thrust_n = {thrust_n!r} must be a finite number > 0")
    veh = dataclasses.replace(sc.vehicle, thrust_n=float(thrust_n))
    kw = {} if tf_bounds_s is None else {"tf_bounds_s": tuple(map(float, tf_bounds_s))}
    return dataclasses.replace(sc, vehicle=veh, name=f"{sc.name}@{thrust_n / 1e3:.4g}kN", **kw)


class ThrustDesignProblem(Problem):
    """Minimum fuel over (tf, T, cubic ψ) for a constant-thrust landing ([003] Wang et al. 2003).

    Parameters
    ----------
    scenario : str or PlanarScenario
        Default ``"wang2003"``. Its vehicle thrust is T_max; its ``tf_bounds_s`` bound tf.
    thrust_bounds_kn : (float, float)
        Bounds of T in kN (default ``(0, T_max)``, [003]: 0–4 kN). Must lie in [0, T_max].
    angle_bounds_deg : (float, float)
        Bounds of the four node angles (default (−90, 90)).
    n_steps : int
        RK4 steps over [0, tf] (default 100).
    speed_tol_m_s, radius_tol_m : float
        Success criterion of :meth:`assess` (default [000]'s 0.5 m/s and 1 m; [003] gives none).
    parallel : bool, optional
        Force the threaded or the serial RK4 kernel (default: serial below 32 candidates).

    Raises
    ------
    ValueError
        A non-planar scenario, reversed or out-of-range bounds, non-positive tolerances.
    """

    n_nodes = 4

    def __init__(self, scenario: str | PlanarScenario = "wang2003",
                 thrust_bounds_kn: tuple[float, float] | None = None,
                 angle_bounds_deg: tuple[float, float] = (-90.0, 90.0), n_steps: int = 100,
                 speed_tol_m_s: float = 0.5, radius_tol_m: float = 1.0,
                 parallel: bool | None = None, penalty_units: str = "si") -> None:
        super().__init__()
        if penalty_units not in ("si", "normalised"):
            raise ValueError(f"penalty_units = {penalty_units!r}; use 'si' or 'normalised'")
        self.penalty_units = penalty_units
        sc = get_scenario(scenario) if isinstance(scenario, str) else scenario
        if getattr(sc, "model", None) != "planar":
            raise ValueError(f"scenario {getattr(sc, 'name', sc)!r} is not planar; "
                             "ThrustDesignProblem needs a PlanarScenario (e.g. 'wang2003')")
        self.scenario = sc
        self.thrust_max_n = float(sc.vehicle.thrust_n)
        tb = (0.0, self.thrust_max_n / 1e3) if thrust_bounds_kn is None else \
            tuple(map(float, thrust_bounds_kn))
        if not (0.0 <= tb[0] <= tb[1] <= self.thrust_max_n / 1e3 + 1e-12):
            raise ValueError(f"thrust_bounds_kn = {thrust_bounds_kn!r} must satisfy "
                             f"0 <= low <= high <= T_max = {self.thrust_max_n / 1e3:g} kN")
        ab = tuple(map(float, angle_bounds_deg))
        if not (np.all(np.isfinite(ab)) and ab[0] <= ab[1]):
            raise ValueError(f"angle_bounds_deg = {angle_bounds_deg!r} must be finite, "
                             "low <= high")
        n_steps = int(n_steps)
        if n_steps < 1:
            raise ValueError(f"n_steps = {n_steps} must be >= 1")
        for name, v in dict(speed_tol_m_s=speed_tol_m_s, radius_tol_m=radius_tol_m).items():
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} = {v!r} must be a finite number > 0")
        self.thrust_bounds_kn = tb
        self.angle_bounds_deg = ab
        self.n_steps = n_steps
        self.speed_tol_m_s = float(speed_tol_m_s)
        self.radius_tol_m = float(radius_tol_m)
        self.parallel = parallel
        self.parameterisation = NodePolynomial(self.n_nodes, 3)
        self._fit_T = np.ascontiguousarray(self.parameterisation._projection.T)
        self._pow = np.arange(4)[None, :]
        self.scaling = sc.scaling()
        self.params = sc.params(self.scaling)  # thrust = T_max; T enters as the throttle
        self.y0_nd = sc.state_nd(scaling=self.scaling)
        self.dry_mass_nd = float(self.scaling.mass_nd(sc.vehicle.dry_mass_kg))
        tfb = sc.tf_bounds_s
        self._lb = np.array([tfb[0], tb[0]] + [ab[0]] * self.n_nodes)
        self._ub = np.array([tfb[1], tb[1]] + [ab[1]] * self.n_nodes)
        t = sc.target
        self._target_nd = np.array([self.scaling.length_nd(t.radius_m),
                                    self.scaling.velocity_nd(t.radial_velocity_m_s),
                                    self.scaling.velocity_nd(t.tangential_velocity_m_s)])
        self._consts: dict = {}
        # A candidate that dives into the Moon is stopped half-way to its centre (the model is
        # singular at r = 0); its end state there is finite and penalised by ~870 km.
        self._r_floor_nd = 0.5 * float(self._target_nd[0])

    # ---- pygmo UDP surface ----------------------------------------------------------------
    def get_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self._lb.copy(), self._ub.copy()

    def get_nec(self) -> int:
        return 3

    def get_name(self) -> str:
        return f"ThrustDesignProblem[{self.scenario.name}]"

    # ---- core -----------------------------------------------------------------------------
    def _control_arrays(self, X: np.ndarray):
        tf_nd = X[:, 0] / self.scaling.time_s
        if not np.all(tf_nd > 0):
            raise ValueError(f"tf must be > 0 s; got {X[:, 0][~(tf_nd > 0)][0]!r}")
        n = X.shape[0]
        # the interpolating cubic through the 4 nodes, in τ = t/tf, then in normalised t
        coefs = np.zeros((n, 1, 2, 4))
        coefs[:, 0, 0, :] = (np.deg2rad(X[:, 2:]) @ self._fit_T) / tf_nd[:, None] ** self._pow
        coefs[:, 0, 1, 0] = X[:, 1] * (1e3 / self.thrust_max_n)
        breaks = np.zeros((n, 2))
        breaks[:, 1] = tf_nd
        return tf_nd, breaks, coefs

    def _end_states(self, X: np.ndarray) -> np.ndarray:
        """Normalised states at tf, (batch, 5): one compiled batched RK4 call."""
        n = X.shape[0]
        tf_nd, breaks, coefs = self._control_arrays(X)
        consts = self._consts.get(n)
        if consts is None:
            import numba

            consts = (np.ascontiguousarray(np.broadcast_to(self.y0_nd, (n, 5))), np.zeros(n),
                      np.full(n, self._r_floor_nd), params_rows(self.params, n),
                      self.parallel if self.parallel is not None else
                      (n >= 32 and numba.config.NUMBA_NUM_THREADS > 1))
            if len(self._consts) > 16:
                self._consts.clear()
            self._consts[n] = consts
        y0, t0, r_stop, p, par = consts
        y_end, _, _, _ = integrate_prepared(PLANAR, y0, t0, tf_nd / self.n_steps, self.n_steps,
                                            breaks, coefs, p, self.dry_mass_nd, r_stop, False,
                                            par)
        return y_end

    def terminal_errors_from_state(self, y_end_nd: np.ndarray) -> dict[str, np.ndarray]:
        """SI terminal errors of normalised end states (batch, 5): ``radial_velocity_m_s``,
        ``tangential_velocity_m_s``, ``speed_m_s`` (their norm), ``radius_m`` (r(tf) − r_L)."""
        y = np.atleast_2d(y_end_nd)
        s, tgt = self.scaling, self._target_nd
        dvr = (y[:, 1] - tgt[1]) * s.velocity_m_s
        dvt = (y[:, 0] * y[:, 3] - tgt[2]) * s.velocity_m_s
        dr = (y[:, 0] - tgt[0]) * s.length_m
        return {"radial_velocity_m_s": dvr, "tangential_velocity_m_s": dvt,
                "speed_m_s": np.hypot(dvr, dvt), "radius_m": dr}

    def _batch_fitness(self, X: np.ndarray) -> np.ndarray:
        y = self._end_states(X)
        if not np.all(np.isfinite(y)):
            bad = X[~np.all(np.isfinite(y), axis=1)][0]
            raise FloatingPointError(f"integration of x = {bad!r} produced a non-finite state")
        err = self.terminal_errors_from_state(y)
        out = np.empty((X.shape[0], 4))
        out[:, 0] = (self.y0_nd[4] - y[:, 4]) * self.scaling.mass_kg
        out[:, 1] = err["radial_velocity_m_s"]
        out[:, 2] = err["tangential_velocity_m_s"]
        out[:, 3] = err["radius_m"]
        return out

    def gradient(self, x: np.ndarray, rel_step: float = 1e-6) -> np.ndarray:
        """Central finite-difference Jacobian of :meth:`fitness`, shape (n_f, dim)."""
        return central_difference_jacobian(self, x, rel_step)

    # ---- the problem's verdict and penalty --------------------------------------------------
    @property
    def objective_scale(self) -> float:
        """Divisor of the fuel in the penalised fitness: 1 (kg) or m0 (``"normalised"``)."""
        return 1.0 if self.penalty_units == "si" else self.scaling.mass_kg

    def penalty_groups(self) -> list[PenaltyGroup]:
        """[000] eq. (11)'s grouping: 5·|ΔV| and |Δr|, in SI (m/s, m; with the fuel in kg, an
        exact penalty for weights ≥ 1, see the module docstring) or in the normalised units of
        [003] eq. (5) (sqrt(μ/r0), r0; with the fuel in m0)."""
        si = self.penalty_units == "si"
        return [PenaltyGroup("velocity", eq=(0, 1), factor=5.0,
                             scale=1.0 if si else self.scaling.velocity_m_s),
                PenaltyGroup("radius", eq=(2,), factor=1.0,
                             scale=1.0 if si else self.scaling.length_m)]

    def terminal_errors(self, x: np.ndarray, f: np.ndarray) -> dict[str, float]:
        dvr, dvt = float(f[1]), float(f[2])
        return {"radial_velocity_m_s": dvr, "tangential_velocity_m_s": dvt,
                "speed_m_s": float(np.hypot(dvr, dvt)), "radius_m": float(f[3])}

    def success_from(self, x, f, errors, feasible) -> tuple[bool, str]:
        ok = errors["speed_m_s"] < self.speed_tol_m_s and abs(errors["radius_m"]) < \
            self.radius_tol_m
        crit = f"|dV| < {self.speed_tol_m_s:g} m/s, |dr| < {self.radius_tol_m:g} m"
        return bool(ok), (f"terminal conditions met ({crit})" if ok else
                          f"terminal conditions NOT met ({crit}): |dV| = "
                          f"{errors['speed_m_s']:.3g} m/s, dr = {errors['radius_m']:.3g} m")

    def fuel_tf(self, x: np.ndarray, f: np.ndarray) -> tuple[float, float]:
        return float(f[0]), float(x[0])

    def _fingerprint_items(self) -> list:
        return super()._fingerprint_items() + [self.scenario, self.y0_nd.tolist(), self.n_steps,
                                               self.penalty_units]

    @functools.cached_property
    def ocp(self):
        """The fixed-thrust continuous problem at T_max (:class:`~.planar_ocp.PlanarOCP`); the
        certified optimum at another T is that of :func:`scenario_at_thrust`."""
        from .planar_ocp import PlanarOCP

        return PlanarOCP(self.scenario)

    def control_law(self, x: np.ndarray) -> ControlLaw:
        """(ψ(t), throttle T/T_max) on SI time, picklable."""
        x = np.asarray(x, dtype=np.float64)[None, :]
        tf_nd = x[:, 0] / self.scaling.time_s
        law = self.parameterisation.control(np.deg2rad(x[:, 2:]), 0.0, tf_nd,
                                            throttle=x[:, 1] * 1e3 / self.thrust_max_n)
        return ControlLaw(law, self.scaling.time_s)

    # ---- the paper's view and decoding ------------------------------------------------------
    def coefficients(self, x: np.ndarray) -> np.ndarray:
        """a0..a3 of ψ(t) = Σ a_i t^i (rad, t in s), shape (4,)."""
        x = np.asarray(x, dtype=np.float64)
        b = self.parameterisation.fit(np.deg2rad(x[None, 2:]))[0]
        return b / x[0] ** np.arange(4)

    def thrust_angle_rad(self, x: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """ψ(t) (rad) of one decision vector at times ``t_s`` (s)."""
        x = np.asarray(x, dtype=np.float64)
        return self.parameterisation.evaluate(np.deg2rad(x[None, 2:]),
                                              np.asarray(t_s, float) / x[0])[0]

    def paper_variables(self, x: np.ndarray) -> dict[str, float]:
        """The paper's 14 variables of ``x``: states (r m, θ rad, v_r m/s, v_θ m/s) at t0 and
        tf (the latter integrated), tf (s), T (N) and a0..a3 (rad, t in s)."""
        x = np.asarray(x, dtype=np.float64)
        s = self.scaling
        y0 = self.y0_nd
        yf = self._end_states(x[None, :])[0]
        out = {}
        for tag, y in (("t0", y0), ("tf", yf)):
            out.update({f"r_{tag}_m": float(y[0] * s.length_m), f"theta_{tag}_rad": float(y[2]),
                        f"v_r_{tag}_m_s": float(y[1] * s.velocity_m_s),
                        f"v_theta_{tag}_m_s": float(y[0] * y[3] * s.velocity_m_s)})
        out["tf_s"] = float(x[0])
        out["thrust_n"] = float(x[1] * 1e3)
        out.update({f"a{i}": float(a) for i, a in enumerate(self.coefficients(x))})
        return out

    def boundary_residuals(self, x: np.ndarray) -> dict[str, float]:
        """The paper's 6 boundary equalities (eq. 7) at ``x``, SI: the 3 at t0 (zero by
        construction) and the 3 at tf (the equality constraints)."""
        v = self.paper_variables(x)
        sc = self.scenario
        return {"r_t0_m": v["r_t0_m"] - sc.initial.radius_m,
                "v_r_t0_m_s": v["v_r_t0_m_s"] - sc.initial.radial_velocity_m_s,
                "v_theta_t0_m_s": v["v_theta_t0_m_s"] - sc.initial.tangential_velocity_m_s,
                "r_tf_m": v["r_tf_m"] - sc.target.radius_m,
                "v_r_tf_m_s": v["v_r_tf_m_s"] - sc.target.radial_velocity_m_s,
                "v_theta_tf_m_s": v["v_theta_tf_m_s"] - sc.target.tangential_velocity_m_s}

    def decode(self, x: np.ndarray, n_steps: int | None = None) -> dict:
        """Physical meaning of one decision vector.

        Returns
        -------
        dict with ``tf_s``, ``thrust_n``, ``coefficients_rad`` (a0..a3, t in s), ``fuel_kg``,
        ``fuel_fraction`` (of m0), ``downrange_deg`` (θ(tf) − θ0), ``terminal_errors`` (SI),
        ``paper_variables`` and ``trajectory`` (:class:`Trajectory` on the RK4 grid: radius,
        radial and tangential velocity, θ, mass, altitude; controls ``phi_rad``, ``throttle``).
        """
        x = np.asarray(x, dtype=np.float64)
        if x.shape != (self.dim,):
            raise ValueError(f"x has shape {x.shape}; expected ({self.dim},)")
        tf_nd = x[0] / self.scaling.time_s
        n = self.n_steps if n_steps is None else int(n_steps)
        prop = integrate(PLANAR, self.y0_nd[None, :], t0_nd=0.0, dt_nd=tf_nd / n, n_steps=n,
                         control=self.control_law(x).law, params=self.params,
                         dry_mass_nd=self.dry_mass_nd,
                         events=(RadiusCrossing(self._r_floor_nd),), record=True)
        s = self.scaling
        k = int(prop.n_records[0])
        st = prop.states[0, :k]
        t_s = prop.times[0, :k] * s.time_s
        burning = np.isnan(prop.t_burnout[0]) | (prop.times[0, :k] < prop.t_burnout[0])
        traj = Trajectory(
            t_s=t_s,
            states={"radius_m": st[:, 0] * s.length_m,
                    "radial_velocity_m_s": st[:, 1] * s.velocity_m_s,
                    "theta_rad": st[:, 2].copy(),
                    "angular_rate_rad_s": st[:, 3] / s.time_s,
                    "tangential_velocity_m_s": st[:, 0] * st[:, 3] * s.velocity_m_s,
                    "mass_kg": st[:, 4] * s.mass_kg,
                    "altitude_m": st[:, 0] * s.length_m - self.scenario.surface_radius_m},
            controls={"phi_rad": self.thrust_angle_rad(x, t_s),
                      "throttle": burning * x[1] * 1e3 / self.thrust_max_n})
        fuel = float((self.y0_nd[4] - prop.y_end[0, 4]) * s.mass_kg)
        return {"tf_s": float(x[0]), "thrust_n": float(x[1] * 1e3),
                "coefficients_rad": self.coefficients(x), "fuel_kg": fuel,
                "fuel_fraction": fuel / self.scenario.vehicle.mass_kg,
                "downrange_deg": float(np.degrees(prop.y_end[0, 2] - self.y0_nd[2])),
                "terminal_errors": {k: float(v[0]) for k, v in
                                    self.terminal_errors_from_state(prop.y_end).items()},
                "paper_variables": self.paper_variables(x), "trajectory": traj}
