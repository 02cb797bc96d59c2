"""The planar minimum-fuel problem at constant thrust, stated once ([000], [002], [003]).

One :class:`~optimizers.common.ocp.OCP` for the planar polar model of
:mod:`lunar_env.dynamics`: powered descent to a soft landing ([000] Zhu & Xu 2007, [003]) and,
with heliocentric constants, the low-thrust transfer to a circular orbit ([002]). The engine
burns at constant full thrust (throttle 1) and only the thrust angle φ is steered, so minimum
fuel is minimum time.

Normalised units (μ = 1, ``scenario.scaling()``): state x = (r, v, θ, ω, m), control φ.
Terminal conditions r(tf) = r_f, v(tf) = v_f, r(tf)·ω(tf) = v_t,f; θ(tf) and m(tf) free; the
initial state is the scenario's nominal one or any SI row (r m, vr m/s, θ rad, v_t m/s, m kg).

Verdict (:meth:`PlanarOCP.success_from`): the terminal radius within ``max(1 m, 1e-8 r_f)`` and
the terminal velocity within 0.01 m/s (the accuracy the certifiers reach with margin:
Pontryagin's DOP853 replay ends 2e-7 m and 4e-10 m/s from the target on zhu2007), the mass
above the dry mass, and — for a landing — never more than 1 m below the surface.
"""

from __future__ import annotations

import math

import numpy as np

from lunar_env import dynamics as dyn
from lunar_env.scenarios import PlanarScenario, get_scenario

from ..common.casadi_tools import casadi
from ..common.ocp import OCP

__all__ = ["PlanarOCP", "as_planar_ocp"]


class PlanarOCP(OCP):
    """Minimum-time (= minimum-fuel) planar transfer or landing at constant thrust.

    Parameters
    ----------
    scenario : PlanarScenario or str
        E.g. ``"zhu2007"``, ``"wang2003"`` (with the vehicle's thrust), ``"peng_mars"``.
    initial_state_si : array_like, shape (5,), optional
        (r m, vr m/s, θ rad, v_t m/s, m kg); default the scenario's nominal initial state.

    Raises
    ------
    TypeError
        ``scenario`` is not planar.
    ValueError
        A bad initial state (shape, non-finite, r <= 0, mass at or below the dry mass).
    """

    n_state = 5
    n_control = 1

    def __init__(self, scenario: PlanarScenario | str = "zhu2007", initial_state_si=None
                 ) -> None:
        sc = get_scenario(scenario) if isinstance(scenario, str) else scenario
        if not isinstance(sc, PlanarScenario):
            raise TypeError(f"scenario must be a PlanarScenario (e.g. get_scenario('zhu2007')), "
                            f"got {type(sc).__name__}")
        self.scenario = sc
        self._scaling = sc.scaling()
        self.params = sc.params(self._scaling)
        if initial_state_si is None:
            self.x0_nd = sc.state_nd(scaling=self._scaling)
        else:
            self.x0_nd = sc.si_to_nd(sc.check_state_si(initial_state_si), self._scaling)
        s, t = self._scaling, sc.target
        self.target_nd = np.array([s.length_nd(t.radius_m), s.velocity_nd(t.radial_velocity_m_s),
                                   s.velocity_nd(t.tangential_velocity_m_s)], dtype=np.float64)
        self.tolerances = {"radius_m": max(1.0, 1e-8 * t.radius_m), "speed_m_s": 0.01}

    def __repr__(self) -> str:
        return f"PlanarOCP({self.scenario.name!r}, x0_nd={self.x0_nd.tolist()})"

    def with_initial_state_si(self, initial_state_si) -> PlanarOCP:
        """The same problem from another SI initial state."""
        return PlanarOCP(self.scenario, initial_state_si)

    # ---- the OCP contract -----------------------------------------------------------------
    @property
    def scaling(self):
        return self._scaling

    @property
    def initial_state(self) -> np.ndarray:
        return self.x0_nd

    @property
    def initial_state_si(self) -> np.ndarray:
        return self.scenario.nd_to_si(self.x0_nd, self._scaling)

    def rhs(self, state, control):
        """Shared planar right-hand side on CasADi symbols, throttle fixed at 1."""
        ca = casadi()
        return dyn.planar_rhs_casadi(state, ca.vertcat(control[0], 1.0), self.params)

    def terminal_residual(self, final_state):
        ca = casadi()
        x, tgt = final_state, self.target_nd
        return ca.vertcat(x[dyn.R] - tgt[0], x[dyn.VR] - tgt[1], x[dyn.R] * x[dyn.OMEGA] - tgt[2])

    @property
    def tf_bounds_nd(self) -> tuple[float, float]:
        lo, hi = self.scenario.tf_bounds_s
        return float(self._scaling.time_nd(lo)), float(self._scaling.time_nd(hi))

    @property
    def mass_flow_nd(self) -> float:
        """|dm/dt| at full thrust (normalised)."""
        return self.params.thrust_nd / self.params.exhaust_velocity_nd

    def fuel_kg(self, tf_nd: float) -> float:
        return float(self.mass_flow_nd * tf_nd * self._scaling.mass_kg)

    @property
    def dry_mass_nd(self) -> float:
        return float(self._scaling.mass_nd(self.scenario.vehicle.dry_mass_kg))

    def rocket_equation_tf_nd(self) -> float:
        """First guess of tf from the rocket equation ([000] eq. 23) with the speed to remove:
        tf ≈ (1 − exp(−Δv/c))·m0·c/F, Δv = |(v0, r0ω0) − (v_f, v_t,f)| (normalised)."""
        x0, tgt, p = self.x0_nd, self.target_nd, self.params
        dv = math.hypot(x0[dyn.VR] - tgt[1], x0[dyn.R] * x0[dyn.OMEGA] - tgt[2])
        c = p.exhaust_velocity_nd
        return float((1.0 - math.exp(-dv / c)) * x0[dyn.M] * c / p.thrust_nd)

    def terminal_errors(self, final_state_nd: np.ndarray) -> dict[str, float]:
        """Absolute SI errors: ``radius_m``, ``radial_velocity_m_s``,
        ``tangential_velocity_m_s`` and their norm ``speed_m_s``."""
        xf = np.asarray(final_state_nd, dtype=np.float64)
        s, tgt = self._scaling, self.target_nd
        dr = abs(xf[dyn.R] - tgt[0]) * s.length_m
        dv = (xf[dyn.VR] - tgt[1]) * s.velocity_m_s
        dvt = (xf[dyn.R] * xf[dyn.OMEGA] - tgt[2]) * s.velocity_m_s
        return {"radius_m": float(dr), "radial_velocity_m_s": float(abs(dv)),
                "tangential_velocity_m_s": float(abs(dvt)), "speed_m_s": float(math.hypot(dv, dvt))}

    @property
    def model(self):
        from lunar_env.integrators import PLANAR

        return PLANAR

    def path_quantities(self, states_nd: np.ndarray) -> dict[str, float]:
        """``min_altitude_m`` above the scenario's surface and ``final_mass_kg``."""
        y = np.atleast_2d(states_nd)
        s = self._scaling
        return {"min_altitude_m": float(np.min(y[:, dyn.R])) * s.length_m
                - self.scenario.surface_radius_m,
                "final_mass_kg": float(y[-1, dyn.M]) * s.mass_kg}

    def success_from(self, errors, path=None) -> tuple[bool, str]:
        ok, why = super().success_from(errors, path)
        path = path or {}
        if ok and path.get("final_mass_kg", math.inf) <= self.scenario.vehicle.dry_mass_kg:
            return False, (f"needs more propellant than there is above the dry mass "
                           f"({path['final_mass_kg']:.3f} kg final mass)")
        if ok and path.get("min_altitude_m", math.inf) < -1.0:
            return False, (f"passes {-path['min_altitude_m']:.1f} m below the surface")
        return ok, why


def as_planar_ocp(problem, initial_state_si=None) -> PlanarOCP:
    """A :class:`PlanarOCP` from a PlanarOCP, a PlanarScenario or a scenario name (with an
    optional SI initial state overriding the problem's)."""
    if isinstance(problem, PlanarOCP):
        return problem if initial_state_si is None else problem.with_initial_state_si(
            initial_state_si)
    if isinstance(problem, str | PlanarScenario):
        return PlanarOCP(problem, initial_state_si)
    raise TypeError(f"expected a PlanarOCP, a PlanarScenario or a scenario name, got "
                    f"{type(problem).__name__}")
