"""Optimal-control spec of the pinpoint landing to touchdown with a throttleable engine
(``LunarPinpointLanding-v3``, scenario ``peng2012_touchdown``).

On the Moon-fixed Cartesian model of :mod:`lunar_env.dynamics` (normalised: μ = 1, L = R_L,
m_ref = m0 of the scenario):

- control: the thrust direction ê, a unit vector given by its components (e_r, e_t, e_n) in the
  orbital frame (radial, along-track, cross-track), and the throttle Γ ∈ [Γ_min, 1]; the
  dynamics are the shared control half :func:`lunar_env.dynamics.moon3d_eom_terms` with
  (Γ e_r, Γ e_t, Γ e_n, Γ) (exactly what (α, β, Γ) gives through
  :func:`~lunar_env.dynamics.moon3d_thrust_terms`);
- initial state: fixed (a drawn start, a true start of a campaign case);
- terminal state: the target point on the surface at rest relative to the Moon (its
  orbital-frame velocity equal to the target's, zero for touchdown); the mass is free;
- objective: maximum final mass (minimum propellant), free final time;
- constraints: the thrust elevation above its lower bound (e_r >= sin α_min; the azimuth is
  free on the whole circle and the elevation reaches the vertical for ``peng2012_touchdown``);
  the mass above m0 − propellant budget; the path above the surface (checked on the replayed
  trajectory: a touchdown approaches from above).

The optimum is bang–bang in the throttle: by Pontryagin's principle Γ = 1 where the switching
function S = −|λ_v|/m − λ_m/c is negative and Γ = Γ_min where it is positive. (A singular arc,
S ≡ 0 on an interval, is ruled out case by case: the certification checks S's sign at every
node of every arc.) For [001]'s start the arcs are max–min–max: full thrust for 7.4 s, the
minimum throttle for 23.6 s, full thrust to touchdown; at corners of its dispersion the first
arc shortens to 0.8 s or vanishes (min–max). The solvers work on that *arc structure*, a tuple
of throttle levels, each arc of free duration: :mod:`optimizers.transcription.phased_gpm`
(Legendre–Gauss collocation per arc) and :mod:`optimizers.indirect.touchdown` (Pontryagin
multi-arc shooting).

The plant's thrust and exhaust velocity are *parameters* of every built NLP and shooting
function (the normalisation does not depend on them), so one build serves every true engine
of a campaign.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from lunar_env import dynamics as dyn
from lunar_env.integrators import MOON3D
from lunar_env.scenarios import TouchdownScenario

from ..common.casadi_tools import casadi as _casadi
from ..common.ocp import OCP
from .pinpoint import orbital_velocity

__all__ = ["TouchdownOCP", "MAX_MIN_MAX"]

#: The arc structure of the optimum from [001]'s start: full thrust, the minimum throttle, full
#: thrust (levels as fractions of full thrust, ``None`` = the scenario's minimum throttle).
MAX_MIN_MAX = (1.0, None, 1.0)


@dataclass(frozen=True, eq=False)
class TouchdownOCP(OCP):
    """Minimum-propellant landing to touchdown with a throttleable engine, normalised.

    Parameters
    ----------
    scenario : TouchdownScenario
        E.g. ``get_scenario("peng2012_touchdown")``.
    tf_max_s : float, optional
        Upper bound of the final time (s); default the scenario's ``tf_bounds_s[1]``.

    Attributes (derived)
    --------------------
    params : Moon3DParams
        Nominal engine (thrust, exhaust velocity), spin, orbit-plane normal.
    x0_nd : ndarray, shape (7,)
        The scenario's nominal start (solvers take any other as ``initial_state``).
    target_position_nd, target_uvw_nd : ndarray, shape (3,)
    throttle_min : float
    sin_alpha_min : float
        Lower bound of e_r (sine of the lowest thrust elevation).
    mass_min_nd : float
        m0 − propellant budget (normalised).
    surface_radius_nd : float
    """

    scenario: TouchdownScenario
    tf_max_s: float | None = None
    params: dyn.Moon3DParams = field(init=False, repr=False)
    x0_nd: np.ndarray = field(init=False, repr=False)
    target_position_nd: np.ndarray = field(init=False, repr=False)
    target_uvw_nd: np.ndarray = field(init=False, repr=False)
    throttle_min: float = field(init=False, repr=False)
    sin_alpha_min: float = field(init=False, repr=False)
    mass_min_nd: float = field(init=False, repr=False)
    surface_radius_nd: float = field(init=False, repr=False)
    tf_bounds_nd: tuple[float, float] = field(init=False, repr=False)

    n_state = 7
    #: (e_r, e_t, e_n, Γ): thrust direction in the orbital frame and throttle
    n_control = 4
    model = MOON3D
    #: the replay's terminal tolerances (SI): the DOP853 replay of a certified optimum lands
    #: within 1 cm and 1 mm/s of the target (measured: below 1e-6 m and 1e-8 m/s)
    tolerances = {"position_m": 0.01, "velocity_m_s": 0.001}

    def __post_init__(self) -> None:
        sc = self.scenario
        if not isinstance(sc, TouchdownScenario):
            raise TypeError("scenario must be a TouchdownScenario (e.g. get_scenario("
                            f"'peng2012_touchdown')), got {type(sc).__name__}")
        s = sc.scaling()
        t = sc.target
        object.__setattr__(self, "params", sc.params(s))
        object.__setattr__(self, "x0_nd", np.asarray(sc.state_nd(scaling=s), dtype=float))
        object.__setattr__(self, "target_position_nd", s.length_nd(sc.target_position_m()))
        object.__setattr__(self, "target_uvw_nd",
                           s.velocity_nd(np.array([t.u_m_s, t.v_m_s, t.w_m_s])))
        object.__setattr__(self, "throttle_min", float(sc.throttle_min))
        object.__setattr__(self, "sin_alpha_min", math.sin(sc.alpha_bounds_rad[0]))
        budget = min(sc.fuel_max_kg, sc.vehicle.mass_kg - sc.vehicle.dry_mass_kg)
        object.__setattr__(self, "mass_min_nd", float(s.mass_nd(sc.initial.mass_kg - budget)))
        object.__setattr__(self, "surface_radius_nd",
                           float(s.length_nd(sc.body.radius_m + t.altitude_m)))
        tf_max = sc.tf_bounds_s[1] if self.tf_max_s is None else float(self.tf_max_s)
        if not (math.isfinite(tf_max) and tf_max > 0):
            raise ValueError(f"tf_max_s = {self.tf_max_s!r} must be finite and > 0")
        object.__setattr__(self, "tf_bounds_nd", (0.0, float(s.time_nd(tf_max))))

    # ---- conveniences ----------------------------------------------------------------------
    @property
    def scaling(self):
        return self.scenario.scaling()

    @property
    def initial_state(self) -> np.ndarray:
        return self.x0_nd

    @property
    def mass_flow_nd(self) -> float:
        """|dm/dt| at full thrust of the nominal engine (normalised)."""
        return self.params.thrust_nd / self.params.exhaust_velocity_nd

    def levels(self, structure) -> tuple[float, ...]:
        """Throttle levels of an arc structure (``None`` = the minimum throttle)."""
        out = tuple(self.throttle_min if g is None else float(g) for g in structure)
        for g in out:
            if not self.throttle_min - 1e-12 <= g <= 1.0 + 1e-12:
                raise ValueError(f"arc throttle {g!r} is outside [{self.throttle_min}, 1]")
        return out

    def fuel_kg(self, tf_nd: float) -> float:
        """Propellant of a burn of ``tf_nd`` at full throttle (kg): an upper bound of this
        problem's propellant for that final time (solutions report theirs from the final mass,
        :meth:`arc_fuel_kg`)."""
        return float(self.mass_flow_nd * tf_nd * self.scaling.mass_kg)

    def arc_fuel_kg(self, durations_nd, levels, thrust_nd: float | None = None,
                    exhaust_velocity_nd: float | None = None) -> float:
        """Propellant of arcs of the given durations (normalised) and throttle levels (kg),
        with the nominal engine or the given one (the mass flow is constant on an arc)."""
        T = self.params.thrust_nd if thrust_nd is None else float(thrust_nd)
        c = self.params.exhaust_velocity_nd if exhaust_velocity_nd is None \
            else float(exhaust_velocity_nd)
        burn = float(np.dot(np.asarray(durations_nd, float), np.asarray(levels, float)))
        return T / c * burn * self.scaling.mass_kg

    # ---- symbolic pieces (CasADi) ----------------------------------------------------------
    def rhs_engine(self, state, control, thrust_nd, exhaust_velocity_nd):
        """Right-hand side on CasADi symbols with the engine's thrust and exhaust velocity as
        arguments (symbols or numbers): state (7,), control (e_r, e_t, e_n, Γ) -> (7,)."""
        ca = _casadi()
        p = self.params
        n = p.plane_normal
        g = control[3]
        return ca.vertcat(*dyn.moon3d_eom_terms(
            state[dyn.X], state[dyn.Y], state[dyn.Z], state[dyn.VX], state[dyn.VY],
            state[dyn.VZ], state[dyn.M3], g * control[0], g * control[1], g * control[2], g,
            thrust_nd, exhaust_velocity_nd, p.spin_rate_nd, n[0], n[1], n[2]))

    def rhs(self, state, control):
        """Right-hand side with the nominal engine (the :class:`OCP` contract)."""
        p = self.params
        return self.rhs_engine(state, control, p.thrust_nd, p.exhaust_velocity_nd)

    def uvw(self, state):
        """(u, v, w): the relative velocity in the orbital frame, symbolic or numeric."""
        return orbital_velocity(state, self.params.plane_normal)

    def terminal_residual(self, state):
        """Touchdown: position minus the target point (3), then (u, v, w) minus the target's
        (3), shape (6,), normalised."""
        ca = _casadi()
        pos = ca.vertcat(state[dyn.X], state[dyn.Y], state[dyn.Z]) - self.target_position_nd
        u, v, w = self.uvw(state)
        tu, tv, tw = self.target_uvw_nd
        return ca.vertcat(pos, u - tu, v - tv, w - tw)

    def orbital_components(self, state, vector):
        """Components of a Moon-fixed vector (3,) in the orbital frame at ``state`` (radial,
        along-track, cross-track); symbolic or numeric."""
        n = self.params.plane_normal
        f = dyn.orbital_frame(state[dyn.X], state[dyn.Y], state[dyn.Z], n[0], n[1], n[2])
        return tuple(vector[0] * f[3 * k] + vector[1] * f[3 * k + 1] + vector[2] * f[3 * k + 2]
                     for k in range(3))

    @property
    def control_lower(self) -> np.ndarray:
        return np.array([self.sin_alpha_min, -1.0, -1.0, self.throttle_min])

    @property
    def control_upper(self) -> np.ndarray:
        return np.array([1.0, 1.0, 1.0, 1.0])

    def state_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Loose box on every node state; the mass never below m0 − budget."""
        lo = np.array([-2.0, -2.0, -2.0, -2.0, -2.0, -2.0, self.mass_min_nd])
        hi = np.array([2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0])
        return lo, hi

    def objective(self, final_state, tf):
        """Mayer objective: −m(tf) (maximum final mass = minimum propellant)."""
        return -final_state[dyn.M3]

    # ---- numeric helpers -------------------------------------------------------------------
    @staticmethod
    def angles_of(directions: np.ndarray) -> np.ndarray:
        """Thrust elevation α and azimuth β (rad, β in [0, 2π)) of orbital-frame directions
        (n, 3) (the model's control angles)."""
        d = np.asarray(directions, dtype=float)
        alpha = np.arctan2(d[:, 0], np.hypot(d[:, 1], d[:, 2]))
        beta = np.mod(np.arctan2(d[:, 2], d[:, 1]), 2.0 * math.pi)
        return np.stack([alpha, beta], axis=1)

    def terminal_errors(self, xf_nd: np.ndarray) -> dict[str, float]:
        """SI terminal errors of a final state (7,): ``position_m`` (distance to the target),
        ``velocity_m_s`` (speed relative to the target's), ``altitude_m`` (above the target)."""
        s = self.scaling
        xf = np.asarray(xf_nd, dtype=float)
        pos = float(np.linalg.norm(xf[:3] - self.target_position_nd) * s.length_m)
        uvw = np.array([float(v) for v in self.uvw(xf)])
        vel = float(np.linalg.norm(uvw - self.target_uvw_nd) * s.velocity_m_s)
        alt = float((np.linalg.norm(xf[:3]) - self.surface_radius_nd) * s.length_m)
        return {"position_m": pos, "velocity_m_s": vel, "altitude_m": alt}

    def path_quantities(self, states_nd: np.ndarray) -> dict[str, float]:
        """``min_altitude_m`` above the target's sphere before the last state (the touchdown
        itself is at 0) and ``final_mass_kg`` of a trajectory (n, 7)."""
        y = np.atleast_2d(np.asarray(states_nd, dtype=float))
        r = np.linalg.norm(y[:-1, :3], axis=1) if len(y) > 1 else np.array([np.inf])
        return {"min_altitude_m": float((r.min() - self.surface_radius_nd)
                                        * self.scaling.length_m),
                "final_mass_kg": float(y[-1, dyn.M3] * self.scaling.mass_kg)}

    def success_from(self, errors, path=None) -> tuple[bool, str]:
        """Terminal conditions within :attr:`tolerances`, never below the surface before
        touchdown (1 mm of rounding allowed), the propellant within the budget."""
        ok, why = super().success_from(errors, path)
        path = path or {}
        if ok and path.get("min_altitude_m", np.inf) < -1e-3:
            return False, (f"the trajectory passes {-path['min_altitude_m']:.3g} m below the "
                           "surface before touchdown")
        if ok and path.get("final_mass_kg", np.inf) < self.mass_min_nd * self.scaling.mass_kg \
                - 1e-6:
            return False, "uses more than the propellant budget"
        return ok, why
