"""Planar minimum-fuel powered descent as a pygmo-style problem ([000] Zhu & Xu 2007).

Decision vector (paper 000, §3 and eq. 24–25), ``dim = n_nodes + 1``:

=========  ===========================  ======  ==========================================
index      meaning                      unit    bounds (paper 000)
=========  ===========================  ======  ==========================================
0 … n−1    thrust angle φ_i at node i   deg     [0, 9·(i+1)]   (eq. 24–25, "×9")
n          final time tf                s       [500, 700]     (eq. 24–25; scenario bounds)
=========  ===========================  ======  ==========================================

The node angles sit at ``t_i = i·tf/(n_nodes − 1)`` ([000] eq. 9); a least-squares polynomial
through them (:class:`optimizers.parameterisations.NodePolynomial`, cubic in [000] eq. 10) is the
thrust angle φ(t) over [0, tf]. The engine is on at full thrust for the whole of [0, tf] ([000]:
"F constant"), so the propellant used is ``F·tf/c`` (until the dry mass is reached) and the
terminal state is the state **at tf**, as in the paper's fitness (eq. 11).

Fitness ``[objective, ceq_vr, ceq_vt, ceq_r]`` (pygmo order; the objective is minimised):

- objective: propellant used (kg) (``objective="fuel"``, default) or ``-m(tf)/m0``
  (``objective="final_mass"``, the paper's normalised J of eq. 4/8 with the sign flipped);
- ``ceq_vr = (v(tf) − v_f) / velocity_scale_m_s`` (radial velocity error),
- ``ceq_vt = (ω(tf) r(tf) − ω_f r_f) / velocity_scale_m_s`` (tangential velocity error),
- ``ceq_r = (r(tf) − r_f) / radius_scale_m`` (radius error).

With the default scales of 1 m/s and 1 m the constraint values are SI errors, so a constraint
tolerance of 0.01 means 1 cm/s and 1 cm — the scale at which the paper's results differ.

Integration. The whole population goes through **one** call of
:func:`lunar_env.integrators.integrate` (compiled batched RK4, ``n_steps`` equal steps of
tf/n_steps, no events: the paper evaluates the state at tf). ``n_steps = 100`` (≈6 s steps).
Measured against the DOP853 reference (rtol 1e-12) at the cubic-parameterised optimum
(tf = 604.52 s): RK4 error of the terminal radial velocity 6e-8 m/s, of the radius 7e-5 m
(50 steps: 1e-6 m/s, 1e-3 m; 25 steps: 2e-5 m/s, 0.016 m; fourth-order convergence), and of
the fuel 0 (it depends on tf only). That is four orders below the 0.01 m/s / 0.1 m at which the
paper's runs differ; ``tests/test_landing_problem.py`` checks it.
"""

from __future__ import annotations

import functools

import numba
import numpy as np

from lunar_env import get_scenario
from lunar_env.integrators import PLANAR, integrate, integrate_prepared, params_rows
from lunar_env.scenarios import PlanarScenario

from ..common.problem import PenaltyGroup, Problem, central_difference_jacobian
from ..common.result import ControlLaw, Trajectory
from ..parameterisations import NodePolynomial

__all__ = ["PlanarLandingProblem", "DEFAULT_N_STEPS"]

DEFAULT_N_STEPS = 100
# same threshold as lunar_env.integrators.integrate: threads cost more than they save below it
_PARALLEL_MIN_BATCH = 32

_OBJECTIVES = ("fuel", "final_mass")


class PlanarLandingProblem(Problem):
    """Minimum-fuel soft landing with node-angle parameterisation ([000] Zhu & Xu 2007).

    Parameters
    ----------
    scenario : str or PlanarScenario
        Planar scenario (default ``"zhu2007"``). Its ``tf_bounds_s`` are the tf bounds.
    parameterisation : NodePolynomial, optional
        Node angles + least-squares polynomial; default ``NodePolynomial(10, 3)`` ([000]).
    n_steps : int
        RK4 steps over [0, tf] (default :data:`DEFAULT_N_STEPS`, see the module docstring).
    objective : {"fuel", "final_mass"}
        ``"fuel"``: propellant used (kg); ``"final_mass"``: ``−m(tf)/m0``.
    initial_state_si : array_like, shape (5,), optional
        (r m, v_r m/s, θ rad, v_t m/s, m kg); default the scenario's nominal initial state.
    node_upper_deg : array_like, shape (n_nodes,), optional
        Upper bounds of the node angles (deg). Default ``90·(i+1)/n_nodes``, which is
        [000] eq. 25 (``9·(i+1)``) for 10 nodes. Lower bounds are 0 ([000] eq. 24).
    node_lower_deg : array_like, shape (n_nodes,), optional
    tf_bounds_s : (float, float), optional
        Default: the scenario's (``(500, 700)`` for zhu2007, [000] eq. 24–25).
    velocity_scale_m_s, radius_scale_m : float
        Divisors of the equality constraints (default 1: constraints in m/s and m).
    parallel : bool, optional
        Force the threaded or the serial RK4 kernel in :meth:`batch_fitness` (default: threaded
        for batches of 32 or more, as :func:`lunar_env.integrators.integrate`; on a heavily
        shared machine the serial kernel can be faster).
    speed_tol_m_s, radius_tol_m : float
        The problem's success criterion (:meth:`assess`): a landing *succeeds* when the terminal
        speed error is below ``speed_tol_m_s`` and the radius error below ``radius_tol_m``
        ([000]'s convergence claim: 0.5 m/s and 1 m).
    penalty_units : {"normalised", "si"}
        Units of the penalised fitness of [000] eq. (11) that the GAs maximise
        (:meth:`penalty_groups`): ``"normalised"`` (the paper's §2 units, default:
        m(tf)/m0, velocities / sqrt(μ/r0), radius / r0) or ``"si"`` (kg, m/s, m; the reading
        under which ASAGA's T0 = 10000 has the size of the early penalties).

    Raises
    ------
    ValueError
        On an unknown objective, a non-planar scenario, inconsistent bound shapes or
        non-positive scales / step counts.
    """

    def __init__(self, scenario: str | PlanarScenario = "zhu2007",
                 parameterisation: NodePolynomial | None = None, n_steps: int = DEFAULT_N_STEPS,
                 objective: str = "fuel", initial_state_si=None, node_upper_deg=None,
                 node_lower_deg=None, tf_bounds_s: tuple[float, float] | None = None,
                 velocity_scale_m_s: float = 1.0, radius_scale_m: float = 1.0,
                 parallel: bool | None = None, speed_tol_m_s: float = 0.5,
                 radius_tol_m: float = 1.0, penalty_units: str = "normalised") -> None:
        super().__init__()
        sc = get_scenario(scenario) if isinstance(scenario, str) else scenario
        if getattr(sc, "model", None) != "planar":
            raise ValueError(f"scenario {getattr(sc, 'name', sc)!r} is not planar; "
                             "PlanarLandingProblem needs a PlanarScenario (e.g. 'zhu2007')")
        if objective not in _OBJECTIVES:
            raise ValueError(f"objective = {objective!r}; allowed: {_OBJECTIVES}")
        n_steps = int(n_steps)
        if n_steps < 1:
            raise ValueError(f"n_steps = {n_steps} must be >= 1")
        for name, v in dict(velocity_scale_m_s=velocity_scale_m_s, radius_scale_m=radius_scale_m,
                            speed_tol_m_s=speed_tol_m_s, radius_tol_m=radius_tol_m).items():
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} = {v!r} must be a finite number > 0")
        if penalty_units not in ("normalised", "si"):
            raise ValueError(f"penalty_units = {penalty_units!r}; use 'normalised' or 'si'")
        self.speed_tol_m_s = float(speed_tol_m_s)
        self.radius_tol_m = float(radius_tol_m)
        self.penalty_units = penalty_units
        self.scenario = sc
        self.parameterisation = parameterisation or NodePolynomial(10, 3)
        self.n_steps = n_steps
        self.objective = objective
        self.velocity_scale_m_s = float(velocity_scale_m_s)
        self.radius_scale_m = float(radius_scale_m)
        self.parallel = parallel
        self._consts: dict = {}
        self.scaling = sc.scaling()
        self.params = sc.params(self.scaling)
        if initial_state_si is None:
            self.y0_nd = sc.state_nd(scaling=self.scaling)
        else:
            self.y0_nd = sc.si_to_nd(sc.check_state_si(initial_state_si), self.scaling)
        self.dry_mass_nd = float(self.scaling.mass_nd(sc.vehicle.dry_mass_kg))
        n = self.parameterisation.n_nodes
        lo = np.zeros(n) if node_lower_deg is None else np.asarray(node_lower_deg, float)
        hi = (90.0 * np.arange(1, n + 1) / n if node_upper_deg is None
              else np.asarray(node_upper_deg, float))
        tfb = sc.tf_bounds_s if tf_bounds_s is None else tuple(map(float, tf_bounds_s))
        if lo.shape != (n,) or hi.shape != (n,) or not np.all(lo <= hi):
            raise ValueError(f"node bounds must have shape ({n},) with lower <= upper; got "
                             f"{lo!r}, {hi!r}")
        if not 0.0 < tfb[0] <= tfb[1]:
            raise ValueError(f"tf_bounds_s = {tfb!r} must satisfy 0 < low <= high")
        self._lb = np.concatenate([lo, [tfb[0]]])
        self._ub = np.concatenate([hi, [tfb[1]]])
        t = sc.target
        self.target_radius_nd = float(self.scaling.length_nd(t.radius_m))
        self.target_radial_velocity_nd = float(self.scaling.velocity_nd(t.radial_velocity_m_s))
        self.target_tangential_velocity_nd = float(
            self.scaling.velocity_nd(t.tangential_velocity_m_s))

    # ---- pygmo UDP surface ----------------------------------------------------------------
    def get_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self._lb.copy(), self._ub.copy()

    def get_nec(self) -> int:
        return 3

    def get_name(self) -> str:
        return f"PlanarLandingProblem[{self.scenario.name}]"

    # ---- core -----------------------------------------------------------------------------
    def control(self, X: np.ndarray):
        """Control law (normalised time) for decision vectors ``X`` (batch, dim)."""
        X = np.atleast_2d(np.asarray(X, dtype=np.float64))
        tf_nd = self.scaling.time_nd(X[:, -1])
        return self.parameterisation.control(np.deg2rad(X[:, :-1]), 0.0, tf_nd), tf_nd

    def propagate(self, X: np.ndarray, *, record: bool = False, n_steps: int | None = None):
        """Integrate every candidate to its tf in one batched RK4 call.

        Returns the :class:`lunar_env.integrators.Propagation` (normalised units).
        """
        X = np.atleast_2d(np.asarray(X, dtype=np.float64))
        control, tf_nd = self.control(X)
        n = self.n_steps if n_steps is None else int(n_steps)
        y0 = np.broadcast_to(self.y0_nd, (X.shape[0], 5))
        return integrate(PLANAR, y0, t0_nd=0.0, dt_nd=tf_nd / n, n_steps=n, control=control,
                         params=self.params, dry_mass_nd=self.dry_mass_nd, events=(),
                         record=record)

    def terminal_errors_from_state(self, y_end_nd: np.ndarray) -> dict[str, np.ndarray]:
        """SI terminal errors from normalised end states (batch, 5).

        Keys: ``radial_velocity_m_s``, ``tangential_velocity_m_s``, ``speed_m_s`` (magnitude of
        the velocity error), ``radius_m`` (r(tf) − r_f), each shape (batch,).
        """
        y = np.atleast_2d(y_end_nd)
        s = self.scaling
        dvr = (y[:, 1] - self.target_radial_velocity_nd) * s.velocity_m_s
        dvt = (y[:, 0] * y[:, 3] - self.target_tangential_velocity_nd) * s.velocity_m_s
        dr = (y[:, 0] - self.target_radius_nd) * s.length_m
        return {"radial_velocity_m_s": dvr, "tangential_velocity_m_s": dvt,
                "speed_m_s": np.hypot(dvr, dvt), "radius_m": dr}

    def _end_states(self, X: np.ndarray) -> np.ndarray:
        """Normalised states at tf, (batch, 5): the hot path, one compiled batched RK4 call
        (:func:`lunar_env.integrators.integrate_prepared`, the same kernel as
        :func:`~lunar_env.integrators.integrate` without its per-call validation; the inputs
        are built here, so they are valid by construction)."""
        n = X.shape[0]
        tf_nd = X[:, -1] / self.scaling.time_s
        if not np.all(tf_nd > 0):
            raise ValueError(f"tf must be > 0 s; got {X[:, -1][~(tf_nd > 0)][0]!r}")
        breaks, coefs = self.parameterisation.control_arrays(
            np.deg2rad(X[:, :-1]), 0.0, tf_nd)
        consts = self._consts.get(n)
        if consts is None:
            consts = (np.ascontiguousarray(np.broadcast_to(self.y0_nd, (n, 5))), np.zeros(n),
                      np.full(n, np.nan), params_rows(self.params, n),
                      self.parallel if self.parallel is not None else
                      (n >= _PARALLEL_MIN_BATCH and numba.config.NUMBA_NUM_THREADS > 1))
            if len(self._consts) > 16:
                self._consts.clear()
            self._consts[n] = consts
        y0, t0, r_stop, p, par = consts
        y_end, _, _, _ = integrate_prepared(PLANAR, y0, t0, tf_nd / self.n_steps, self.n_steps,
                                            breaks, coefs, p, self.dry_mass_nd, r_stop, False,
                                            par)
        return y_end

    def _batch_fitness(self, X: np.ndarray) -> np.ndarray:
        y = self._end_states(X)
        if not np.all(np.isfinite(y)):
            bad = X[~np.all(np.isfinite(y), axis=1)][0]
            raise FloatingPointError(f"integration of x = {bad!r} produced a non-finite state; "
                                     "check the bounds and n_steps")
        err = self.terminal_errors_from_state(y)
        out = np.empty((X.shape[0], 4))
        if self.objective == "fuel":
            out[:, 0] = (self.y0_nd[4] - y[:, 4]) * self.scaling.mass_kg
        else:
            out[:, 0] = -y[:, 4]
        out[:, 1] = err["radial_velocity_m_s"] / self.velocity_scale_m_s
        out[:, 2] = err["tangential_velocity_m_s"] / self.velocity_scale_m_s
        out[:, 3] = err["radius_m"] / self.radius_scale_m
        return out

    def gradient(self, x: np.ndarray, rel_step: float = 1e-6) -> np.ndarray:
        """Central finite-difference Jacobian of :meth:`fitness`, one batched call.

        Returns
        -------
        ndarray, shape (n_f, dim)
        """
        return central_difference_jacobian(self, x, rel_step)

    # ---- the problem's verdict and penalty --------------------------------------------------
    @property
    def objective_scale(self) -> float:
        """Objective divisor of the penalised fitness: m0 (kg) for the fuel objective in
        normalised units, so −fuel/m0 is m(tf)/m0 up to a constant ([000] eq. 11)."""
        si = self.penalty_units == "si"
        if self.objective == "fuel":
            return 1.0 if si else self.scaling.mass_kg
        return 1.0 / self.scaling.mass_kg if si else 1.0

    def penalty_groups(self) -> list[PenaltyGroup]:
        """[000] eq. (11): σ1·|ΔV| (σ1 = 5σ2) and σ2·|Δr|, in the units of ``penalty_units``."""
        s = self.scaling
        v_unit = 1.0 if self.penalty_units == "si" else s.velocity_m_s
        r_unit = 1.0 if self.penalty_units == "si" else s.length_m
        return [PenaltyGroup("velocity", eq=(0, 1), factor=5.0,
                             scale=v_unit / self.velocity_scale_m_s),
                PenaltyGroup("radius", eq=(2,), factor=1.0, scale=r_unit / self.radius_scale_m)]

    def terminal_errors(self, x: np.ndarray, f: np.ndarray) -> dict[str, float]:
        """SI terminal errors from a fitness row: radial and tangential velocity, their norm
        ``speed_m_s``, and ``radius_m`` (r(tf) − r_f)."""
        dvr = float(f[1] * self.velocity_scale_m_s)
        dvt = float(f[2] * self.velocity_scale_m_s)
        return {"radial_velocity_m_s": dvr, "tangential_velocity_m_s": dvt,
                "speed_m_s": float(np.hypot(dvr, dvt)),
                "radius_m": float(f[3] * self.radius_scale_m)}

    def success_from(self, x, f, errors, feasible) -> tuple[bool, str]:
        ok = errors["speed_m_s"] < self.speed_tol_m_s and abs(errors["radius_m"]) < \
            self.radius_tol_m
        crit = f"|dV| < {self.speed_tol_m_s:g} m/s, |dr| < {self.radius_tol_m:g} m"
        return bool(ok), (f"terminal conditions met ({crit})" if ok else
                          f"terminal conditions NOT met ({crit}): |dV| = "
                          f"{errors['speed_m_s']:.3g} m/s, dr = {errors['radius_m']:.3g} m")

    def replay_verdict(self, errors: dict[str, float], path: dict[str, float]
                       ) -> tuple[bool, str]:
        """Verdict on a reference replay (:func:`optimizers.certification.certify`): this
        problem's terminal tolerances and the OCP's path conditions."""
        ok, why = self.success_from(None, None, errors, True)
        if ok:
            path_ok, path_why = self.ocp.success_from(
                {k: 0.0 for k in self.ocp.tolerances}, path)
            if not path_ok:
                return False, path_why
        return ok, why

    def fuel_tf(self, x: np.ndarray, f: np.ndarray) -> tuple[float, float]:
        return float(self.fuel_kg_from_fitness(f[None, :])[0]), float(x[-1])

    def _fingerprint_items(self) -> list:
        return super()._fingerprint_items() + [
            self.scenario, self.y0_nd.tolist(), self.n_steps, self.objective,
            repr(self.parameterisation), self.velocity_scale_m_s, self.radius_scale_m,
            self.penalty_units]

    def fuel_kg_from_fitness(self, F: np.ndarray) -> np.ndarray:
        """Propellant (kg) from rows of :meth:`batch_fitness`, shape (batch,)."""
        F = np.atleast_2d(F)
        if self.objective == "fuel":
            return F[:, 0].copy()
        return (self.y0_nd[4] + F[:, 0]) * self.scaling.mass_kg

    @functools.cached_property
    def ocp(self):
        """The continuous problem this parameterisation approximates
        (:class:`~optimizers.problems.planar_ocp.PlanarOCP`, same scenario and initial state):
        its certified optimum is what :func:`optimizers.certification.certify` compares with."""
        from .planar_ocp import PlanarOCP

        return PlanarOCP(self.scenario, self.scenario.nd_to_si(self.y0_nd, self.scaling))

    def control_law(self, x: np.ndarray) -> ControlLaw:
        """(φ(t), throttle 1) of the fitted polynomial on SI time, picklable."""
        return ControlLaw(self.control(np.asarray(x, dtype=np.float64)[None, :])[0],
                          self.scaling.time_s)

    # ---- decoding -------------------------------------------------------------------------
    def thrust_angle_rad(self, x: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Fitted thrust angle φ(t) (rad) of one decision vector at times ``t_s`` (s)."""
        x = np.asarray(x, dtype=np.float64)
        s = np.asarray(t_s, dtype=np.float64) / x[-1]
        return self.parameterisation.evaluate(np.deg2rad(x[None, :-1]), s)[0]

    def decode(self, x: np.ndarray, n_steps: int | None = None) -> dict:
        """Physical meaning of one decision vector.

        Returns
        -------
        dict with
            ``tf_s``; ``node_times_s``, ``node_angles_rad`` (shape (n_nodes,));
            ``coefficients_rad`` (shape (degree+1,), ascending powers of t in s);
            ``control``: the :class:`PiecewisePolynomial` (normalised time);
            ``trajectory``: :class:`Trajectory` in SI on the RK4 grid (``radius_m``,
            ``radial_velocity_m_s``, ``theta_rad``, ``angular_rate_rad_s``,
            ``tangential_velocity_m_s``, ``mass_kg``, ``altitude_m``; control ``phi_rad``,
            ``throttle``); ``fuel_kg``; ``terminal_errors`` (SI floats).
        """
        x = np.asarray(x, dtype=np.float64)
        if x.shape != (self.dim,):
            raise ValueError(f"x has shape {x.shape}; expected ({self.dim},)")
        prop = self.propagate(x[None, :], record=True, n_steps=n_steps)
        s = self.scaling
        n = int(prop.n_records[0])
        st = prop.states[0, :n]
        t_s = prop.times[0, :n] * s.time_s
        phi = self.thrust_angle_rad(x, t_s)
        burning = np.isnan(prop.t_burnout[0]) | (prop.times[0, :n] < prop.t_burnout[0])
        traj = Trajectory(
            t_s=t_s,
            states={
                "radius_m": st[:, 0] * s.length_m,
                "radial_velocity_m_s": st[:, 1] * s.velocity_m_s,
                "theta_rad": st[:, 2].copy(),
                "angular_rate_rad_s": st[:, 3] / s.time_s,
                "tangential_velocity_m_s": st[:, 0] * st[:, 3] * s.velocity_m_s,
                "mass_kg": st[:, 4] * s.mass_kg,
                "altitude_m": st[:, 0] * s.length_m - self.scenario.surface_radius_m,
            },
            controls={"phi_rad": phi, "throttle": burning.astype(float)},
        )
        err = {k: float(v[0]) for k, v in self.terminal_errors_from_state(prop.y_end).items()}
        tf_s = float(x[-1])
        a = self.parameterisation.fit(np.deg2rad(x[None, :-1]))[0]
        return {
            "tf_s": tf_s,
            "node_times_s": self.parameterisation.node_times(0.0, tf_s)[0],
            "node_angles_rad": np.deg2rad(x[:-1]),
            "coefficients_rad": a / tf_s ** np.arange(a.size),
            "control": self.control(x[None, :])[0],
            "trajectory": traj,
            "fuel_kg": float((self.y0_nd[4] - prop.y_end[0, 4]) * s.mass_kg),
            "terminal_errors": err,
        }
