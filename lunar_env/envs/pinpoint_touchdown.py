"""``LunarPinpointLanding-v3``: pinpoint landing to touchdown with a throttleable engine.

[001]'s start (15 km, 1713.8 m/s) continued through approach and terminal descent to touchdown
on the target (25°E, 9°N) on the Moon's reference sphere; the engine throttles between the
scenario's ``throttle_min`` and full thrust (``peng2012_touchdown``).

Public: :class:`LunarPinpointTouchdownEnv`, :class:`LunarPinpointTouchdownVectorEnv`,
:class:`TouchdownTask`, :func:`throttle_from_action`, :func:`action_from_throttle`,
:data:`OBSERVATION_NAMES`.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba.extending import register_jitable

from .. import dynamics as dyn
from ..scenarios import TouchdownScenario, get_scenario
from ..uncertainty import UncertaintyModel
from ..validation import require_finite_positive
from .base import LanderEnv, LanderVectorEnv
from .pinpoint_landing import PinpointTask, action_from_angles
from .task import box, float_array

__all__ = ["LunarPinpointTouchdownEnv", "LunarPinpointTouchdownVectorEnv", "TouchdownTask",
           "throttle_from_action", "action_from_throttle", "OBSERVATION_NAMES",
           "OBSERVATION_LAYOUT_VERSION", "POSITION_SCALE_M", "VELOCITY_SCALE_M_S",
           "SUCCESS_MISS_M", "SUCCESS_VERTICAL_SPEED_M_S", "SUCCESS_HORIZONTAL_SPEED_M_S"]

#: Pinpoint radius of a success (m): SLIM's landing-accuracy requirement, 100 m (JAXA's Smart
#: Lander for Investigating Moon, flown in January 2024).
SUCCESS_MISS_M = 100.0
#: Largest vertical touchdown speed of a success (m/s): the Apollo LM landing gear's design
#: sink rate, 10 ft/s (Rogers, "Apollo Experience Report: Lunar Module Landing Gear
#: Subsystem", NASA TN D-6850, 1972).
SUCCESS_VERTICAL_SPEED_M_S = 3.0
#: Largest horizontal touchdown speed of a success (m/s): the same gear's lateral limit, 4 ft/s
#: (NASA TN D-6850).
SUCCESS_HORIZONTAL_SPEED_M_S = 1.2

#: The observation's channels, in order (layout version :data:`OBSERVATION_LAYOUT_VERSION`).
OBSERVATION_NAMES = ("along_m", "cross_m", "altitude_m", "v_along_m_s", "v_cross_m_s",
                     "v_up_m_s", "propellant_fraction", "time_fraction")
#: Version of the observation layout; a change of channels or scales bumps it with the env id.
OBSERVATION_LAYOUT_VERSION = 1
#: Scales of the logarithmic position and velocity channels (see the manual): the channel is
#: sign(x)·log(1 + |x|/scale), so 1 m (1 m/s) near touchdown and 534 km (1.7 km/s) at the start
#: are both resolved (0.095 and 10.9; 0.69 and 7.4).
POSITION_SCALE_M = 10.0
VELOCITY_SCALE_M_S = 1.0

_TD = get_scenario("peng2012_touchdown")
# the orbital frame of lunar_env.dynamics, compiled (one definition of the geometry)
_frame_jit = numba.njit(cache=True, inline="always")(dyn.orbital_frame)

# bounds of the channels: positions up to 1600 km, velocities up to 2980 m/s (beyond the
# escape speed at the surface, 2.38 km/s), propellant fraction and time fraction as v1's
_OBS_LOW = np.array([-12.0, -12.0, -12.0, -8.0, -8.0, -8.0, 0.0, 0.0])
_OBS_HIGH = np.array([12.0, 12.0, 12.0, 8.0, 8.0, 8.0, 1.5, 2.0])


@register_jitable(inline="always")
def _slog(x, inv_scale):
    """sign(x)·log(1 + |x|/scale), as log of 1 + |x|/scale: libm's log1p costs 2.4 times its
    log here, and the difference (below 1e-16 absolute) is far under the float32 channel's
    resolution."""
    return math.copysign(math.log(1.0 + abs(x) * inv_scale), x)


@numba.njit(cache=True, error_model="numpy")
def _observation_kernel(y, t_s, c, lo, hi, out):  # pragma: no cover  (compiled)
    """Observations (B, 8) float32 of states y (B, 7) at times t_s (B,) into ``out``; ``c``
    packs the constants (see ``TouchdownTask._obs_consts``)."""
    nx, ny, nz = c[0], c[1], c[2]
    tx, ty, tz = c[3], c[4], c[5]
    L, V = c[7], c[8]
    inv_p, inv_v = 1.0 / c[9], 1.0 / c[10]
    for i in range(y.shape[0]):
        x, yy, z = y[i, 0], y[i, 1], y[i, 2]
        ux, uy, uz, ax, ay, az, cx, cy, cz = _frame_jit(x, yy, z, nx, ny, nz)
        r = math.sqrt(x * x + yy * yy + z * z)
        # the site seen along the surface from the lander (the guidance frame's definition,
        # guidance.frames.pinpoint_frame): great-circle arc at the lander's radius toward it
        cos_psi = ux * tx + uy * ty + uz * tz
        hx, hy, hz = tx - cos_psi * ux, ty - cos_psi * uy, tz - cos_psi * uz
        sin_psi = math.sqrt(hx * hx + hy * hy + hz * hz)
        arc = r * math.atan2(sin_psi, cos_psi) / max(sin_psi, 1e-15) * L
        vx, vy, vz = y[i, 3], y[i, 4], y[i, 5]
        q0 = _slog(-arc * (hx * ax + hy * ay + hz * az), inv_p)
        q1 = _slog(-arc * (hx * cx + hy * cy + hz * cz), inv_p)
        q2 = _slog((r - c[6]) * L, inv_p)
        q3 = _slog((vx * ax + vy * ay + vz * az) * V, inv_v)
        q4 = _slog((vx * cx + vy * cy + vz * cz) * V, inv_v)
        q5 = _slog((vx * ux + vy * uy + vz * uz) * V, inv_v)
        out[i, 0] = min(max(q0, lo[0]), hi[0])
        out[i, 1] = min(max(q1, lo[1]), hi[1])
        out[i, 2] = min(max(q2, lo[2]), hi[2])
        out[i, 3] = min(max(q3, lo[3]), hi[3])
        out[i, 4] = min(max(q4, lo[4]), hi[4])
        out[i, 5] = min(max(q5, lo[5]), hi[5])
        out[i, 6] = min(max((y[i, 6] - c[11]) / c[12], lo[6]), hi[6])
        out[i, 7] = min(max(t_s[i] / c[13], lo[7]), hi[7])


@numba.njit(cache=True)
def _controls_kernel(a, lo_a, span_a, lo_b, span_b, thr_min, u):  # pragma: no cover
    """(α, β rad, throttle) (B, 3) of finite actions a (B, 3) into ``u``: each channel clipped
    to [-1, 1], then the affine maps of :func:`~lunar_env.envs.pinpoint_landing.
    angles_from_action` and :func:`throttle_from_action`."""
    for i in range(a.shape[0]):
        u[i, 0] = lo_a + 0.5 * (min(max(a[i, 0], -1.0), 1.0) + 1.0) * span_a
        u[i, 1] = lo_b + 0.5 * (min(max(a[i, 1], -1.0), 1.0) + 1.0) * span_b
        u[i, 2] = thr_min + 0.5 * (min(max(a[i, 2], -1.0), 1.0) + 1.0) * (1.0 - thr_min)


def throttle_from_action(a, throttle_min: float = _TD.throttle_min) -> np.ndarray:
    """Throttle (fraction of full thrust) of throttle-channel actions ``a`` (any shape):
    affine, a = −1 → ``throttle_min``, a = +1 → 1; out-of-range actions are clipped."""
    a = np.clip(np.asarray(a, dtype=np.float64), -1.0, 1.0)
    return throttle_min + 0.5 * (a + 1.0) * (1.0 - throttle_min)


def action_from_throttle(throttle, throttle_min: float = _TD.throttle_min) -> np.ndarray:
    """Inverse of :func:`throttle_from_action`: actions, clipped to [-1, 1] (a throttle below
    ``throttle_min`` maps to −1: the engine cannot go lower)."""
    t = np.asarray(throttle, dtype=np.float64)
    return np.clip(2.0 * (t - throttle_min) / (1.0 - throttle_min) - 1.0, -1.0, 1.0)


def _slog_inverse(o: np.ndarray, scale: float) -> np.ndarray:
    """Inverse of the channels' sign(x)·log(1 + |x|/scale)."""
    return np.sign(o) * scale * np.expm1(np.abs(o))


class TouchdownTask(PinpointTask):
    """The touchdown task (:class:`~lunar_env.envs.task.LandingTask`; picklable). Arguments:
    the env's (see the Arguments section of :class:`LunarPinpointTouchdownEnv`).

    A :class:`~lunar_env.envs.pinpoint_landing.PinpointTask` (geometry, navigation, IMU, start
    states) whose terminal surface is the sphere through the target, whose engine throttles
    and never cuts off at a speed minimum, with its own observation, verdict and terminal term.

    Raises
    ------
    ValueError
        A scenario that is no :class:`~lunar_env.scenarios.TouchdownScenario`, a success limit
        that is not finite and > 0 (named), ``throttle_channel=False``, or any shared setting
        out of its range (:class:`~lunar_env.envs.task.StepSettings`).
    """

    stop_name = "the landing surface"
    extra_info_keys = ("touchdown_vertical_speed_m_s", "touchdown_horizontal_speed_m_s")

    def __init__(self, scenario: str | TouchdownScenario = "peng2012_touchdown",
                 dt_s: float = 1.0, substeps: int = 2, time_limit_s: float | None = None,
                 throttle_channel: bool = True, success_miss_m: float = SUCCESS_MISS_M,
                 success_vertical_speed_m_s: float = SUCCESS_VERTICAL_SPEED_M_S,
                 success_horizontal_speed_m_s: float = SUCCESS_HORIZONTAL_SPEED_M_S,
                 max_fall_s: float | None = None,
                 uncertainty: UncertaintyModel | str | dict | None = None,
                 sensors: tuple[str, ...] | list[str] = ()) -> None:
        sc = get_scenario(scenario) if isinstance(scenario, str) else scenario
        if not isinstance(sc, TouchdownScenario):
            raise ValueError(f"scenario {getattr(sc, 'name', sc)!r} is not a touchdown scenario; "
                             "LunarPinpointLanding-v3 needs a TouchdownScenario "
                             "('peng2012_touchdown')")
        if throttle_channel is not True:
            raise ValueError(f"throttle_channel = {throttle_channel!r} is not allowed; "
                             "LunarPinpointLanding-v3's engine throttles, so its action always "
                             "has the throttle channel (True)")
        v_lim = require_finite_positive("success_vertical_speed_m_s", success_vertical_speed_m_s)
        h_lim = require_finite_positive("success_horizontal_speed_m_s",
                                        success_horizontal_speed_m_s)
        miss = require_finite_positive("success_miss_m", success_miss_m)
        # the shared settings' speed limit is the largest touchdown speed a success can have
        super().__init__(sc, dt_s=dt_s, substeps=substeps, time_limit_s=time_limit_s,
                         throttle_channel=True, success_speed_m_s=math.hypot(v_lim, h_lim),
                         success_miss_m=miss, max_fall_s=max_fall_s, cutoff_speed_m_s=None,
                         charge_propellant_on_failure=True, gate_range_m=None,
                         uncertainty=uncertainty, sensors=sensors)
        self.success_vertical_speed_m_s = v_lim
        self.success_horizontal_speed_m_s = h_lim
        self.throttle_min = float(sc.throttle_min)
        self.action_space = box([-1.0] * 3, [1.0] * 3)
        self.obs_low = _OBS_LOW.copy()
        self.obs_high = _OBS_HIGH.copy()
        self.observation_space = box(self.obs_low, self.obs_high)
        tu = self.target_nd / np.linalg.norm(self.target_nd)
        self._obs_consts = np.array([
            *self.plane_normal, *tu, self.r_stop_nd, self.length_ref_m, self.velocity_ref_m_s,
            POSITION_SCALE_M, VELOCITY_SCALE_M_S, self.dry_mass_nd, self.prop_nominal_nd,
            self.time_limit_s])

    # -- mapping --------------------------------------------------------------------------------
    def controls_from_actions(self, a: np.ndarray) -> np.ndarray:
        """(α, β rad, throttle) (B, 3) of actions (B, 3): the angles on the scenario's bounds
        (:func:`~lunar_env.envs.pinpoint_landing.angles_from_action`), the throttle by
        :func:`throttle_from_action`."""
        u = np.empty((len(a), 3))
        _controls_kernel(float_array(a), *self._angle_map, self.throttle_min, u)
        return u

    def actions_from_controls(self, u: np.ndarray) -> np.ndarray:
        """Actions (B, 3) float32 of controls (α, β rad, throttle) (B, 3): the inverse maps,
        clipped to the action bounds."""
        u = np.asarray(u, dtype=np.float64)
        sc = self.scenario
        act = action_from_angles(u[:, 0], u[:, 1], sc.alpha_bounds_rad, sc.beta_bounds_rad)
        thr = action_from_throttle(u[:, 2], self.throttle_min)
        return np.concatenate([act, thr[:, None]], axis=1).astype(np.float32)

    # -- observations ---------------------------------------------------------------------------
    def observation(self, y: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Observations (B, 8) float32 (see Observation Space in the env's manual)."""
        out = np.empty((len(y), 8), dtype=np.float32)
        _observation_kernel(np.ascontiguousarray(y, dtype=np.float64),
                            np.ascontiguousarray(t_s, dtype=np.float64), self._obs_consts,
                            self.obs_low, self.obs_high, out)
        return out

    def observation_quantities(self, obs: np.ndarray) -> dict[str, np.ndarray]:
        """SI quantities encoded in observations (B, n_obs): the inverse of :meth:`observation`
        (exact inside its bounds, to float32 rounding). Keys: :data:`OBSERVATION_NAMES` with
        ``propellant_kg`` and ``time_s`` for the last two (and the sensor channels')."""
        o = self.observation_rows(obs)
        out = {n: _slog_inverse(o[:, j], POSITION_SCALE_M)
               for j, n in enumerate(OBSERVATION_NAMES[:3])}
        out.update({n: _slog_inverse(o[:, 3 + j], VELOCITY_SCALE_M_S)
                    for j, n in enumerate(OBSERVATION_NAMES[3:6])})
        out["propellant_kg"] = o[:, 6] * self.prop_nominal_nd * self.mass_ref_kg
        out["time_s"] = o[:, 7] * self.time_limit_s
        out.update(self.sensor_quantities(o))
        return out

    def physical_constants(self) -> dict[str, float]:
        """SI constants policies may use: the pinpoint task's (``gate_radius_m`` is the landing
        surface's radius here) and ``surface_radius_m``, ``thrust_min_n``, ``throttle_min``."""
        out = super().physical_constants()
        out["surface_radius_m"] = float(self.r_stop_nd * self.length_ref_m)
        out["throttle_min"] = self.throttle_min
        out["thrust_min_n"] = float(self.throttle_min * self.scenario.vehicle.thrust_n)
        return out

    # -- verdict --------------------------------------------------------------------------------
    def _speed_split(self, y: np.ndarray, touched_down: np.ndarray | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
        """Vertical (downward, m/s) and horizontal (m/s) speed of states (B, 7) at touchdown;
        for a lander that did not touch down (``touched_down`` False) the vertical speed it
        would reach at the surface falling freely (energy conservation), and its horizontal
        speed now."""
        pos = y[:, 0:3]
        r = np.sqrt(np.sum(pos * pos, axis=1))
        u = np.sum(pos * y[:, 3:6], axis=1) / r
        v2 = np.sum(y[:, 3:6] ** 2, axis=1)
        horizontal = np.sqrt(np.maximum(v2 - u * u, 0.0))
        vertical = np.abs(u)
        if touched_down is not None and not touched_down.all():
            fall = np.sqrt(np.maximum(u * u + 2.0 * (1.0 / self.r_stop_nd - 1.0 / r), 0.0))
            vertical = np.where(touched_down, vertical, fall)
        V = self.velocity_ref_m_s
        return vertical * V, horizontal * V

    def terminal_penalty(self, y: np.ndarray, speed_m_s: np.ndarray, miss_m: np.ndarray,
                         touched_down: np.ndarray) -> np.ndarray:
        """log(1 + v_vertical / 1 m/s) + log(1 + v_horizontal / 1 m/s) + log(1 + miss / 100 m)
        (see Rewards in the env's manual)."""
        vert, horiz = self._speed_split(y, touched_down)
        return np.log1p(vert) + np.log1p(horiz) + np.log1p(miss_m / 100.0)

    def landed_within_limits(self, y: np.ndarray, speed_m_s: np.ndarray,
                             miss_m: np.ndarray) -> np.ndarray:
        """Vertical speed <= ``success_vertical_speed_m_s``, horizontal speed <=
        ``success_horizontal_speed_m_s`` and miss <= ``success_miss_m``."""
        vert, horiz = self._speed_split(y)
        return ((vert <= self.success_vertical_speed_m_s)
                & (horiz <= self.success_horizontal_speed_m_s) & (miss_m <= self.success_miss_m))

    def touchdown_info(self, y: np.ndarray) -> dict[str, np.ndarray]:
        """``touchdown_vertical_speed_m_s`` (downward) and ``touchdown_horizontal_speed_m_s``
        of landers at touchdown states (B, 7)."""
        vert, horiz = self._speed_split(y)
        return {"touchdown_vertical_speed_m_s": vert, "touchdown_horizontal_speed_m_s": horiz}

    def success_thresholds(self) -> dict[str, float]:
        """``speed_m_s`` (the largest touchdown speed a success can have, the hypotenuse of the
        two limits), ``miss_m``, ``vertical_speed_m_s`` and ``horizontal_speed_m_s``."""
        return {**super().success_thresholds(),
                "vertical_speed_m_s": float(self.success_vertical_speed_m_s),
                "horizontal_speed_m_s": float(self.success_horizontal_speed_m_s)}

    # -- rendering ------------------------------------------------------------------------------
    def track(self, ys: np.ndarray) -> dict:
        """The pinpoint task's track (ground track, altitude, downrange, target) with the speed
        relative to the surface (m/s) and the decision interval ``dt_s`` (s) for the speed
        profile; the reference line of the altitude panel is the landing surface."""
        out = super().track(ys)
        out["speed_m_s"] = self.speed_m_s(ys)
        out["dt_s"] = self.dt_s
        out["target_altitude_label"] = "surface"
        return out


_DOC = """

    ## Description

    Pinpoint landing to touchdown on a rotating Moon: [001]'s start (15 km altitude at (10°E,
    0°N), 1713.8 m/s along a plane inclined 30°, 600 kg) continued through braking, approach and
    terminal descent to touchdown on the target (25°E, 9°N) on the Moon's reference sphere, with
    as little propellant as possible. The engine gives 1500 N and Isp 300 s as [001]'s and
    throttles between ``throttle_min`` (0.2, the 5:1 range of Chang'e-3's 1.5–7.5 kN engine)
    and full thrust; it stays lit until the propellant (300 kg) runs out. Dynamics: the shared
    Moon-fixed model (:func:`lunar_env.dynamics.moon3d_eom`: central gravity, Coriolis and
    centrifugal terms) integrated by the compiled RK4 of :mod:`lunar_env.integrators`; each step
    holds the action for ``dt_s`` (default 1 s) over ``substeps`` (default 2) RK4 steps, and
    touchdown is located inside the step. The minimum-fuel landing from the nominal start uses
    277.58 kg (``optimizers.optimum.touchdown``: full thrust for 7 s, the minimum throttle for
    24 s, then full thrust to touchdown, 563 s in all).

    ## Action Space

    ``Box(-1, 1, (3,), float32)``, each channel mapped affinely onto its range:

    | Num | Action                                        | Range (``peng2012_touchdown``)   |
    |-----|-----------------------------------------------|----------------------------------|
    | 0   | thrust elevation α above the local horizontal | [−50°, 90°]                      |
    | 1   | thrust azimuth β from the along-track axis    | [0°, 360°] (a₁ = 0: 180°, brake) |
    | 2   | throttle (fraction of 1500 N)                 | [throttle_min, 1] = [0.2, 1]     |

    (α, β: :func:`~lunar_env.envs.pinpoint_landing.angles_from_action` on the scenario's bounds;
    throttle = throttle_min + (a₂ + 1)/2 · (1 − throttle_min), :func:`throttle_from_action`.)
    α reaches the vertical and β the whole circle because terminal descent hovers and corrects
    its horizontal velocity in any direction. Finite out-of-range actions are clipped; NaN/inf
    raise ``ValueError`` and leave the state untouched.

    ## Observation Space

    ``Box(float32, (8,))``, layout version 1 (:data:`OBSERVATION_NAMES`): the navigated state
    relative to the target in the local frame at the lander (along-track ŷ and cross-track ẑ of
    the orbital frame, up x̂; the axes of :func:`guidance.frames.pinpoint_frame`), the mass
    estimate and the time. The horizontal position is the lander's offset from the site along
    the surface (the great-circle arc at the lander's radius, split along ŷ and ẑ; negative
    along-track before the site), the vertical one its altitude above the target's sphere.
    Positions and velocities are log-scaled, o = sign(x)·log(1 + |x|/s), with s = 10 m and
    1 m/s, so the 534 km of the start and the last metres are both resolved; the inverse is
    ``env.unwrapped.observation_quantities(obs)`` (SI). Values are clipped to the bounds.

    | Num | Observation                                  | Unit | Min | Max |
    |-----|----------------------------------------------|------|-----|-----|
    | 0   | along-track offset from the target, log      | m    | -12 | 12  |
    | 1   | cross-track offset from the target, log      | m    | -12 | 12  |
    | 2   | altitude above the target's sphere, log      | m    | -12 | 12  |
    | 3   | along-track velocity, log                    | m/s  | -8  | 8   |
    | 4   | cross-track velocity, log                    | m/s  | -8  | 8   |
    | 5   | vertical velocity (up), log                  | m/s  | -8  | 8   |
    | 6   | propellant estimate / nominal propellant     | kg   | 0   | 1.5 |
    | 7   | time / time limit                            | s    | 0   | 2   |

    ``sensors=("imu",)`` appends three channels, the IMU's measured specific force along
    (along-track, cross-track, up) in units of the full thrust acceleration at the wet mass
    (2.5 m/s²), within ±3 (as the other envs; ``env.sensor_readings()`` always has them).

    ## Rewards

    Each step −(propellant burnt)/(propellant capacity, 300 kg). At the end
    −log(1 + v_v/1 m/s) − log(1 + v_h/1 m/s) − log(1 + miss/100 m), with v_v and v_h the
    vertical and horizontal touchdown speeds and miss the distance from the target to the
    touchdown point (for a truncated episode: the vertical speed a free fall would reach at the
    surface, the horizontal speed at the end, and the miss of the radial projection). A landing
    that is not a success is also charged the propellant left, −(propellant left)/(capacity), as
    v1/v2: a failed landing loses the vehicle and its propellant, so no failure is cheaper in
    propellant than a full tank. The terms' slopes at zero (1 per m/s, 0.01 per m) are thousands
    of times the propellant a harder touchdown saves (about 0.1 kg of 300 kg per m/s), so the
    fuel-optimal soft landing on the target has the best return. Measured from the nominal
    start at 1 s steps (``tests/lunar_env/test_env_pinpoint_touchdown.py``): the certified
    optimum replayed open loop −1.84 (a success: 277.75 kg, 0.75 m/s down, 0.42 m/s across,
    0.4 m off), diving −22.0, hovering until the propellant runs out −24.7, flying past −24.8,
    the best of 50 random policies −25.1.

    ## Starting State

    [001]'s dispersion (altitude ±500 m, speed ±5 m/s, mass ±10 kg, longitude and latitude
    ±0.05°); ``options={"nominal": True}``, ``{"state_nd": ...}`` or ``{"state_si": (x, y, z m,
    vx, vy, vz m/s, m kg)}`` pin the start, checked as in v1 (above the surface, propellant
    left, at most the full tank, bound to the Moon).

    ## Episode End

    1. Termination: touchdown, the lander crossing the reference sphere (the target's; located
       inside the step), wherever it happens: a touchdown too fast or off target is a crash,
       still a touchdown. The engine never cuts off at a speed minimum (the throttle is the
       law's); when the propellant runs out inside a step the lander falls freely and the fall
       to the surface is integrated in the same step. Success: vertical speed <=
       ``success_vertical_speed_m_s`` (3 m/s) and horizontal speed <=
       ``success_horizontal_speed_m_s`` (1.2 m/s), the Apollo LM landing gear's limits (10 and
       4 ft/s, NASA TN D-6850), and miss distance <= ``success_miss_m`` (100 m, SLIM's pinpoint
       requirement).
    2. Truncation: time >= ``time_limit_s`` (default 1200 s = 1.5 × 800 s), or a free fall that
       does not reach the surface within ``max_fall_s``.

    ``info``: ``fuel_used_kg``, ``is_success``, ``altitude_m``, ``time_s``; after touchdown
    ``touchdown_speed_m_s``, ``touchdown_vertical_speed_m_s`` (downward) and
    ``touchdown_horizontal_speed_m_s``; at the end of an episode ``miss_distance_m``. Under an
    uncertainty model also ``state_nd`` (truth) and ``navigation_state_nd``.

    ## Plant and Navigation Errors

    As v1's (``uncertainty="standard"``, ...; :mod:`lunar_env.uncertainty`): entry, engine
    (thrust, Isp, misalignment of α and β, wet mass), navigation (inertial, then the terminal
    sensors below their acquisition altitude) and IMU errors. The observation encodes the
    navigated state; reward, termination and success use the truth.

    ## Arguments

    | Argument                         | Default              | Meaning                      |
    |----------------------------------|----------------------|------------------------------|
    | ``scenario``                     | "peng2012_touchdown" | a ``TouchdownScenario``      |
    | ``dt_s``                         | 1.0                  | seconds each action is held  |
    | ``substeps``                     | 2                    | RK4 steps per env step       |
    | ``time_limit_s``                 | None                 | None: 1.5 × tf_bounds_s[1]   |
    | ``throttle_channel``             | True                 | always True (it throttles)   |
    | ``success_miss_m``               | 100.0                | pinpoint radius (m)          |
    | ``success_vertical_speed_m_s``   | 3.0                  | vertical speed limit (m/s)   |
    | ``success_horizontal_speed_m_s`` | 1.2                  | horizontal speed limit (m/s) |
    | ``max_fall_s``                   | None                 | longest fall (None: limit)   |
    | ``uncertainty``                  | "none"               | plant and navigation errors  |
    | ``sensors``                      | ()                   | ``("imu",)``: IMU channels   |
    | ``render_mode``                  | None                 | "rgb_array" or "human"       |

    A limit that is not a finite number > 0 raises ``ValueError`` naming it.

    >>> import gymnasium as gym
    >>> import lunar_env
    >>> env = gym.make("LunarPinpointLanding-v3")
    >>> obs, info = env.reset(seed=0)
    >>> obs.shape, env.action_space.shape
    ((8,), (3,))
    >>> env.unwrapped.scenario.name
    'peng2012_touchdown'

    ## Version History

    - v3: to touchdown on the target with a throttleable engine (``peng2012_touchdown``): new
      observation (layout version 1), action (throttle channel on [throttle_min, 1]), episode
      end (touchdown, no speed-minimum cut-off), success and terminal term. v0–v2 ([001]'s
      2 km gate, constant thrust) are unchanged.
    """


class LunarPinpointTouchdownEnv(LanderEnv):
    __doc__ = ("Pinpoint landing to touchdown with a throttleable engine (single env)." + _DOC)
    _task_cls = TouchdownTask


class LunarPinpointTouchdownVectorEnv(LanderVectorEnv):
    __doc__ = ("Native vector version of :class:`LunarPinpointTouchdownEnv` (one compiled call "
               "per step, autoreset NEXT_STEP, sub-env i seeded with seed + i).\n" + _DOC)
    _task_cls = TouchdownTask
