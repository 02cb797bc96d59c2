"""``LunarPinpointLanding-v1``: 3D pinpoint landing on a rotating Moon ([001] Peng et al. 2012).

Public helpers: :func:`angles_from_action`, :func:`action_from_angles`,
:class:`LunarPinpointLandingEnv` and :class:`LunarPinpointLandingVectorEnv` (``scenario``,
``state_nd``, ``t_s``, ``observation_from_state``).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba.extending import register_jitable

from .. import dynamics as dyn
from .. import integrators as integ
from ..scenarios import PinpointScenario, get_scenario
from ..uncertainty import EpisodeErrors, UncertaintyModel
from ..uncertainty.navigation import navigation_error, standard_normals, terminal_normals
from ..validation import require_finite_positive
from .base import LanderEnv, LanderVectorEnv
from .task import LandingTask, StepSettings, box, float_array

__all__ = ["LunarPinpointLandingEnv", "LunarPinpointLandingVectorEnv", "PinpointTask",
           "angles_from_action", "action_from_angles"]

_PENG = get_scenario("peng2012")

# The orbital frame of lunar_env.dynamics, compiled (one definition of the geometry).
_orbital_frame_jit = numba.njit(cache=True, inline="always")(dyn.orbital_frame)


@numba.njit(cache=True)
def _observation_kernel(y, t_s, c, lo, hi, out):  # pragma: no cover  (compiled)
    """Observations (B, 9) float32 of states y (B, 7) at times t_s (B,) into ``out`` (allocated
    by the caller: NumPy allocates faster than numba boxes a new array); ``c`` packs the
    constants (see ``PinpointTask._obs_consts``)."""
    n = y.shape[0]
    raw = np.empty(9)
    for i in range(n):
        x, yy, z = y[i, 0], y[i, 1], y[i, 2]
        vx, vy, vz = y[i, 3], y[i, 4], y[i, 5]
        f = _orbital_frame_jit(x, yy, z, c[0], c[1], c[2])
        dx, dy, dz = c[3] - x, c[4] - yy, c[5] - z
        r = np.sqrt(x * x + yy * yy + z * z)
        raw[0] = (r - c[6]) * c[7]
        raw[1] = (dx * f[0] + dy * f[1] + dz * f[2]) * c[8]
        raw[2] = (dx * f[3] + dy * f[4] + dz * f[5]) * c[8]
        raw[3] = (dx * f[6] + dy * f[7] + dz * f[8]) * c[8]
        raw[4] = (vx * f[0] + vy * f[1] + vz * f[2]) * c[9]
        raw[5] = (vx * f[3] + vy * f[4] + vz * f[5]) * c[10]
        raw[6] = (vx * f[6] + vy * f[7] + vz * f[8]) * c[9]
        raw[7] = (y[i, 6] - c[11]) / c[12]
        raw[8] = t_s[i] / c[13]
        for j in range(9):
            out[i, j] = min(max(raw[j], lo[j]), hi[j])


@numba.njit(cache=True)
def _controls_kernel(a, lo_a, span_a, lo_b, span_b, throttle_channel, u):  # pragma: no cover
    """(α, β rad, throttle) (B, 3) of finite actions a (B, n_act) into ``u``: the arithmetic of
    :func:`angles_from_action` (clip, then the affine map; ``span`` = upper − lower bound),
    compiled so that one lander costs no more than a NumPy call."""
    for i in range(a.shape[0]):
        u[i, 0] = lo_a + 0.5 * (min(max(a[i, 0], -1.0), 1.0) + 1.0) * span_a
        u[i, 1] = lo_b + 0.5 * (min(max(a[i, 1], -1.0), 1.0) + 1.0) * span_b
        if throttle_channel:
            u[i, 2] = 0.5 * (min(max(a[i, 2], -1.0), 1.0) + 1.0)
        else:
            u[i, 2] = 1.0


# inlined (numba IR) into its compiled callers: see lunar_env.uncertainty.navigation._shrink
@register_jitable(inline="always")
def _altitude_row(y, i, radius_nd, length_ref_m):
    """Altitude (m) above the sphere of radius ``radius_nd`` of state ``y[i]`` (the one formula
    of :meth:`PinpointTask.altitude_m`, also used by the navigation kernel)."""
    r = np.sqrt(y[i, 0] * y[i, 0] + y[i, 1] * y[i, 1] + y[i, 2] * y[i, 2])
    return (r - radius_nd) * length_ref_m


@numba.njit(cache=True)
def _altitude_kernel(y, radius_nd, length_ref_m, out):  # pragma: no cover  (compiled)
    """Altitude (m) above the sphere of radius ``radius_nd`` of states y (B, 7) into ``out``,
    compiled for the same reason as the observation."""
    for i in range(y.shape[0]):
        out[i] = _altitude_row(y, i, radius_nd, length_ref_m)


# Inlined (numba IR) into its compiled callers, which run with NumPy's error model: no divisor
# here is zero (positive units), and without the zero test the loop has no branch (see
# lunar_env.uncertainty.navigation); the results are the same.
@register_jitable(inline="always")
def _offset_row(y, i, dp_up, dp_down, dp_cross, dv_up, dv_down, dv_cross, dmass, n_hat, L, V,
                M, out):
    """:meth:`PinpointTask.offset_states` of lander i (errors in m, m/s, kg) into ``out[i]``:
    the one formula of the offset, for the NumPy-facing kernel and the navigation kernel."""
    f = dyn.orbital_frame(y[i, 0], y[i, 1], y[i, 2], n_hat[0], n_hat[1], n_hat[2])
    for j in range(3):
        out[i, j] = y[i, j] + (dp_up * f[j] + dp_down * f[3 + j] + dp_cross * f[6 + j]) / L
        out[i, 3 + j] = y[i, 3 + j] + (dv_up * f[j] + dv_down * f[3 + j]
                                       + dv_cross * f[6 + j]) / V
    out[i, 6] = y[i, 6] + dmass / M


@numba.njit(cache=True, error_model="numpy")
def _offset_kernel(y, dpos, dvel, dmass, n_hat, L, V, M, out):  # pragma: no cover  (compiled)
    """:meth:`PinpointTask.offset_states` in one loop (entry errors, and the reference of the
    navigated state)."""
    for i in range(y.shape[0]):
        _offset_row(y, i, dpos[i, 0], dpos[i, 1], dpos[i, 2], dvel[i, 0], dvel[i, 1],
                    dvel[i, 2], dmass[i], n_hat, L, V, M, out)


@numba.njit(cache=True, error_model="numpy")
def _navigation_kernel(y, keys, counters, bias_p, bias_v, t_frac, t_floor, t_vel, c, dmass,
                       radius_nd, n_hat, L, V, M, out):  # pragma: no cover  (compiled)
    """:meth:`PinpointTask.navigation_states`: the decision's noise for the whole batch, then
    per lander the true altitude, its navigation errors and the offset state, in one pass (no
    (B, 3) error arrays, no second pass over the states)."""
    z = np.empty((6, y.shape[0]))  # position and velocity noise along the three axes
    standard_normals(keys, counters, z)
    h = np.empty(y.shape[0])
    for i in range(y.shape[0]):
        h[i] = _altitude_row(y, i, radius_nd, L)
    zt = np.empty((6, y.shape[0]))
    terminal_normals(keys, counters, h, c[6], zt)
    for i in range(y.shape[0]):
        e = navigation_error(z, zt, i, h[i], bias_p, bias_v, t_frac, t_floor, t_vel, c, 3)
        _offset_row(y, i, e[0], e[1], e[2], e[3], e[4], e[5], dmass[i], n_hat, L, V, M, out)


def angles_from_action(action, alpha_bounds_rad: tuple[float, float] = _PENG.alpha_bounds_rad,
                       beta_bounds_rad: tuple[float, float] = _PENG.beta_bounds_rad
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Thrust elevation α and azimuth β (rad) from actions (..., 2) in [-1, 1].

    Affine: a = −1 → lower bound, a = +1 → upper bound (defaults: [001]'s α ∈ [−50°, 40°],
    β ∈ [130°, 220°]; β = 180° brakes along the track). Out-of-range actions are clipped.
    """
    a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
    lo_a, hi_a = alpha_bounds_rad
    lo_b, hi_b = beta_bounds_rad
    return (lo_a + 0.5 * (a[..., 0] + 1.0) * (hi_a - lo_a),
            lo_b + 0.5 * (a[..., 1] + 1.0) * (hi_b - lo_b))


def action_from_angles(alpha_rad, beta_rad,
                       alpha_bounds_rad: tuple[float, float] = _PENG.alpha_bounds_rad,
                       beta_bounds_rad: tuple[float, float] = _PENG.beta_bounds_rad
                       ) -> np.ndarray:
    """Inverse of :func:`angles_from_action`: actions (..., 2), clipped to [-1, 1]."""
    lo_a, hi_a = alpha_bounds_rad
    lo_b, hi_b = beta_bounds_rad
    a0 = 2.0 * (np.asarray(alpha_rad, dtype=np.float64) - lo_a) / (hi_a - lo_a) - 1.0
    a1 = 2.0 * (np.asarray(beta_rad, dtype=np.float64) - lo_b) / (hi_b - lo_b) - 1.0
    return np.clip(np.stack([a0, a1], axis=-1), -1.0, 1.0)


class PinpointTask(LandingTask):
    """The pinpoint-landing task (:class:`~lunar_env.envs.task.LandingTask`; picklable).
    Arguments: the env's (see the Arguments section of :class:`LunarPinpointLandingEnv`)."""

    has_target = True
    stop_name = "the terminal gate"
    model = integ.MOON3D

    def __init__(self, scenario: str | PinpointScenario = "peng2012", dt_s: float = 1.0,
                 substeps: int = 2, time_limit_s: float | None = None,
                 throttle_channel: bool = False, success_speed_m_s: float = 5.0,
                 success_miss_m: float = 500.0, max_fall_s: float | None = None,
                 cutoff_speed_m_s: float = 20.0, charge_propellant_on_failure: bool = True,
                 gate_range_m: float | None = None,
                 uncertainty: UncertaintyModel | str | dict | None = None,
                 sensors: tuple[str, ...] | list[str] = ()) -> None:
        sc = get_scenario(scenario) if isinstance(scenario, str) else scenario
        if not isinstance(sc, PinpointScenario):
            raise ValueError(f"scenario {getattr(sc, 'name', sc)!r} is not a pinpoint scenario; "
                             "LunarPinpointLanding-v0 needs a PinpointScenario ('peng2012')")
        settings = StepSettings.validated(
            dt_s=dt_s, substeps=substeps, time_limit_s=time_limit_s, max_fall_s=max_fall_s,
            throttle_channel=throttle_channel, success_speed_m_s=success_speed_m_s,
            cutoff_speed_m_s=cutoff_speed_m_s, default_time_limit_s=1.5 * sc.tf_bounds_s[1],
            # a pinpoint landing always has a miss criterion: None is refused, not read as inf
            success_miss_m=require_finite_positive("success_miss_m", success_miss_m))
        super().__init__(sc, settings, uncertainty, sensors)
        s = self.scaling
        #: v1 reward: an episode that ends without success is also charged the propellant left
        #: (see the Rewards section of the manual); False gives v0's reward
        self.charge_propellant_on_failure = bool(charge_propellant_on_failure)
        self.plane_normal = np.asarray(self.params.plane_normal)
        self.surface_radius_nd = 1.0 * float(s.length_nd(sc.body.radius_m))
        # terminal gate: the sphere through the target ([001] ends at hf = 2 km above it)
        self.r_stop_nd = float(s.length_nd(sc.body.radius_m + sc.target.altitude_m))
        self.target_nd = s.length_nd(sc.target_position_m())
        self.altitude_scale_m = max(sc.initial.altitude_m - sc.target.altitude_m, 1.0)
        r0 = s.length_nd(sc.initial_position_velocity_m()[0])
        self.range_scale_m = max(float(np.linalg.norm(self.target_nd - r0)) * s.length_m, 1.0)
        self.speed_scale_m_s = max(math.sqrt(sc.initial.u_m_s ** 2 + sc.initial.v_m_s ** 2
                                             + sc.initial.w_m_s ** 2), 1.0)
        #: v2: the 2 km gate counts only within this great-circle distance of the target (at
        #: the gate radius); elsewhere the lander may fly below 2 km and ends at the surface
        #: (None: the gate sphere ends the episode everywhere, v0/v1)
        if gate_range_m is not None:
            self.gate_range_m = require_finite_positive("gate_range_m", gate_range_m)
            self._gate_cos = math.cos(self.gate_range_m / (self.r_stop_nd * s.length_m))
            self._target_unit = self.target_nd / np.linalg.norm(self.target_nd)
        (lo_a, hi_a), (lo_b, hi_b) = sc.alpha_bounds_rad, sc.beta_bounds_rad
        self._angle_map = (lo_a, hi_a - lo_a, lo_b, hi_b - lo_b)
        n_act = 3 if self.throttle_channel else 2
        self.action_space = box([-1.0] * n_act, [1.0] * n_act)
        # v2 lets the lander fly below the gate away from the target: altitude down to the
        # surface (-2 km / h0) must stay observable
        alt_low = 0.0 if self.gate_range_m is None else \
            -1.05 * sc.target.altitude_m / self.altitude_scale_m
        self.obs_low = np.array([alt_low, -3.0, -3.0, -3.0, -20.0, -2.0, -20.0, 0.0, 0.0])
        self.obs_high = np.array([20.0, 3.0, 3.0, 3.0, 20.0, 2.0, 20.0, 1.5, 2.0])
        self.observation_space = box(self.obs_low, self.obs_high)
        L, V = self.length_ref_m, self.velocity_ref_m_s
        self._obs_consts = np.array([
            *self.plane_normal, *self.target_nd, self.r_stop_nd, L / self.altitude_scale_m,
            L / self.range_scale_m, V / (0.1 * self.speed_scale_m_s), V / self.speed_scale_m_s,
            self.dry_mass_nd, self.prop_nominal_nd, self.time_limit_s])

    # -- mapping --------------------------------------------------------------------------------
    def controls_from_actions(self, a: np.ndarray) -> np.ndarray:
        """(α, β rad, throttle) (B, 3) of actions (B, n_act): :func:`angles_from_action` on the
        scenario's bounds, throttle (a₂ + 1)/2 with a throttle channel, else 1."""
        u = np.empty((len(a), 3))
        _controls_kernel(float_array(a), *self._angle_map,
                         self.throttle_channel, u)
        return u

    def actions_from_controls(self, u: np.ndarray) -> np.ndarray:
        """Actions (B, n_act) float32 of controls (α, β rad, throttle) (B, 3):
        :func:`action_from_angles` on the scenario's bounds, and 2·throttle − 1 with a throttle
        channel."""
        u = np.asarray(u, dtype=np.float64)
        sc = self.scenario
        act = action_from_angles(u[:, 0], u[:, 1], sc.alpha_bounds_rad, sc.beta_bounds_rad)
        if self.throttle_channel:
            act = np.concatenate([act, (2.0 * u[:, 2] - 1.0)[:, None]], axis=1)
        return act.astype(np.float32)

    def observation_quantities(self, obs: np.ndarray) -> dict[str, np.ndarray]:
        """SI quantities encoded in observations (B, 9): the inverse of :meth:`observation`
        (exact inside the observation bounds). Keys: ``altitude_m`` (above the gate),
        ``target_radial_m``, ``target_along_m``, ``target_cross_m`` (target − lander in the
        orbital frame), ``u_m_s``, ``v_m_s``, ``w_m_s`` (velocity in the orbital frame),
        ``propellant_kg``, ``time_s``."""
        o = self.observation_rows(obs)
        v0 = self.speed_scale_m_s
        return {"altitude_m": o[:, 0] * self.altitude_scale_m,
                "target_radial_m": o[:, 1] * self.range_scale_m,
                "target_along_m": o[:, 2] * self.range_scale_m,
                "target_cross_m": o[:, 3] * self.range_scale_m,
                "u_m_s": o[:, 4] * 0.1 * v0, "v_m_s": o[:, 5] * v0, "w_m_s": o[:, 6] * 0.1 * v0,
                "propellant_kg": o[:, 7] * self.prop_nominal_nd * self.mass_ref_kg,
                "time_s": o[:, 8] * self.time_limit_s, **self.sensor_quantities(o)}

    def physical_constants(self) -> dict[str, float]:
        """SI constants policies may use (derived features): ``thrust_n``,
        ``exhaust_velocity_m_s``, ``dry_mass_kg``, ``mass_ref_kg``, ``prop_nominal_kg``,
        ``mu_m3_s2`` (the Moon's gravitational parameter), ``gate_radius_m``."""
        v = self.scenario.vehicle
        L, V = self.length_ref_m, self.velocity_ref_m_s
        return {"thrust_n": float(v.thrust_n),
                "exhaust_velocity_m_s": float(v.exhaust_velocity_m_s),
                "dry_mass_kg": float(self.dry_mass_nd * self.mass_ref_kg),
                "mass_ref_kg": float(self.mass_ref_kg),
                "prop_nominal_kg": float(self.prop_nominal_nd * self.mass_ref_kg),
                "mu_m3_s2": float(V * V * L),  # μ = 1 in normalised units
                "gate_radius_m": float(self.r_stop_nd * L)}

    def in_gate_zone(self, y: np.ndarray) -> np.ndarray:
        """(B,) bool: the lander is within ``gate_range_m`` of the target (great circle at the
        gate radius); all True without a gate range (v0/v1)."""
        if self.gate_range_m is None:
            return np.ones(len(y), dtype=bool)
        pos = y[:, 0:3]
        cos = (pos @ self._target_unit) / np.sqrt(np.sum(pos * pos, axis=1))
        return cos >= self._gate_cos

    def stop_radius(self, y: np.ndarray) -> np.ndarray:
        """Terminal radius of each lander for the coming step: the gate sphere in the target
        zone, the Moon's reference sphere elsewhere (v2)."""
        return np.where(self.in_gate_zone(y), self.r_stop_nd, self.surface_radius_nd)

    def below_gate_in_zone(self, y: np.ndarray) -> np.ndarray:
        """(B,) bool: inside the target zone and under the gate (v2 ends the episode there)."""
        if self.gate_range_m is None:
            return np.zeros(len(y), dtype=bool)
        r = np.sqrt(np.sum(y[:, 0:3] ** 2, axis=1))
        return self.in_gate_zone(y) & (r < self.r_stop_nd * (1.0 - 1e-12))

    def observation(self, y: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Observations (B, 9) float32 (see Observation Space in the env's manual)."""
        out = np.empty((len(y), 9), dtype=np.float32)
        _observation_kernel(np.ascontiguousarray(y, dtype=np.float64),
                            np.ascontiguousarray(t_s, dtype=np.float64), self._obs_consts,
                            self.obs_low, self.obs_high, out)
        return out

    def speed_m_s(self, y: np.ndarray) -> np.ndarray:
        """Speed relative to the rotating Moon (m/s), shape (B,)."""
        return np.sqrt(np.sum(y[:, 3:6] ** 2, axis=1)) * self.velocity_ref_m_s

    def offset_states(self, y: np.ndarray, dpos_m: np.ndarray, dvel_m_s: np.ndarray,
                      dmass_kg: np.ndarray) -> np.ndarray:
        """Moon-fixed states displaced along the orbital frame at each position (up x̂,
        downrange ŷ, crossrange ẑ; :func:`~lunar_env.dynamics.orbital_frame`) and in mass."""
        out = np.empty((len(y), 7))
        _offset_kernel(np.ascontiguousarray(y, dtype=np.float64),
                       np.ascontiguousarray(dpos_m, dtype=np.float64),
                       np.ascontiguousarray(dvel_m_s, dtype=np.float64),
                       np.ascontiguousarray(dmass_kg, dtype=np.float64), self.plane_normal,
                       self.length_ref_m, self.velocity_ref_m_s, self.mass_ref_kg, out)
        return out

    def navigation_states(self, y: np.ndarray, errors: EpisodeErrors,
                          counters: np.ndarray, mass_belief_kg: np.ndarray) -> np.ndarray:
        """As :meth:`LandingTask.navigation_states` (same arithmetic, bit for bit), in one
        compiled call."""
        out = np.empty((len(y), 7))
        _navigation_kernel(*self._navigation_inputs(y, errors, counters, mass_belief_kg),
                           self.surface_radius_nd, self.plane_normal, self.length_ref_m,
                           self.velocity_ref_m_s, self.mass_ref_kg, out)
        return out

    def target_offsets_m(self, y: np.ndarray) -> np.ndarray:
        """Where each state's position, projected radially onto the gate sphere, lies from the
        target (m), shape (B, 2): (downrange, crossrange) along the orbital frame's ŷ and ẑ at
        the target (the landing footprint's axes; their norm is the miss distance to within
        the curvature, < 1 mm at 1 km)."""
        y = np.asarray(y, dtype=np.float64)
        r = np.sqrt(np.sum(y[:, 0:3] ** 2, axis=1))
        d = y[:, 0:3] * (self.r_stop_nd / r)[:, None] - self.target_nd[None, :]
        f = dyn.orbital_frame(*self.target_nd, *self.plane_normal)
        return np.stack([d @ np.array(f[3:6]), d @ np.array(f[6:9])], axis=1) * self.length_ref_m

    def radius_nd(self, y: np.ndarray) -> np.ndarray:
        """|r| (normalised), shape (B,)."""
        y = np.asarray(y)
        return np.sqrt(np.sum(y[:, 0:3] ** 2, axis=1))

    def altitude_m(self, y: np.ndarray) -> np.ndarray:
        """Altitude above the reference sphere R_L (m) (the target is 2 km above it)."""
        out = np.empty(len(y))
        _altitude_kernel(np.ascontiguousarray(y, dtype=np.float64), self.surface_radius_nd,
                         self.length_ref_m, out)
        return out

    def landing_metrics(self, y: np.ndarray, touched_down: np.ndarray):
        """Speed at the gate (m/s) and miss distance (m): distance from the target to the
        lander's position projected radially onto the gate sphere. A lander that did not reach
        the gate is charged with its energy-conservation speed at the gate radius."""
        pos = y[:, 0:3]
        r = np.sqrt(np.sum(pos * pos, axis=1))
        v2 = np.sum(y[:, 3:6] ** 2, axis=1)
        est = np.sqrt(np.maximum(v2 + 2.0 * (1.0 / self.r_stop_nd - 1.0 / r), 0.0))
        speed = np.where(touched_down, np.sqrt(v2), est) * self.velocity_ref_m_s
        on_gate = pos * (self.r_stop_nd / r)[:, None]
        miss = np.sqrt(np.sum((on_gate - self.target_nd[None, :]) ** 2, axis=1)) \
            * self.length_ref_m
        return speed, miss

    # -- initial states -------------------------------------------------------------------------
    def initial_state(self, rng: np.random.Generator, options: dict | None) -> np.ndarray:
        """Normalised (x, y, z, vx, vy, vz, m) (see Starting State in the env's manual)."""
        sc = self.scenario
        s = self.scaling
        options = options or {}
        given_si = None  # the row as given, for the message, where the user gave SI
        if options.get("state_nd") is not None:
            y = np.asarray(options["state_nd"], dtype=np.float64).reshape(-1)
            source = "options['state_nd'] (x, y, z, vx, vy, vz, m)"
        elif options.get("state_si") is not None:
            si = np.asarray(options["state_si"], dtype=np.float64).reshape(-1)
            if si.shape != (7,):
                raise ValueError(f"options['state_si'] has {si.size} numbers; expected 7: "
                                 "(x, y, z m, vx, vy, vz m/s, m kg)")
            y = np.concatenate([s.length_nd(si[0:3]), s.velocity_nd(si[3:6]),
                                [s.mass_nd(si[6])]])
            source = "options['state_si'] (x, y, z m, vx, vy, vz m/s, m kg)"
            given_si = si
        elif options.get("nominal"):
            y = sc.state_nd(scaling=s)
            source = "the nominal start (x, y, z, vx, vy, vz, m)"
        else:
            y = sc.state_nd(sc.sample_initial(rng, 1)[0], scaling=s)
            source = "the dispersed start (x, y, z, vx, vy, vz, m)"
        return self.check_start(y, source, given_si)

    # -- rendering ------------------------------------------------------------------------------
    def track(self, ys: np.ndarray) -> dict:
        """Ground track (longitude, latitude in degrees), altitude (km), downrange (km, great
        circle from the first state), target (deg, and its downrange)."""
        t = self.scenario.target
        r = np.sqrt(np.sum(ys[:, 0:3] ** 2, axis=1))
        up = ys[:, 0:3] / r[:, None]
        rl_km = self.surface_radius_nd * self.length_ref_m / 1e3
        tgt = self.target_nd / np.linalg.norm(self.target_nd)
        return {"downrange_km": rl_km * np.arccos(np.clip(up @ up[0], -1.0, 1.0)),
                "target_downrange_km": rl_km * float(np.arccos(np.clip(tgt @ up[0], -1, 1))),
                "longitude_deg": np.degrees(np.arctan2(ys[:, 1], ys[:, 0])),
                "latitude_deg": np.degrees(np.arcsin(ys[:, 2] / r)),
                "altitude_km": self.altitude_m(ys) / 1e3,
                "target_deg": (math.degrees(t.longitude_rad), math.degrees(t.latitude_rad)),
                "target_altitude_km": t.altitude_m / 1e3}


_DOC = """

    ## Description

    Pinpoint powered descent on a rotating Moon ([001] Peng et al. 2012): from 15 km altitude at
    (10°E, 0°N), 1713.8 m/s along a plane inclined 30°, a constant-thrust (1500 N), steer-only
    lander must reach the point 2 km above (25°E, 9°N) at rest, with as little propellant as
    possible. Dynamics: the shared Moon-fixed Cartesian model
    (:func:`lunar_env.dynamics.moon3d_eom`,
    central gravity, Coriolis and centrifugal terms) integrated by the compiled RK4 of
    :mod:`lunar_env.integrators`; each step holds the action for ``dt_s`` (default 1 s) over
    ``substeps`` (default 2) RK4 steps.

    ## Action Space

    ``Box(-1, 1, (2,), float32)``: thrust elevation α above the local horizontal and azimuth β
    of its horizontal projection from the along-track axis (β = 180° brakes), each mapped
    affinely onto the scenario's bounds (α ∈ [−50°, 40°], β ∈ [130°, 220°] for ``peng2012``;
    :func:`angles_from_action`). ``throttle_channel=True`` adds a third channel,
    throttle = (a₂ + 1)/2. Finite out-of-range actions are clipped; NaN/inf raise ``ValueError``
    and leave the state untouched.

    ## Observation Space

    ``Box(float32, (9,))``; vectors are expressed in the lander's orbital frame (radial x̂,
    along-track ŷ, cross-track ẑ). h₀ = initial altitude above the gate (13 km), d₀ = initial
    distance to the target, v₀ = initial speed (1713.8 m/s). Values are clipped to the bounds.

    | Num | Observation                                   | Unit (before scaling) | Min | Max |
    |-----|-----------------------------------------------|-----------------------|-----|-----|
    | 0   | altitude above the target gate / h₀           | m                     | 0   | 20  |
    | 1   | target − lander position, radial / d₀         | m                     | -3  | 3   |
    | 2   | target − lander position, along-track / d₀    | m                     | -3  | 3   |
    | 3   | target − lander position, cross-track / d₀    | m                     | -3  | 3   |
    | 4   | velocity rel. to the target u (radial)/(0.1 v₀)| m/s                  | -20 | 20  |
    | 5   | velocity v (along-track) / v₀                 | m/s                   | -2  | 2   |
    | 6   | velocity w (cross-track) / (0.1 v₀)           | m/s                   | -20 | 20  |
    | 7   | propellant left / nominal propellant          | kg                    | 0   | 1.5 |
    | 8   | time / time limit                             | s                     | 0   | 2   |

    (The target is fixed on the Moon, so the target-relative velocity is the velocity relative
    to the rotating Moon.)

    ## Rewards

    Each step −(propellant burnt)/(propellant capacity, 300 kg). At the end
    −log(1 + v/1 m/s) − log(1 + miss/100 m), with v the speed at the terminal gate and miss
    the distance from the target to the gate crossing (for a truncated episode: the
    energy-conservation speed at the gate radius and the distance of the lander's radial
    projection onto the gate sphere). v1: an episode that ends *without success* is also
    charged the propellant left, −(propellant left)/(capacity): a failed landing loses the
    vehicle and its propellant with it.

    Why: the engine burns at constant thrust, so the fuel term is just −time, and
    under v0 a lander that ends its episode early by diving to the gate (α at its lower bound,
    the gate in ~110 s at ~1.5 km/s, 345 km from the target) *saved* 0.75 of return in fuel
    over any failure that kept flying, about as much as the whole spread of the saturating
    logarithmic terms between failures (v0 on the nominal start: diving −15.7, braking along
    the track −14.7, climbing −14.7, random policies −15.0): PPO settled there. With the
    charge, no failure can be cheaper in fuel than the full tank, and a success is unchanged,
    so the fuel-optimal landing keeps the best return and diving becomes the worst strategy
    (ranking in ``tests/test_env_pinpoint.py``). ``charge_propellant_on_failure=False`` gives
    v0's reward.

    ## Starting State

    The scenario's dispersion (altitude ±500 m, speed ±5 m/s, mass ±10 kg, longitude and
    latitude ±0.05°). ``options={"nominal": True}``, ``{"state_nd": 7 normalised numbers}`` or
    ``{"state_si": (x, y, z m, vx, vy, vz m/s, m kg)}`` (Moon-fixed) pin the start. Every
    start, pinned or drawn, must be finite, above the terminal gate's radius, with a mass above
    the dry mass and at most the full tank (the wet mass plus the dispersion's largest mass
    offset), and bound to the Moon (speed relative to the surface below the escape speed at its
    radius); any other is refused with a ValueError naming the option, the value and the
    allowed range.

    ## Episode End

    [001] ends at hf = 2 km above the target with zero relative velocity. Here the terminal
    condition is physical: the *terminal gate* is the sphere of radius R_L + 2 km through the
    target. The engine cuts off at a speed minimum at or below ``cutoff_speed_m_s`` (default
    20 m/s) or at propellant exhaustion; the lander then falls freely to the gate (integrated
    in the same step).

    1. Termination: crossing the gate (located inside the step). Success: speed at the gate
       <= ``success_speed_m_s`` (5 m/s) and miss distance <= ``success_miss_m`` (500 m).
    2. Truncation: time >= ``time_limit_s`` (default 1200 s = 1.5 × 800 s) or a free fall that
       does not reach the gate within ``max_fall_s``.

    v2 (``gate_range_m=10000``): the gate counts only within 10 km (great circle at the gate
    radius) of the target. Elsewhere the lander may fly below 2 km and the terminal surface is
    the Moon's reference sphere (a crash, scored like a gate crossing: speed there and the miss
    of its radial projection); a lander that enters the target zone under the gate ends there.
    Why: [001]'s optimum cruises the last ~250 s only 300-500 m above the 2 km
    sphere at up to 1 km/s, so under v0/v1 an error of a few hundred metres of altitude
    anywhere on the way ends the episode as a 1 km/s crash, while [001]'s problem (and a real
    descent) only ends at the gate above the target. The optimum, the observations and the
    rewards are v1's; the altitude observation may go negative (down to -2 km / h₀).

    [001]'s path constraint |u|, |w| <= 110 m/s is an optimiser constraint, not enforced here;
    its propellant bound (300 kg) is the vehicle's: the burn ends at the dry mass.

    ``info``: ``fuel_used_kg``, ``is_success``, ``altitude_m`` (above R_L), ``time_s``; after
    the gate crossing ``touchdown_speed_m_s`` (speed at the gate) and, at the end of the episode,
    ``miss_distance_m``.

    ## Plant and Navigation Errors

    As ``LunarSoftLanding-v0``'s (``uncertainty="standard"``, ...; :mod:`lunar_env.uncertainty`),
    in three axes: position and velocity errors along the local up, downrange (the orbital
    frame's ŷ) and crossrange (ẑ) axes, and a misalignment bias on each of α and β. ``info``
    carries ``state_nd`` and ``navigation_state_nd`` ((7,), normalised) under a model; the
    default ``"none"`` is the env exactly as without it.

    ## Sensors

    As ``LunarSoftLanding-v0``'s: the IMU's specific force in (along-track, cross-track, up)
    (m/s²), ``env.unwrapped.sensor_readings()["imu"]``; ``sensors=("imu",)`` appends it to the
    observation as three columns in units of T/m₀, clipped to ±3 (observation layout: the nine
    columns above, then the sensor columns).

    ## Arguments

    As ``LunarSoftLanding-v0`` (``scenario`` default "peng2012", ``dt_s``, ``substeps``,
    ``time_limit_s``, ``throttle_channel``, ``success_speed_m_s``, ``max_fall_s``,
    ``cutoff_speed_m_s``, ``uncertainty``, ``sensors``, ``render_mode``) plus
    ``success_miss_m`` (500.0),
    ``charge_propellant_on_failure`` (v1/v2 True, v0 False) and ``gate_range_m`` (v2 10000.0;
    None: the gate sphere everywhere).

    >>> import gymnasium as gym
    >>> import lunar_env
    >>> env = gym.make("LunarPinpointLanding-v1")
    >>> obs, info = env.reset(seed=0)
    >>> obs.shape
    (9,)

    ## Version History

    - v2: the gate ends an episode only within 10 km of the target (``gate_range_m``; see
      Episode End); otherwise v1.
    - v1: an episode that ends without success is charged the propellant left (the
      dynamics, observations, actions and termination are v0's).
    - v0: initial version (``gym.make("LunarPinpointLanding-v0")`` still gives it:
      ``charge_propellant_on_failure=False``).
    """


class LunarPinpointLandingEnv(LanderEnv):
    __doc__ = "Pinpoint landing on a rotating Moon (single env)." + _DOC
    _task_cls = PinpointTask


class LunarPinpointLandingVectorEnv(LanderVectorEnv):
    __doc__ = ("Native vector version of :class:`LunarPinpointLandingEnv` (one compiled call "
               "per step, autoreset NEXT_STEP, sub-env i seeded with seed + i).\n" + _DOC)
    _task_cls = PinpointTask
