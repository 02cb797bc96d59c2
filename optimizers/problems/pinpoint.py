"""Optimal-control spec of the 3D pinpoint landing on a rotating Moon ([001] Peng et al. 2012).

The problem, in the paper's words (§1.2–1.3), on the Moon-fixed Cartesian model of
:mod:`lunar_env.dynamics`:

- dynamics: ``lunar_env.dynamics.moon3d_rhs_casadi`` with the throttle fixed at 1 (the engine
  runs at its constant 1500 N; only the thrust direction (α, β) is steered);
- initial state: fixed (the scenario's ``state_nd()``);
- terminal state: the target point (position) and the target relative velocity (u, v, w in the
  orbital frame at the target; zero for [001]); the mass is free;
- path constraints: α ∈ [α_min, α_max], β ∈ [β_min, β_max] (simple bounds on the controls),
  u, w ∈ [−bound, bound] (radial and cross-track relative velocity, orbital-frame projection
  with the same formulas as :func:`lunar_env.dynamics.moon3d_derived`), fuel used ≤ fuel_max
  (the mass decreases monotonically, so this is m(tf) ≥ m0 − fuel_max);
- objective: minimum fuel = minimum tf (constant thrust, [001] eq. (12)–(13));
- the surface: the trajectory never goes below it. [001] states only the terminal condition
  (h_f = 2 km, the end of the main braking phase), so the 2 km gate altitude is *not* a path
  constraint (decision); "never below the surface" is, because a trajectory through the Moon is
  no landing. It is imposed at every transcription node (|r| >= R_L, :meth:`PinpointOCP.
  path_constraints`) and checked on the replayed trajectory by the verdict
  (:meth:`PinpointOCP.success_from`, ``min_altitude_m`` >= 0), so a start below the gate, or one
  from which the unconstrained optimum dips under the ground, is either flown above the surface
  or reported as a failure (without the path constraint and this check, a solve from 1 km
  reached −4.7 km and was reported a success).

Verdict: position within 1 m of the target point, relative velocity within 0.01 m/s of the
target's, above the surface everywhere, fuel within the budget.

Everything is normalised (μ = 1, L = R_L, m_ref = m0) as in the dynamics core; SI values are
converted at the edges by :class:`lunar_env.scaling.Scaling`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from lunar_env import dynamics as dyn
from lunar_env.integrators import MOON3D, integrate
from lunar_env.scenarios import PinpointScenario

from ..common.casadi_tools import casadi as _casadi_module
from ..common.ocp import OCP
from ..parameterisations import piecewise_linear_control

__all__ = ["PinpointOCP", "orbital_velocity"]


def _ca():
    return _casadi_module()


def orbital_velocity(state, plane_normal):
    """(u, v, w): the relative velocity of a symbolic or numeric normalised Moon-fixed
    ``state`` in the orbital frame of the plane with unit normal ``plane_normal`` (radial,
    transverse, normal)."""
    n = plane_normal
    xr, yr, zr, xt, yt, zt, xn, yn, zn = dyn.orbital_frame(
        state[dyn.X], state[dyn.Y], state[dyn.Z], n[0], n[1], n[2])
    vx, vy, vz = state[dyn.VX], state[dyn.VY], state[dyn.VZ]
    return (vx * xr + vy * yr + vz * zr, vx * xt + vy * yt + vz * zt,
            vx * xn + vy * yn + vz * zn)


@dataclass(frozen=True, eq=False)
class PinpointOCP(OCP):
    """Minimum-time (= minimum-fuel) pinpoint landing, normalised.

    Parameters
    ----------
    scenario : PinpointScenario
        E.g. ``get_scenario("peng2012")``.

    Attributes (derived)
    --------------------
    params : Moon3DParams
    x0_nd : ndarray, shape (7,)
        Initial Moon-fixed state.
    target_position_nd : ndarray, shape (3,)
    target_uvw_nd : ndarray, shape (3,)
        Target relative velocity in the orbital frame (radial, along-track, cross-track).
    alpha_bounds_rad, beta_bounds_rad : (float, float)
    uw_bound_nd : float
    mass_min_nd : float
        m0 − fuel_max (normalised): the fuel constraint as a bound on the final mass.
    tf_bounds_nd : (float, float)
    """

    scenario: PinpointScenario
    #: lowest altitude above R_L allowed along the path (m). 0: the surface ([001] constrains
    #: only the end); ``LunarPinpointLanding-v*`` ends an episode wherever the lander crosses the
    #: 2 km gate sphere, so the env's own per-case optimum uses the gate altitude here.
    min_altitude_m: float = 0.0
    #: extra clearance above that floor away from the target (m): the path must stay
    #: ``floor_margin_m · d²/(d² + floor_margin_range_m²)`` above it, d the distance to the
    #: target point (a state-only, smooth floor that vanishes at the target). 0: none.
    floor_margin_m: float = 0.0
    floor_margin_range_m: float = 5000.0
    params: dyn.Moon3DParams = field(init=False, repr=False)
    x0_nd: np.ndarray = field(init=False, repr=False)
    target_position_nd: np.ndarray = field(init=False, repr=False)
    target_uvw_nd: np.ndarray = field(init=False, repr=False)
    mass_min_nd: float = field(init=False, repr=False)
    uw_bound_nd: float = field(init=False, repr=False)
    tf_bounds_nd: tuple[float, float] = field(init=False, repr=False)

    n_state = 7
    n_control = 2  # (α, β); the throttle is fixed at 1
    model = MOON3D
    tolerances = {"position_m": 1.0, "velocity_m_s": 0.01}

    def __post_init__(self) -> None:
        sc = self.scenario
        if not isinstance(sc, PinpointScenario):
            raise TypeError(f"scenario must be a PinpointScenario (e.g. get_scenario('peng2012'))"
                            f", got {type(sc).__name__}")
        for name in ("min_altitude_m", "floor_margin_m"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0.0):
                raise ValueError(f"{name} = {v!r} must be finite and >= 0")
        if not (np.isfinite(self.floor_margin_range_m) and self.floor_margin_range_m > 0):
            raise ValueError(f"floor_margin_range_m = {self.floor_margin_range_m!r} must be "
                             "finite and > 0")
        s = sc.scaling()
        t = sc.target
        object.__setattr__(self, "params", sc.params(s))
        object.__setattr__(self, "x0_nd", np.asarray(sc.state_nd(scaling=s), dtype=float))
        object.__setattr__(self, "target_position_nd", s.length_nd(sc.target_position_m()))
        object.__setattr__(self, "target_uvw_nd",
                           s.velocity_nd(np.array([t.u_m_s, t.v_m_s, t.w_m_s])))
        fuel_max = min(sc.fuel_max_kg, sc.vehicle.mass_kg - sc.vehicle.dry_mass_kg)
        object.__setattr__(self, "mass_min_nd",
                           float(s.mass_nd(sc.initial.mass_kg - fuel_max)))
        object.__setattr__(self, "uw_bound_nd", float(s.velocity_nd(sc.uw_bound_m_s)))
        object.__setattr__(self, "tf_bounds_nd",
                           tuple(float(v) for v in s.time_nd(np.array(sc.tf_bounds_s))))

    # ---- conveniences ----------------------------------------------------------------------
    @property
    def scaling(self):
        return self.scenario.scaling()

    @property
    def alpha_bounds_rad(self) -> tuple[float, float]:
        return self.scenario.alpha_bounds_rad

    @property
    def beta_bounds_rad(self) -> tuple[float, float]:
        return self.scenario.beta_bounds_rad

    @property
    def control_lower(self) -> np.ndarray:
        return np.array([self.alpha_bounds_rad[0], self.beta_bounds_rad[0]])

    @property
    def control_upper(self) -> np.ndarray:
        return np.array([self.alpha_bounds_rad[1], self.beta_bounds_rad[1]])

    @property
    def mass_flow_nd(self) -> float:
        """|dm/dt| at full thrust (normalised)."""
        return self.params.thrust_nd / self.params.exhaust_velocity_nd

    def fuel_kg(self, tf_nd: float) -> float:
        """Propellant used by a burn of ``tf_nd`` at constant full thrust (kg)."""
        return float(self.mass_flow_nd * tf_nd * self.scaling.mass_kg)

    def tf_upper_by_fuel_nd(self) -> float:
        """Longest burn the fuel budget allows (normalised)."""
        return (1.0 - self.mass_min_nd) / self.mass_flow_nd

    # ---- symbolic pieces (CasADi) ----------------------------------------------------------
    def rhs(self, state, control):
        """Shared right-hand side on CasADi symbols, throttle fixed at 1: (7,), (2,) -> (7,)."""
        ca = _ca()
        return dyn.moon3d_rhs_casadi(state, ca.vertcat(control[0], control[1], 1.0), self.params)

    def uw(self, state):
        """Radial u and cross-track w relative velocity (normalised) of a symbolic state.

        The orbital-frame projection of :func:`lunar_env.dynamics.moon3d_derived`, written with
        :func:`lunar_env.dynamics.orbital_frame` so it evaluates on CasADi symbols.
        """
        n = self.params.plane_normal
        xr, yr, zr, xt, yt, zt, xn, yn, zn = dyn.orbital_frame(
            state[dyn.X], state[dyn.Y], state[dyn.Z], n[0], n[1], n[2])
        vx, vy, vz = state[dyn.VX], state[dyn.VY], state[dyn.VZ]
        return vx * xr + vy * yr + vz * zr, vx * xn + vy * yn + vz * zn

    def uvw(self, state):
        """(u, v, w) of a symbolic or numeric state (normalised)."""
        return orbital_velocity(state, self.params.plane_normal)

    def terminal_residual(self, state):
        """Boundary condition φ(X_f) = 0 ([001] §1.2), shape (6,), normalised.

        Position minus the target point (3), then the relative velocity's orbital-frame
        components minus the target's (u, v, w). For the zero target velocity of [001] the
        latter are equivalent to V = 0.
        """
        ca = _ca()
        pos = ca.vertcat(state[dyn.X], state[dyn.Y], state[dyn.Z]) - self.target_position_nd
        u, v, w = self.uvw(state)
        tu, tv, tw = self.target_uvw_nd
        return ca.vertcat(pos, u - tu, v - tv, w - tw)

    # ---- the transcription protocol (see optimizers.transcription.gpm) ---------------------
    @property
    def initial_state(self) -> np.ndarray:
        return self.x0_nd

    def path_constraints(self, state, control):
        """Path constraints at a node: (expr, lower, upper) with |u|, |w| <= bound and the
        squared radius >= 1 (normalised: never below the surface R_L)."""
        ca = _ca()
        u, w = self.uw(state)
        b = self.uw_bound_nd
        r2 = state[dyn.X] ** 2 + state[dyn.Y] ** 2 + state[dyn.Z] ** 2
        if self.floor_margin_m > 0:
            s = self.scaling
            tp = self.target_position_nd
            d2 = ((state[dyn.X] - tp[0]) ** 2 + (state[dyn.Y] - tp[1]) ** 2
                  + (state[dyn.Z] - tp[2]) ** 2)
            big_d2 = float(s.length_nd(self.floor_margin_range_m)) ** 2
            clearance = ca.sqrt(r2) - self.floor_radius_nd - float(
                s.length_nd(self.floor_margin_m)) * d2 / (d2 + big_d2)
            return (ca.vertcat(u, w, clearance), np.array([-b, -b, 0.0]),
                    np.array([b, b, np.inf]))
        return (ca.vertcat(u, w, r2), np.array([-b, -b, self.floor_radius_nd ** 2]),
                np.array([b, b, np.inf]))

    @property
    def surface_radius_nd(self) -> float:
        return float(self.scaling.length_nd(self.scenario.body.radius_m))

    @property
    def floor_radius_nd(self) -> float:
        """Radius the path must stay above: R_L + ``min_altitude_m`` (normalised)."""
        return float(self.scaling.length_nd(self.scenario.body.radius_m + self.min_altitude_m))

    def state_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Loose box on every node state; the mass never goes below m0 − fuel_max."""
        lo = np.array([-2.0, -2.0, -2.0, -2.0, -2.0, -2.0, self.mass_min_nd])
        hi = np.array([2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 1.0])
        return lo, hi

    def objective(self, final_state, tf):
        """Mayer objective: tf (minimum time = minimum fuel at constant thrust)."""
        return tf

    # ---- numeric helpers -------------------------------------------------------------------
    def propagate(self, breaks_nd: np.ndarray, control_nodes_rad: np.ndarray, n_steps: int,
                  *, record: bool = True):
        """Integrate a piecewise-linear (α, β) history with the compiled RK4 (no events).

        Parameters
        ----------
        breaks_nd : ndarray, shape (n_nodes,)
            Increasing node times, normalised; the first is t0.
        control_nodes_rad : ndarray, shape (n_nodes, 2)
            (α, β) at the nodes; linear in between ([001] eq. (18)).
        n_steps : int
            Uniform RK4 steps over [breaks[0], breaks[-1]].

        Returns
        -------
        lunar_env.integrators.Propagation
        """
        pp = piecewise_linear_control(breaks_nd, control_nodes_rad)
        t0 = float(breaks_nd[0])
        dt = (float(breaks_nd[-1]) - t0) / n_steps
        return integrate(MOON3D, self.x0_nd[None, :], t0_nd=t0, dt_nd=dt, n_steps=n_steps,
                         control=pp, params=self.params, record=record)

    def describe_states(self, states_nd: np.ndarray) -> dict[str, np.ndarray]:
        """SI named histories from normalised states (n, 7): position, altitude, lon, lat,
        u, v, w, mass."""
        s = self.scaling
        d = dyn.moon3d_derived(states_nd, self.params)
        return {
            "x_m": states_nd[:, dyn.X] * s.length_m,
            "y_m": states_nd[:, dyn.Y] * s.length_m,
            "z_m": states_nd[:, dyn.Z] * s.length_m,
            "altitude_m": d["radius_nd"] * s.length_m - self.scenario.body.radius_m,
            "longitude_rad": d["longitude_rad"],
            "latitude_rad": d["latitude_rad"],
            "u_m_s": d["u_nd"] * s.velocity_m_s,
            "v_m_s": d["v_nd"] * s.velocity_m_s,
            "w_m_s": d["w_nd"] * s.velocity_m_s,
            "mass_kg": states_nd[:, dyn.M3] * s.mass_kg,
        }

    def path_quantities(self, states_nd: np.ndarray) -> dict[str, float]:
        """``min_altitude_m`` over the trajectory (n, 7) and ``final_mass_kg``."""
        y = np.atleast_2d(states_nd)
        r = np.linalg.norm(y[:, :3], axis=1)
        return {"min_altitude_m": float(r.min() * self.scaling.length_m
                                        - self.scenario.body.radius_m),
                "final_mass_kg": float(y[-1, dyn.M3] * self.scaling.mass_kg)}

    def success_from(self, errors, path=None) -> tuple[bool, str]:
        ok, why = super().success_from(errors, path)
        path = path or {}
        if ok and path.get("min_altitude_m", np.inf) < 0.0:
            return False, (f"the trajectory passes {-path['min_altitude_m']:.1f} m below the "
                           "surface")
        if ok and self.min_altitude_m > 0 and \
                path.get("min_altitude_m", np.inf) < self.min_altitude_m - 1.0:
            return False, (f"the trajectory passes {path['min_altitude_m']:.1f} m above R_L, "
                           f"below its {self.min_altitude_m:g} m floor")
        if ok and path.get("final_mass_kg", np.inf) < self.mass_min_nd * self.scaling.mass_kg \
                - 1e-6:
            return False, f"uses more than the {self.scenario.fuel_max_kg:g} kg fuel budget"
        return ok, why

    def terminal_errors(self, xf_nd: np.ndarray) -> dict[str, float]:
        """SI terminal errors of a final state (7,): miss distance, speed error, altitude error."""
        s = self.scaling
        pos_err = np.linalg.norm(xf_nd[:3] - self.target_position_nd) * s.length_m
        d = dyn.moon3d_derived(xf_nd[None, :], self.params)
        uvw = np.array([d["u_nd"][0], d["v_nd"][0], d["w_nd"][0]])
        vel_err = np.linalg.norm(uvw - self.target_uvw_nd) * s.velocity_m_s
        alt = d["radius_nd"][0] * s.length_m - self.scenario.body.radius_m
        return {"position_m": float(pos_err), "velocity_m_s": float(vel_err),
                "altitude_m": float(alt - self.scenario.target.altitude_m)}
