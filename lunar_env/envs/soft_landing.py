"""``LunarSoftLanding-v0``: planar powered descent of a constant-thrust, steer-only lander.

Public helpers other modules rely on: :func:`thrust_angle_from_action`,
:func:`action_from_thrust_angle`, :class:`LunarSoftLandingEnv` (``scenario``, ``state_nd``,
``t_s``, ``observation_from_state``) and :class:`LunarSoftLandingVectorEnv` (the same names).
"""

from __future__ import annotations

import dataclasses
import math

import numba
import numpy as np
from numba.extending import register_jitable

from .. import integrators as integ
from ..scenarios import PlanarScenario, get_scenario
from ..uncertainty import EpisodeErrors, UncertaintyModel
from ..uncertainty.navigation import navigation_error, standard_normals, terminal_normals
from .base import LanderEnv, LanderVectorEnv
from .task import LandingTask, StepSettings, box, float_array

__all__ = ["LunarSoftLandingEnv", "LunarSoftLandingVectorEnv", "PlanarTask",
           "thrust_angle_from_action", "action_from_thrust_angle", "MAX_THRUST_ANGLE_RAD"]

#: |φ| reached at action ±1: the engine can point anywhere from straight down to straight up on
#: the braking side (cos φ >= 0), which contains the fuel-optimal law (0 → 90°, [000]).
MAX_THRUST_ANGLE_RAD = 0.5 * math.pi


@numba.njit(cache=True)
def _controls_kernel(a, throttle_channel, u):  # pragma: no cover  (compiled)
    """(φ rad, throttle) (B, 2) of finite actions a (B, n_act) into ``u``: the arithmetic of
    :func:`thrust_angle_from_action` (clip, then scale), compiled so that one lander costs no
    more than a NumPy call (``u`` allocated by the caller: NumPy allocates faster than numba
    boxes a new array)."""
    for i in range(a.shape[0]):
        u[i, 0] = MAX_THRUST_ANGLE_RAD * min(max(a[i, 0], -1.0), 1.0)
        if throttle_channel:
            u[i, 1] = 0.5 * (min(max(a[i, 1], -1.0), 1.0) + 1.0)
        else:
            u[i, 1] = 1.0


@numba.njit(cache=True)
def _observation_kernel(y, t_s, c, lo, hi, out):  # pragma: no cover  (compiled)
    """Observations (B, 5) float32 of states y (B, 5) at times t_s (B,) into ``out``; ``c``
    packs the constants (see ``PlanarTask._obs_consts``). Compiled for the same reason as the
    pinpoint observation: one lander must not pay a dozen NumPy calls."""
    raw = np.empty(5)
    for i in range(y.shape[0]):
        raw[0] = (y[i, 0] - c[0]) * c[1]
        raw[1] = y[i, 1] * c[2]
        raw[2] = y[i, 0] * y[i, 3] * c[3]
        raw[3] = (y[i, 4] - c[4]) / c[5]
        raw[4] = t_s[i] / c[6]
        for j in range(5):
            out[i, j] = min(max(raw[j], lo[j]), hi[j])


# inlined (numba IR) into its compiled callers: see lunar_env.uncertainty.navigation._shrink
@register_jitable(inline="always")
def _altitude_row(y, i, r_stop_nd, length_ref_m):
    """Altitude (m) above the surface radius of state ``y[i]`` (the one formula of
    :meth:`PlanarTask.altitude_m`, also used by the navigation kernel)."""
    return (y[i, 0] - r_stop_nd) * length_ref_m


@numba.njit(cache=True)
def _altitude_kernel(y, r_stop_nd, length_ref_m, out):  # pragma: no cover  (compiled)
    """Altitude (m) above the surface radius of states y (B, 5) into ``out``."""
    for i in range(y.shape[0]):
        out[i] = _altitude_row(y, i, r_stop_nd, length_ref_m)


# Inlined (numba IR) into its compiled callers, which run with NumPy's error model: no divisor
# here is zero (positive units and radii), and without the zero test the loop has no branch (see
# lunar_env.uncertainty.navigation); the results are the same.
@register_jitable(inline="always")
def _offset_row(y, i, dp_up, dp_down, dv_up, dv_down, dmass, L, V, M, out):
    """:meth:`PlanarTask.offset_states` of lander i (errors in m, m/s, kg) into ``out[i]``: the
    one formula of the offset, for the NumPy-facing kernel and the navigation kernel."""
    r = y[i, 0] + dp_up / L
    v_t = y[i, 0] * y[i, 3] + dv_down / V
    out[i, 0] = r
    out[i, 1] = y[i, 1] + dv_up / V
    out[i, 2] = y[i, 2] + dp_down / L / y[i, 0]
    out[i, 3] = v_t / r
    out[i, 4] = y[i, 4] + dmass / M


@numba.njit(cache=True, error_model="numpy")
def _offset_kernel(y, dpos, dvel, dmass, L, V, M, out):  # pragma: no cover  (compiled)
    """:meth:`PlanarTask.offset_states` in one loop (entry errors, and the reference of the
    navigated state)."""
    for i in range(y.shape[0]):
        _offset_row(y, i, dpos[i, 0], dpos[i, 1], dvel[i, 0], dvel[i, 1], dmass[i], L, V, M,
                    out)


@numba.njit(cache=True, error_model="numpy")
def _navigation_kernel(y, keys, counters, bias_p, bias_v, t_frac, t_floor, t_vel, c, dmass,
                       r_stop_nd, L, V, M, out):  # pragma: no cover  (compiled)
    """:meth:`PlanarTask.navigation_states`: the decision's noise for the whole batch, then
    per lander the true altitude, its navigation errors and the offset state, in one pass (no
    (B, 3) error arrays, no second pass over the states)."""
    z = np.empty((4, y.shape[0]))  # planar: position and velocity noise, up and downrange
    standard_normals(keys, counters, z)
    h = np.empty(y.shape[0])
    for i in range(y.shape[0]):
        h[i] = _altitude_row(y, i, r_stop_nd, L)
    zt = np.empty((6, y.shape[0]))
    terminal_normals(keys, counters, h, c[6], zt)
    for i in range(y.shape[0]):
        e = navigation_error(z, zt, i, h[i], bias_p, bias_v, t_frac, t_floor, t_vel, c, 2)
        _offset_row(y, i, e[0], e[1], e[3], e[4], dmass[i], L, V, M, out)


def thrust_angle_from_action(action) -> np.ndarray:
    """Thrust angle to the local horizontal φ (rad) from the normalised action channel.

    φ = (π/2) · clip(a, −1, 1): a = 0 thrusts horizontally against the motion (pure braking),
    a = 1 straight up, a = −1 straight down. Vectorised; NaN propagates (the envs reject NaN
    actions before calling this).
    """
    return MAX_THRUST_ANGLE_RAD * np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)


def action_from_thrust_angle(phi_rad) -> np.ndarray:
    """Inverse of :func:`thrust_angle_from_action`; angles beyond ±π/2 clip to ±1."""
    return np.clip(np.asarray(phi_rad, dtype=np.float64) / MAX_THRUST_ANGLE_RAD, -1.0, 1.0)


class PlanarTask(LandingTask):
    """The soft-landing task (:class:`~lunar_env.envs.task.LandingTask`; picklable, no compiled
    objects). Arguments: the env's (see the Arguments table of :class:`LunarSoftLandingEnv`)."""

    has_target = False
    stop_name = "the surface"
    n_axes = 2
    model = integ.PLANAR

    def __init__(self, scenario: str | PlanarScenario = "zhu2007", dt_s: float = 1.0,
                 substeps: int = 2, time_limit_s: float | None = None,
                 throttle_channel: bool = False, success_speed_m_s: float = 5.0,
                 max_fall_s: float | None = None, cutoff_speed_m_s: float = 20.0,
                 thrust_n: float | None = None,
                 uncertainty: UncertaintyModel | str | dict | None = None,
                 sensors: tuple[str, ...] | list[str] = ()) -> None:
        sc = get_scenario(scenario) if isinstance(scenario, str) else scenario
        if not isinstance(sc, PlanarScenario):
            raise ValueError(f"scenario {getattr(sc, 'name', sc)!r} is not planar; "
                             "LunarSoftLanding-v0 needs a PlanarScenario (e.g. 'zhu2007')")
        if thrust_n is not None:
            # fly the vehicle's engine at a chosen constant level ([003]: T is a design
            # variable in [0, T_max]); the throttle channel, if any, then scales this level
            t_max = sc.vehicle.thrust_n
            try:
                level = float(thrust_n)
            except (TypeError, ValueError):
                level = math.nan
            if isinstance(thrust_n, bool) or not (math.isfinite(level) and 0 < level <= t_max):
                raise ValueError(f"thrust_n = {thrust_n!r} is not allowed; it must be in "
                                 f"(0, {t_max:g}] N, the vehicle's maximum thrust")
            sc = dataclasses.replace(
                sc, name=f"{sc.name}@{level / 1e3:.4g}kN",
                vehicle=dataclasses.replace(sc.vehicle, thrust_n=level))
        settings = StepSettings.validated(
            dt_s=dt_s, substeps=substeps, time_limit_s=time_limit_s, max_fall_s=max_fall_s,
            throttle_channel=throttle_channel, success_speed_m_s=success_speed_m_s,
            cutoff_speed_m_s=cutoff_speed_m_s, default_time_limit_s=1.5 * sc.tf_bounds_s[1])
        super().__init__(sc, settings, uncertainty, sensors)
        s = self.scaling
        self.r_stop_nd = float(s.length_nd(sc.surface_radius_m))
        self.altitude_scale_m = max(sc.initial.radius_m - sc.surface_radius_m, 1.0)
        self.speed_scale_m_s = max(math.hypot(sc.initial.radial_velocity_m_s,
                                              sc.initial.tangential_velocity_m_s), 1.0)
        n_act = 2 if self.throttle_channel else 1
        self.action_space = box([-1.0] * n_act, [1.0] * n_act)
        self.obs_low = np.array([0.0, -20.0, -2.0, 0.0, 0.0])
        self.obs_high = np.array([20.0, 20.0, 2.0, 1.5, 2.0])
        self.observation_space = box(self.obs_low, self.obs_high)
        v = self.velocity_ref_m_s
        self._obs_consts = np.array([
            self.r_stop_nd, self.length_ref_m / self.altitude_scale_m,
            v / (0.1 * self.speed_scale_m_s), v / self.speed_scale_m_s, self.dry_mass_nd,
            self.prop_nominal_nd, self.time_limit_s])

    # -- mapping --------------------------------------------------------------------------------
    def controls_from_actions(self, a: np.ndarray) -> np.ndarray:
        """(φ rad, throttle) (B, 2) of actions (B, n_act): :func:`thrust_angle_from_action`,
        throttle (a₁ + 1)/2 with a throttle channel, else 1."""
        u = np.empty((len(a), 2))
        _controls_kernel(float_array(a), self.throttle_channel, u)
        return u

    def actions_from_controls(self, u: np.ndarray) -> np.ndarray:
        """Actions (B, n_act) float32 of controls (φ rad, throttle) (B, 2):
        :func:`action_from_thrust_angle`, and 2·throttle − 1 with a throttle channel."""
        u = np.asarray(u, dtype=np.float64)
        act = action_from_thrust_angle(u[:, 0])[:, None]
        if self.throttle_channel:
            act = np.concatenate([act, (2.0 * u[:, 1] - 1.0)[:, None]], axis=1)
        return act.astype(np.float32)

    def observation(self, y: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Observations (B, 5) float32 (see Observation Space in the env's manual)."""
        out = np.empty((len(y), 5), dtype=np.float32)
        _observation_kernel(np.ascontiguousarray(y, dtype=np.float64),
                            np.ascontiguousarray(t_s, dtype=np.float64), self._obs_consts,
                            self.obs_low, self.obs_high, out)
        return out

    def observation_quantities(self, obs: np.ndarray) -> dict[str, np.ndarray]:
        """SI quantities encoded in observations (B, 5): the inverse of :meth:`observation`
        (exact inside the observation bounds). Keys: ``altitude_m``,
        ``radial_velocity_m_s``, ``tangential_velocity_m_s``, ``propellant_kg``, ``time_s``."""
        o = self.observation_rows(obs)
        return {"altitude_m": o[:, 0] * self.altitude_scale_m,
                "radial_velocity_m_s": o[:, 1] * 0.1 * self.speed_scale_m_s,
                "tangential_velocity_m_s": o[:, 2] * self.speed_scale_m_s,
                "propellant_kg": o[:, 3] * self.prop_nominal_nd * self.mass_ref_kg,
                "time_s": o[:, 4] * self.time_limit_s, **self.sensor_quantities(o)}

    def physical_constants(self) -> dict[str, float]:
        """SI constants of the lander and the body that policies may use (derived features):
        ``thrust_n``, ``exhaust_velocity_m_s``, ``dry_mass_kg``, ``gravity_m_s2`` (at the
        surface), ``mass_ref_kg``, ``prop_nominal_kg`` (the propellant a full observation
        fraction means)."""
        v = self.scenario.vehicle
        return {"thrust_n": float(v.thrust_n), "exhaust_velocity_m_s": float(
                    v.exhaust_velocity_m_s),
                "dry_mass_kg": float(self.dry_mass_nd * self.mass_ref_kg),
                # μ = 1 in normalised units: g_surface = (V² / L) / r_surface²
                "gravity_m_s2": float(self.velocity_ref_m_s ** 2 / self.length_ref_m
                                      / self.r_stop_nd ** 2),
                "mass_ref_kg": float(self.mass_ref_kg),
                "prop_nominal_kg": float(self.prop_nominal_nd * self.mass_ref_kg)}

    def speed_m_s(self, y: np.ndarray) -> np.ndarray:
        """Speed relative to the surface (m/s), shape (B,)."""
        return np.sqrt(y[:, 1] ** 2 + (y[:, 0] * y[:, 3]) ** 2) * self.velocity_ref_m_s

    def offset_states(self, y: np.ndarray, dpos_m: np.ndarray, dvel_m_s: np.ndarray,
                      dmass_kg: np.ndarray) -> np.ndarray:
        """(r, vr, θ, ω, m) displaced along up (r), downrange (r·θ) and in mass; the
        tangential velocity r·ω moves by the downrange velocity error. Crossrange is ignored."""
        out = np.empty((len(y), 5))
        _offset_kernel(np.ascontiguousarray(y, dtype=np.float64),
                       np.ascontiguousarray(dpos_m, dtype=np.float64),
                       np.ascontiguousarray(dvel_m_s, dtype=np.float64),
                       np.ascontiguousarray(dmass_kg, dtype=np.float64), self.length_ref_m,
                       self.velocity_ref_m_s, self.mass_ref_kg, out)
        return out

    def navigation_states(self, y: np.ndarray, errors: EpisodeErrors,
                          counters: np.ndarray, mass_belief_kg: np.ndarray) -> np.ndarray:
        """As :meth:`LandingTask.navigation_states` (same arithmetic, bit for bit), in one
        compiled call."""
        out = np.empty((len(y), 5))
        _navigation_kernel(*self._navigation_inputs(y, errors, counters, mass_belief_kg),
                           self.r_stop_nd, self.length_ref_m, self.velocity_ref_m_s,
                           self.mass_ref_kg, out)
        return out

    def radius_nd(self, y: np.ndarray) -> np.ndarray:
        """r (normalised), shape (B,)."""
        return np.asarray(y)[:, 0]

    def altitude_m(self, y: np.ndarray) -> np.ndarray:
        """Altitude above the surface radius (m), shape (B,)."""
        out = np.empty(len(y))
        _altitude_kernel(np.ascontiguousarray(y, dtype=np.float64), self.r_stop_nd,
                         self.length_ref_m, out)
        return out

    def landing_metrics(self, y: np.ndarray, touched_down: np.ndarray):
        """Touchdown speed (m/s); for a lander that did not touch down, the speed it would have
        at the surface radius by energy conservation (engine off). No miss distance."""
        v2 = y[:, 1] ** 2 + (y[:, 0] * y[:, 3]) ** 2
        est = np.sqrt(np.maximum(v2 + 2.0 * (1.0 / self.r_stop_nd - 1.0 / y[:, 0]), 0.0))
        speed = np.where(touched_down, np.sqrt(v2), est) * self.velocity_ref_m_s
        return speed, None

    # -- initial states -------------------------------------------------------------------------
    def initial_state(self, rng: np.random.Generator, options: dict | None) -> np.ndarray:
        """Normalised (r, vr, θ, ω, m) (see Starting State in the env's manual)."""
        sc = self.scenario
        options = options or {}
        given_si = None  # the row as given, for the message, where the user gave SI
        if options.get("state_nd") is not None:
            y = np.asarray(options["state_nd"], dtype=np.float64).reshape(-1)
            source = "options['state_nd'] (r, vr, θ, ω, m)"
        elif options.get("state_si") is not None:
            si = np.asarray(options["state_si"], dtype=np.float64).reshape(-1)
            if si.shape != (5,):
                raise ValueError(f"options['state_si'] has {si.size} numbers; expected 5: "
                                 "(r m, vr m/s, θ rad, v_t m/s, m kg)")
            y = sc.si_to_nd(si, self.scaling)
            source = "options['state_si'] (r m, vr m/s, θ rad, v_t m/s, m kg)"
            given_si = si
        elif options.get("nominal"):
            y = sc.state_nd(scaling=self.scaling)
            source = "the nominal start (r, vr, θ, ω, m)"
        else:
            y = sc.si_to_nd(sc.sample_initial(rng, 1)[0], self.scaling)
            source = "the dispersed start (r, vr, θ, ω, m)"
        return self.check_start(y, source, given_si)

    # -- rendering ------------------------------------------------------------------------------
    def track(self, ys: np.ndarray) -> dict:
        """Downrange (km, along the surface from θ of the first state) and altitude (km)."""
        rs = self.r_stop_nd * self.length_ref_m
        return {"downrange_km": rs * (ys[:, 2] - ys[0, 2]) / 1e3,
                "altitude_km": self.altitude_m(ys) / 1e3}


_DOC = """

    ## Description

    Planar powered descent to the Moon ([000] Zhu & Xu 2007 by default): a lander at the
    periapsis of its descent orbit (15 km, 1.69 km/s for ``zhu2007``) fires a constant-thrust
    engine that can only be steered and must land softly with as little propellant as possible.
    The dynamics are the shared normalised two-body polar model of :mod:`lunar_env.dynamics`,
    integrated by the compiled RK4 of :mod:`lunar_env.integrators` (no other copy of the
    equations). Each step holds the action for ``dt_s`` (default 1 s) over ``substeps``
    (default 2, i.e. 0.5 s RK4 steps) RK4 steps; events are located inside the step. The
    dynamics are smooth on this scale: the fuel-optimal landing replayed with 1, 2, 4 or 16
    substeps touches down within 2e-8 s, 1e-7 m/s and 1e-8 m of each other (measured).

    ## Action Space

    ``Box(-1, 1, (1,), float32)``: the thrust angle to the local horizontal,
    φ = (π/2)·a (:func:`thrust_angle_from_action`): 0 brakes horizontally, +1 points the thrust
    straight up, −1 straight down. With ``throttle_channel=True`` the shape is (2,) and
    throttle = (a₁ + 1)/2 ∈ [0, 1] (variable-thrust vehicles, [003]); by default the engine runs
    at full thrust ([000]: "constant or 0"). Finite out-of-range actions are clipped to [−1, 1];
    NaN or infinite actions raise ``ValueError`` and leave the state untouched.

    ## Observation Space

    ``Box(float32, (5,))``, each quantity scaled and clipped to the bounds shown (h₀, v₀: the
    scenario's nominal initial altitude and speed, 15 km and 1691.6 m/s for ``zhu2007``).

    | Num | Observation                             | Unit (before scaling) | Min  | Max  |
    |-----|-----------------------------------------|-----------------------|------|------|
    | 0   | altitude / h₀                           | m                     | 0    | 20   |
    | 1   | radial velocity / (0.1 v₀)              | m/s                   | -20  | 20   |
    | 2   | horizontal velocity r·ω / v₀            | m/s                   | -2   | 2    |
    | 3   | propellant left / nominal propellant    | kg                    | 0    | 1.5  |
    | 4   | time / time limit                       | s                     | 0    | 2    |

    ## Rewards

    Each step: −(propellant burnt in the step) / (vehicle propellant capacity, 300 kg for
    ``zhu2007``), so the whole fuel term lies in [−1, 0]. At the end of the episode:
    −log(1 + v_td / 1 m/s) with the touchdown speed v_td; a truncated episode is charged with
    the speed it would reach at the surface by energy conservation. The term's slope at
    v_td = 0 is hundreds of times the fuel saved by landing harder, so the fuel-optimal soft
    landing has the best return (tested against crashing, hovering, flying past, landing
    harder and random policies in ``tests/test_env_soft_landing.py``). Measured on the nominal
    ``zhu2007`` case: the fuel-optimal law returns −1.38 (277.59 kg, touchdown at 0.58 m/s);
    cutting off 5 s early −3.89, horizontal braking −7.33, diving −7.63, flying past −7.98,
    hovering −8.88, the best of 100 random policies −7.46.

    ## Starting State

    Drawn from the scenario's dispersion (``scenario.sample_initial(self.np_random, 1)``; for
    ``zhu2007``: altitude ±1 km, horizontal speed ±15 m/s, mass ±20 kg, θ ±0.01 rad).
    ``reset(options={"nominal": True})`` starts from the nominal state,
    ``options={"state_si": (r m, vr m/s, θ rad, v_t m/s, m kg)}`` or
    ``{"state_nd": (r, vr, θ, ω, m)}`` (normalised) from an exact state. Every start, pinned or
    drawn, must be finite, above the surface radius, with a mass above the dry mass and at most
    the full tank (the wet mass plus the dispersion's largest mass offset: 620 kg for
    ``zhu2007``), and bound to the Moon (speed below the escape speed at its radius); any
    other is refused with a ValueError naming the option, the value and the allowed range.

    ## Episode End

    1. Termination: touchdown, the radius crossing the surface radius (located inside the
       step). The engine cuts off when the speed relative to the surface reaches a minimum
       inside a step (located by the integrator's ``SpeedMinimum`` event; ideally the minimum
       is zero) at or below ``cutoff_speed_m_s`` (default 20 m/s: a minimum at a higher speed
       is a steering error, not the terminal phase, and the engine keeps burning; a minimum at
       a step boundary caused by the new action is not a cut-off either), or when the
       propellant is exhausted. The lander then falls freely (throttle 0) and the fall to
       touchdown is integrated in the same step call, so the episode ends in the step in which
       the engine stops. Success: touchdown speed <= ``success_speed_m_s`` (default 5 m/s, a
       free fall from 7.7 m).
    2. Truncation: time >= ``time_limit_s`` (default 1.5 × the scenario's upper final-time
       bound, 1050 s for ``zhu2007``), or a free fall that does not reach the surface within
       ``max_fall_s`` (default the time limit).

    ``info``: ``fuel_used_kg``, ``is_success``, ``altitude_m``, ``time_s``, and after touchdown
    ``touchdown_speed_m_s`` (absent before: infos carry no NaN).

    ## Plant and Navigation Errors

    ``uncertainty="standard"`` (or ``"stress"``, an :class:`~lunar_env.uncertainty.
    UncertaintyModel`, or a dict of its fields) draws, per episode, entry errors of the start
    (up and downrange position and velocity), a thrust scale, an Isp scale, a thrust-angle
    misalignment and a wet-mass error, navigation errors (a bias per episode and white noise per
    decision, then below the terminal sensors' acquisition altitude their own errors, a fraction
    of the altitude), and the IMU's (bias, scale factor, noise): see
    :mod:`lunar_env.uncertainty` for the model and the source of each value. The observation
    then encodes the *navigated* state; integration, reward, termination, success and the usual
    ``info`` keys use the truth, and ``info`` also carries ``state_nd`` (truth) and
    ``navigation_state_nd`` (normalised, (5,)). ``env.unwrapped.episode_errors`` holds the drawn
    errors, and ``reset(options={"errors": {...}})`` pins some of them (e.g. ``{"thrust_scale":
    0.98}``). The errors of an episode reset with seed s come from a stream of their own seeded
    by s, so case k of a campaign is the same for every law. The default ``"none"`` is this env
    exactly as without the model (every seeded episode bit for bit,
    ``benchmarks/record_episodes.py``).

    ## Sensors

    The flight computer's IMU measures the specific force over each decision, the mean thrust
    acceleration along the (misaligned) thrust axis, in (downrange, up) (m/s²), with the
    episode's IMU errors: ``env.unwrapped.sensor_readings()["imu"]`` (0 plus the errors at an
    episode's first decision). ``sensors=("imu",)`` also appends it to the observation, as two
    columns in units of T/m₀ (the nominal thrust acceleration at the wet mass), clipped to ±3;
    ``observation_quantities`` decodes them as ``imu_m_s2``. Observation layout: the five
    columns above, then the sensor columns in the order given.

    ## Arguments

    | Argument            | Default     | Meaning                                              |
    |---------------------|-------------|------------------------------------------------------|
    | ``scenario``        | "zhu2007"   | any planar scenario name or ``PlanarScenario``       |
    | ``dt_s``            | 1.0         | seconds each action is held                          |
    | ``substeps``        | 2           | RK4 steps per env step                               |
    | ``time_limit_s``    | None        | truncation time (None: 1.5 × ``tf_bounds_s[1]``)    |
    | ``throttle_channel``| False       | add a throttle action channel                        |
    | ``success_speed_m_s``| 5.0        | touchdown speed tolerance of ``is_success``          |
    | ``max_fall_s``      | None        | longest free fall integrated (None: time limit)      |
    | ``cutoff_speed_m_s``| 20.0        | speed minima at or below it cut the engine off       |
    | ``thrust_n``        | None        | engine level (N) in (0, T_max]; None: T_max          |
    | ``uncertainty``     | "none"      | plant and navigation errors (see above)              |
    | ``sensors``         | ()          | sensor channels appended to the observation ("imu")  |
    | ``render_mode``     | None        | "rgb_array" or "human"                               |

    >>> import gymnasium as gym
    >>> import lunar_env
    >>> env = gym.make("LunarSoftLanding-v0", scenario="zhu2007", dt_s=1.0)
    >>> obs, info = env.reset(seed=0)
    >>> obs.shape
    (5,)
    >>> env.unwrapped.scenario.name
    'zhu2007'

    ## Version History

    - v0: initial version.
    """


class LunarSoftLandingEnv(LanderEnv):
    __doc__ = "Soft landing of a constant-thrust, steer-only lander (single env)." + _DOC
    _task_cls = PlanarTask


class LunarSoftLandingVectorEnv(LanderVectorEnv):
    __doc__ = ("Native vector version of :class:`LunarSoftLandingEnv`: all N landers step in one "
               "compiled integrator call. Autoreset NEXT_STEP; sub-env i seeded with seed + i.\n"
               + _DOC)
    _task_cls = PlanarTask
