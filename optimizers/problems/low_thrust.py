"""Earth–Mars low-thrust transfer with the interpolation parameterisation of [002] (Peng et al.).

The planar polar model of :mod:`lunar_env.dynamics` with heliocentric constants (scenario
``peng_mars``: circular coplanar Earth and Mars orbits, planets' gravity neglected, constant
0.5 N thrust, so maximum final mass is minimum time). Normalised units of the paper
(r* = r0 = 1 AU, m* = m0, μ = 1; time unit sqrt(r0³/μ) = 58.13 days).

Decision vector (``dim = 11``, [002] §3 and §5)
------------------------------------------------

=========  ========================================  ======  ========================
index      meaning                                   unit    bounds ([002] §5)
=========  ========================================  ======  ========================
0 … 4      thrust angle u_i at node i                rad     [0, π]
5 … 9      thrust angle u_i at node i                rad     [π, 2π]
10         final time tf                             t*      [3.5, 4]  (203–233 days)
=========  ========================================  ======  ========================

The paper's thrust angle u is measured from the local horizontal in the direction of motion
(v_θ' = … + (F/m) cos u, v_r' = … + (F/m) sin u). The shared model's φ is measured from the
local horizontal *against* the motion (cos φ > 0 brakes), so φ = π − u; both are linear, so a
polynomial through the u_i is the polynomial through the φ_i = π − u_i. The M = 10 nodes sit at
t_i = i·tf/9; a polynomial with N = 6 power terms (degree 5) is least-squares fitted through
them (:class:`optimizers.parameterisations.NodePolynomial`, "interpolation function
approximation"; with N < M the fit is a least-squares one, the paper's "插值拟合").

Fitness ``[−m(tf)/m0, ceq_r, ceq_vr, ceq_vt]`` (pygmo order, minimised; normalised units):
``ceq_r = r(tf) − r_f``, ``ceq_vr = v_r(tf)``, ``ceq_vt = v_θ(tf) − sqrt(1/r_f)``. The penalised
affinity of [002] eq. (3) is built from these by :mod:`optimizers.evolutionary.penalties`:
``f_aff = m(tf)/m0 − σ1|Δr| − σ2|Δv_r| − σ3|Δv_θ|`` (three penalty groups, factor 1, in the
normalised units of the paper's eq. (2)); the weights σ_λ are the algorithm's schedule
(:func:`optimizers.evolutionary.gaia.annealed_penalty_weight`).

Success (:meth:`LowThrustTransferProblem.assess`). The paper gives no tolerance. The transfer
ends where Mars' capture phase begins, so "arrived on Mars' orbit" is judged on that scale:
``|Δr| < radius_tol_m`` (default 1e8 m = 1e5 km, a sixth of Mars' sphere of influence of
5.8e5 km) and ``|Δv| < speed_tol_m_s`` (default 10 m/s: the 0.5 N engine removes it in
~3 hours for ~0.13 kg of propellant, 0.05 % of the transfer's). Fixed before any run was made.

Integration: one compiled batched RK4 call (:func:`lunar_env.integrators.integrate_prepared`)
for the whole population, ``n_steps`` = 100 equal steps (≈2.2 days). Measured at the
parameterisation's optimum against 3200 steps: terminal radius error 1.2e-7 r0 (18 km) and
velocity errors 1e-7 (3 mm/s); 200 steps: 7.6e-9 r0; fourth-order convergence
(``tests/test_gaia.py::test_rk4_against_dop853`` checks it against DOP853). Four orders below
the success tolerances.
"""

from __future__ import annotations

import functools
import math

import numba
import numpy as np

from lunar_env import get_scenario
from lunar_env.integrators import PLANAR, integrate, integrate_prepared, params_rows
from lunar_env.scenarios import PlanarScenario

from ..common.problem import PenaltyGroup, Problem, central_difference_jacobian
from ..common.result import ControlLaw, Trajectory
from ..parameterisations import NodePolynomial

__all__ = ["LowThrustTransferProblem", "paper_node_bounds"]


def paper_node_bounds(n_nodes: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """[002] §5: the first half of the node angles in [0, π], the second half in [π, 2π] (rad).

    Returns
    -------
    lower, upper : ndarray, shape (n_nodes,)
    """
    half = n_nodes // 2
    lo = np.where(np.arange(n_nodes) < half, 0.0, math.pi)
    return lo, lo + math.pi


class LowThrustTransferProblem(Problem):
    """Maximum-final-mass planar low-thrust transfer between circular orbits ([002]).

    Parameters
    ----------
    scenario : str or PlanarScenario
        Default ``"peng_mars"`` (heliocentric Earth → Mars).
    parameterisation : NodePolynomial, optional
        Default ``NodePolynomial(10, 5)``: M = 10 nodes, N = 6 power terms ([002] §5).
    n_steps : int
        RK4 steps over [0, tf] (default 100).
    node_bounds_rad : (ndarray, ndarray), optional
        Bounds of the paper's thrust angles u_i; default :func:`paper_node_bounds`.
    tf_bounds_nd : (float, float)
        Normalised final-time bounds (default the paper's (3.5, 4)).
    radius_tol_m, speed_tol_m_s : float
        Success criterion (see the module docstring).
    parallel : bool
        Threaded RK4 kernel (default False: measured on 2 cores, the serial kernel evaluates
        a GAIA generation's 1000 candidates at 33 µs each against 65 µs threaded, and a
        100-candidate batch at 120 µs against 510 µs each).

    Raises
    ------
    ValueError
        A non-planar scenario, bad bounds, non-positive tolerances or step counts.
    """

    def __init__(self, scenario: str | PlanarScenario = "peng_mars",
                 parameterisation: NodePolynomial | None = None, n_steps: int = 100,
                 node_bounds_rad=None, tf_bounds_nd: tuple[float, float] = (3.5, 4.0),
                 radius_tol_m: float = 1.0e8, speed_tol_m_s: float = 10.0,
                 parallel: bool = False) -> None:
        super().__init__()
        sc = get_scenario(scenario) if isinstance(scenario, str) else scenario
        if not isinstance(sc, PlanarScenario):
            raise ValueError(f"scenario {getattr(sc, 'name', sc)!r} is not planar; "
                             "LowThrustTransferProblem needs a PlanarScenario (e.g. 'peng_mars')")
        n_steps = int(n_steps)
        if n_steps < 1:
            raise ValueError(f"n_steps = {n_steps} must be >= 1")
        for name, v in dict(radius_tol_m=radius_tol_m, speed_tol_m_s=speed_tol_m_s).items():
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} = {v!r} must be a finite number > 0")
        self.scenario = sc
        self.parameterisation = parameterisation or NodePolynomial(10, 5)
        self.n_steps = n_steps
        self.radius_tol_m = float(radius_tol_m)
        self.speed_tol_m_s = float(speed_tol_m_s)
        self.parallel = parallel
        self.scaling = sc.scaling()
        self.params = sc.params(self.scaling)
        self.y0_nd = sc.state_nd(scaling=self.scaling)
        self.dry_mass_nd = float(self.scaling.mass_nd(sc.vehicle.dry_mass_kg))
        n = self.parameterisation.n_nodes
        lo, hi = paper_node_bounds(n) if node_bounds_rad is None else (
            np.asarray(node_bounds_rad[0], float), np.asarray(node_bounds_rad[1], float))
        tfb = tuple(map(float, tf_bounds_nd))
        if lo.shape != (n,) or hi.shape != (n,) or not np.all(lo <= hi):
            raise ValueError(f"node bounds must have shape ({n},) with lower <= upper; got "
                             f"{lo!r}, {hi!r}")
        if not 0.0 < tfb[0] <= tfb[1]:
            raise ValueError(f"tf_bounds_nd = {tfb!r} must satisfy 0 < low <= high")
        self._lb = np.concatenate([lo, [tfb[0]]])
        self._ub = np.concatenate([hi, [tfb[1]]])
        t = sc.target
        self.target_nd = np.array([self.scaling.length_nd(t.radius_m),
                                   self.scaling.velocity_nd(t.radial_velocity_m_s),
                                   self.scaling.velocity_nd(t.tangential_velocity_m_s)])
        self._consts: dict = {}

    # ---- pygmo UDP surface ----------------------------------------------------------------
    def get_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self._lb.copy(), self._ub.copy()

    def get_nec(self) -> int:
        return 3

    def get_name(self) -> str:
        return f"LowThrustTransferProblem[{self.scenario.name}]"

    # ---- core -----------------------------------------------------------------------------
    @staticmethod
    def model_angle(u_rad):
        """The shared model's φ (from the horizontal, cos φ > 0 brakes) from the paper's u."""
        return math.pi - np.asarray(u_rad, dtype=np.float64)

    @staticmethod
    def paper_angle(phi_rad):
        """The paper's u in [0, 2π) from the model's φ."""
        return np.mod(math.pi - np.asarray(phi_rad, dtype=np.float64), 2.0 * math.pi)

    def control(self, X: np.ndarray):
        """Control law (normalised time) and tf_nd for decision vectors ``X`` (batch, dim)."""
        X = np.atleast_2d(np.asarray(X, dtype=np.float64))
        return self.parameterisation.control(self.model_angle(X[:, :-1]), 0.0, X[:, -1]), \
            X[:, -1].copy()

    def propagate(self, X: np.ndarray, *, record: bool = False, n_steps: int | None = None):
        """Integrate every candidate to its tf (one batched RK4 call); normalised units."""
        X = np.atleast_2d(np.asarray(X, dtype=np.float64))
        control, tf_nd = self.control(X)
        n = self.n_steps if n_steps is None else int(n_steps)
        y0 = np.broadcast_to(self.y0_nd, (X.shape[0], 5))
        return integrate(PLANAR, y0, t0_nd=0.0, dt_nd=tf_nd / n, n_steps=n, control=control,
                         params=self.params, dry_mass_nd=self.dry_mass_nd, events=(),
                         record=record)

    def _end_states(self, X: np.ndarray) -> np.ndarray:
        n = X.shape[0]
        tf_nd = np.ascontiguousarray(X[:, -1])
        if not np.all(tf_nd > 0):
            raise ValueError(f"tf must be > 0; got {tf_nd[~(tf_nd > 0)][0]!r}")
        breaks, coefs = self.parameterisation.control_arrays(self.model_angle(X[:, :-1]), 0.0,
                                                             tf_nd)
        consts = self._consts.get(n)
        if consts is None:
            par = bool(self.parallel) and numba.config.NUMBA_NUM_THREADS > 1
            consts = (np.ascontiguousarray(np.broadcast_to(self.y0_nd, (n, 5))), np.zeros(n),
                      np.full(n, np.nan), params_rows(self.params, n), par)
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
        out = np.empty((X.shape[0], 4))
        out[:, 0] = -y[:, 4]
        out[:, 1] = y[:, 0] - self.target_nd[0]
        out[:, 2] = y[:, 1] - self.target_nd[1]
        out[:, 3] = y[:, 0] * y[:, 3] - self.target_nd[2]
        return out

    def gradient(self, x: np.ndarray, rel_step: float = 1e-6) -> np.ndarray:
        """Central finite-difference Jacobian of :meth:`fitness`, shape (n_f, dim), one batch."""
        return central_difference_jacobian(self, x, rel_step)

    # ---- verdict and penalty --------------------------------------------------------------
    def penalty_groups(self) -> list[PenaltyGroup]:
        """[002] eq. (3): σ1|Δr|, σ2|Δv_r|, σ3|Δv_θ| in the paper's normalised units."""
        return [PenaltyGroup("radius", eq=(0,)), PenaltyGroup("radial_velocity", eq=(1,)),
                PenaltyGroup("tangential_velocity", eq=(2,))]

    def terminal_errors(self, x: np.ndarray, f: np.ndarray) -> dict[str, float]:
        """SI terminal errors: ``radius_m``, ``radial_velocity_m_s``,
        ``tangential_velocity_m_s`` (signed) and ``speed_m_s`` (norm of the velocity error)."""
        s = self.scaling
        dvr = float(f[2]) * s.velocity_m_s
        dvt = float(f[3]) * s.velocity_m_s
        return {"radius_m": float(f[1]) * s.length_m, "radial_velocity_m_s": dvr,
                "tangential_velocity_m_s": dvt, "speed_m_s": math.hypot(dvr, dvt)}

    def success_from(self, x, f, errors, feasible) -> tuple[bool, str]:
        ok = (abs(errors["radius_m"]) < self.radius_tol_m
              and errors["speed_m_s"] < self.speed_tol_m_s)
        crit = f"|dr| < {self.radius_tol_m:.3g} m, |dV| < {self.speed_tol_m_s:g} m/s"
        return bool(ok), (f"arrived on the target orbit ({crit})" if ok else
                          f"did NOT arrive ({crit}): dr = {errors['radius_m']:.4g} m, |dV| = "
                          f"{errors['speed_m_s']:.4g} m/s")

    def fuel_tf(self, x: np.ndarray, f: np.ndarray) -> tuple[float, float]:
        return (float((self.y0_nd[4] + f[0]) * self.scaling.mass_kg),
                float(x[-1] * self.scaling.time_s))

    def fuel_kg(self, F: np.ndarray) -> np.ndarray:
        """Propellant (kg) from fitness rows, shape (batch,)."""
        return (self.y0_nd[4] + np.atleast_2d(F)[:, 0]) * self.scaling.mass_kg

    def _fingerprint_items(self) -> list:
        return super()._fingerprint_items() + [self.scenario, self.y0_nd.tolist(), self.n_steps,
                                               repr(self.parameterisation)]

    @functools.cached_property
    def ocp(self):
        """The continuous problem (:class:`~optimizers.problems.planar_ocp.PlanarOCP`) whose
        Pontryagin optimum the gap is measured against."""
        from .planar_ocp import PlanarOCP

        return PlanarOCP(self.scenario)

    def control_law(self, x: np.ndarray) -> ControlLaw:
        """(φ(t), throttle 1) of the fitted polynomial on SI time, picklable."""
        return ControlLaw(self.control(np.asarray(x, dtype=np.float64)[None, :])[0],
                          self.scaling.time_s)

    # ---- decoding -------------------------------------------------------------------------
    def thrust_angle_rad(self, x: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """The paper's fitted thrust angle u(t) (rad, not wrapped) at times ``t_s`` (s)."""
        x = np.asarray(x, dtype=np.float64)
        s = np.asarray(t_s, dtype=np.float64) / (x[-1] * self.scaling.time_s)
        return self.parameterisation.evaluate(x[None, :-1], s)[0]

    def node_angles_for(self, u_of_s) -> np.ndarray:
        """Node values of a thrust-angle law ``u_of_s(s)`` (s = t/tf in [0, 1]), clipped to the
        bounds: the decision vector's first ``n_nodes`` entries that sample it."""
        lb, ub = self.get_bounds()
        u = np.asarray(u_of_s(self.parameterisation.node_fractions), dtype=np.float64)
        return np.clip(u, lb[:-1], ub[:-1])

    def decode(self, x: np.ndarray, n_steps: int | None = None) -> dict:
        """Physical meaning of one decision vector.

        Returns
        -------
        dict with ``tf_s``, ``tf_days``; ``node_times_s`` and ``node_angles_rad`` (paper's u);
        ``trajectory`` (:class:`Trajectory`, SI: ``radius_m``, ``radial_velocity_m_s``,
        ``theta_rad``, ``tangential_velocity_m_s``, ``mass_kg``; controls ``u_rad`` (paper)
        and ``phi_rad`` (model)); ``fuel_kg``; ``terminal_errors`` (SI).
        """
        x = np.asarray(x, dtype=np.float64)
        if x.shape != (self.dim,):
            raise ValueError(f"x has shape {x.shape}; expected ({self.dim},)")
        prop = self.propagate(x[None, :], record=True, n_steps=n_steps)
        s = self.scaling
        n = int(prop.n_records[0])
        st = prop.states[0, :n]
        t_s = prop.times[0, :n] * s.time_s
        u = self.thrust_angle_rad(x, t_s)
        traj = Trajectory(
            t_s=t_s,
            states={"radius_m": st[:, 0] * s.length_m,
                    "radial_velocity_m_s": st[:, 1] * s.velocity_m_s,
                    "theta_rad": st[:, 2].copy(),
                    "tangential_velocity_m_s": st[:, 0] * st[:, 3] * s.velocity_m_s,
                    "mass_kg": st[:, 4] * s.mass_kg},
            controls={"u_rad": u, "phi_rad": self.model_angle(u),
                      "throttle": np.ones_like(u)})
        f = self._batch_fitness(x[None, :])[0]
        tf_s = float(x[-1] * s.time_s)
        return {"tf_s": tf_s, "tf_days": tf_s / 86400.0,
                "node_times_s": self.parameterisation.node_times(0.0, tf_s)[0],
                "node_angles_rad": x[:-1].copy(), "trajectory": traj,
                "fuel_kg": float((self.y0_nd[4] - prop.y_end[0, 4]) * s.mass_kg),
                "terminal_errors": self.terminal_errors(x, f)}
