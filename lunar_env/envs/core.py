"""Batched physics of an env step, shared by the single env, the native vector env and the SB3
adapter, so that all three step exactly the same arithmetic.

An env step (:meth:`LanderBatch.step`):

1. **Powered flight**: the action is held constant over ``dt_s`` and integrated by the compiled
   RK4 kernel of :mod:`lunar_env.integrators` (``substeps`` RK4 steps, the control laid out as
   ``PiecewisePolynomial.constant`` would lay it out) with the events ``RadiusCrossing`` at the
   landing radius and, for an engine that cuts off (:attr:`~lunar_env.envs.task.LandingTask.
   engine_cutoff`: the papers' constant-thrust, steer-only engine; not a throttleable one),
   ``SpeedMinimum``, both located inside the step. Fuel exhaustion at the dry mass ends the
   burn inside the kernel.
2. **Engine cut-off or burnout → free fall in the same step**: a lander whose engine stopped
   (speed minimum reached, or propellant exhausted) is integrated with throttle 0 until it
   crosses the landing radius (touchdown), at most ``max_fall_s`` (then it is truncated: a
   ballistic arc that does not come down). The episode therefore always ends in the step in which
   the engine stops.
3. **Bookkeeping**: fuel reward, the task's terminal landing-quality term and verdict
   (:meth:`~lunar_env.envs.task.LandingTask.terminal_penalty`, ``landed_within_limits``),
   truncation at the time limit, and the per-lander quantities every ``info`` reports
   (:meth:`LanderBatch.info_arrays`, with the task's own touchdown keys).

Under a task's uncertainty model (:mod:`lunar_env.uncertainty`; none by default) the batch also
holds each lander's episode errors (:class:`~lunar_env.uncertainty.EpisodeErrors`, which apply
themselves): its plant (thrust and Isp scale, in its own row of the kernel's parameters; a
misalignment bias added to its gimbal angles) and its navigation errors, which make the
observations encode the *navigated* state (:meth:`LanderBatch.navigation_states`) while the
integration, the reward and the verdict use the truth. Without errors none of this runs, and
the arithmetic is exactly that of an env without the model. A batch's task and model are fixed
when it is built: :meth:`LanderBatch.with_uncertainty` returns a new batch under another model.

This is the only place where any of this is computed: the single env is a batch of one, and it,
the native vector env and ``step_landers`` only present the same arrays in their own formats.

A speed minimum that happens *exactly at a step boundary* because the new action starts to
accelerate the lander is not a cut-off: the cut-off logic watches the speed under a held command
(the event is located inside the step).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from .. import dynamics as dyn
from .. import integrators as integ
from ..uncertainty import EpisodeErrors, UncertaintyModel
from ..uncertainty.navigation import IMU_SALT, standard_normals

__all__ = ["LanderBatch", "landing_penalty", "SPEED_SCALE_M_S", "MISS_SCALE_M",
           "INFO_KEYS"]

#: Scales of the terminal landing-quality term (see :func:`landing_penalty`).
SPEED_SCALE_M_S = 1.0
MISS_SCALE_M = 100.0

#: Batch size from which env steps use the parallel kernel by default. An env step is only
#: ``substeps`` RK4 steps per lander (~1 µs), so thread start-up dominates below several
#: thousand landers (measured on a loaded 2-core machine: serial 7 ms vs parallel 58 ms at 4096).
PARALLEL_MIN_BATCH = 16384
_MAX_RESUMES = 8

#: Keys of :meth:`LanderBatch.info_arrays`, in the order the infos list them.
INFO_KEYS = ("fuel_used_kg", "is_success", "altitude_m", "time_s", "touchdown_speed_m_s",
             "miss_distance_m")


def landing_penalty(speed_m_s, miss_m=None):
    """Terminal landing-quality term (to be subtracted from the return).

    ``log1p(speed / 1 m/s)`` (+ ``log1p(miss / 100 m)`` for pinpoint landing). Its slope at zero
    (1 per m/s, 0.01 per m) is hundreds of times the fuel a constant-thrust lander saves by
    cutting off early (about 0.5 kg of 300 kg of budget per m/s of touchdown speed), so the
    return is maximised by the fuel-optimal landing at zero speed (and zero miss); the logarithm
    keeps crash penalties bounded (a 1.7 km/s crash costs 7.4) so value functions stay well
    scaled.
    """
    out = np.log1p(np.asarray(speed_m_s, dtype=np.float64) / SPEED_SCALE_M_S)
    if miss_m is not None:
        out = out + np.log1p(np.asarray(miss_m, dtype=np.float64) / MISS_SCALE_M)
    return out


@numba.njit(cache=True)
def _prepare(t0, dt_nd, controls, breaks, coefs):  # pragma: no cover  (compiled)
    """Fill the kernel's control layout: the action held over [t0, t0 + dt_nd] (as
    ``PiecewisePolynomial.constant`` lays it out). One compiled loop instead of four NumPy
    assignments, whose overhead would dominate a step of one lander."""
    for i in range(t0.shape[0]):
        breaks[i, 0] = t0[i]
        breaks[i, 1] = t0[i] + dt_nd
        for j in range(controls.shape[1]):
            coefs[i, 0, j, 0] = controls[i, j]


@numba.njit(cache=True)
def _fuel_and_clock(y0, y_end, t_end, status, t_burn, mass_ref_kg, propellant_ref_kg,
                    time_ref_s, t_limit_s, reward, late):  # pragma: no cover  (compiled)
    """The step's fuel reward (propellant burnt / capacity, negative) into ``reward`` and the
    time-limit test (``t >= t_limit_s``, s) into ``late``, per lander; returns how many landers
    need the terminal logic (an integrator event, a burnout or the time limit)."""
    last = y_end.shape[1] - 1
    n_busy = 0
    for i in range(y_end.shape[0]):
        reward[i] = (y0[i, last] - y_end[i, last]) * mass_ref_kg / -propellant_ref_kg
        late[i] = t_end[i] * time_ref_s >= t_limit_s
        if late[i] or status[i] != integ.STATUS_COMPLETED or t_burn[i] == t_burn[i]:
            n_busy += 1
    return n_busy


@numba.njit(cache=True)
def _fuel_used_and_time(m_start, y, t_nd, mass_ref_kg, time_ref_s, fuel, t_s
                        ):  # pragma: no cover  (compiled)
    """Propellant used since the episode's start (kg) and episode time (s) per lander, into
    ``fuel`` and ``t_s`` (allocated by the caller: NumPy allocates faster than numba boxes)."""
    last = y.shape[1] - 1
    for i in range(y.shape[0]):
        fuel[i] = (m_start[i] - y[i, last]) * mass_ref_kg
        t_s[i] = t_nd[i] * time_ref_s


@numba.njit(cache=True, error_model="numpy")
def _imu_kernel(rows, y0, t0, y, t_nd, controls, c_nd, n_axes, time_ref_s, velocity_ref_m_s,
                keys, counters, gain, bias, sigma, uncertain, out):  # pragma: no cover
    """The accelerometers' reading into ``out`` (n, n_axes) (zeroed by the caller): for each
    stepped lander ``rows[j]`` that has flown a step of its episode, the step's mean thrust
    acceleration c·ln(m₀/m₁)/Δt along its thrust direction in the guidance frame's axes; then,
    under an uncertainty model, gain × that + bias + σ·noise for every lander (the noise
    counter-based on the episode's IMU key). The one formula of
    :meth:`LanderBatch.specific_force_m_s2` and :meth:`LanderBatch.sensor_readings`."""
    last = y.shape[1] - 1
    for j in range(rows.shape[0]):
        i = rows[j]
        if t_nd[i] <= 0.0:
            continue
        dv = c_nd[j] * np.log(y0[j, last] / y[i, last]) * velocity_ref_m_s
        a = dv / ((t_nd[i] - t0[j]) * time_ref_s)
        # the thrust direction of the equations of motion (lunar_env.dynamics)
        if n_axes == 2:
            up, brake, _ = dyn.planar_thrust_terms(controls[j, 0], 1.0)
            out[i, 0] = -brake * a
            out[i, 1] = up * a
        else:
            radial, along, cross, _ = dyn.moon3d_thrust_terms(controls[j, 0], controls[j, 1], 1.0)
            out[i, 0] = along * a
            out[i, 1] = cross * a
            out[i, 2] = radial * a
    if uncertain:
        n = out.shape[0]
        ikeys = np.empty(n, dtype=np.uint64)
        for i in range(n):
            ikeys[i] = keys[i] ^ IMU_SALT
        z = np.empty((4, n))
        standard_normals(ikeys, counters, z)
        for i in range(n):
            # bias and noise columns (up, downrange, crossrange) in the guidance axes' order
            if n_axes == 2:
                out[i, 0] = gain[i] * out[i, 0] + bias[i, 1] + sigma * z[1, i]
                out[i, 1] = gain[i] * out[i, 1] + bias[i, 0] + sigma * z[0, i]
            else:
                out[i, 0] = gain[i] * out[i, 0] + bias[i, 1] + sigma * z[1, i]
                out[i, 1] = gain[i] * out[i, 1] + bias[i, 2] + sigma * z[2, i]
                out[i, 2] = gain[i] * out[i, 2] + bias[i, 0] + sigma * z[0, i]


class LanderBatch:
    """State and step physics of ``n`` landers of one task.

    Parameters
    ----------
    task : LandingTask
        The task (:class:`~lunar_env.envs.task.LandingTask`) supplying the model, the control
        mapping and the landing geometry.
    n : int
        Batch size (1 for the single env).
    parallel : bool or None
        Use numba's parallel kernel (None: from :data:`PARALLEL_MIN_BATCH` landers).
    carries_errors : bool or None
        The landers carry episode errors (None: unless the task's uncertainty model is null,
        see :attr:`uncertain`).

    The task (and so the uncertainty model) is fixed for the batch's life: read-only
    :attr:`task` and :attr:`uncertainty`; :meth:`with_uncertainty` returns a new batch.
    """

    def __init__(self, task, n: int, parallel: bool | None = None,
                 carries_errors: bool | None = None) -> None:
        self._task = task
        self.n = int(n)
        nx = task.model.n_state
        nu = task.model.n_control
        self.y = np.zeros((self.n, nx))
        self.t_nd = np.zeros(self.n)
        self.m_start_nd = np.ones(self.n)
        # pre-allocated kernel inputs for the whole batch (the common case; for one lander the
        # allocations would cost as much as the integration)
        self._breaks = np.zeros((self.n, 2))
        self._coefs = np.zeros((self.n, 1, nu, 1))
        self._h = np.full(self.n, task.h_nd)
        self._r_stop = np.full(self.n, task.r_stop_nd)
        # the kernel writes the step's end into the spare state buffers, which then swap with
        # the current ones (new result arrays would cost more than integrating one lander)
        self._y_spare = np.zeros((self.n, nx))
        self._t_spare = np.zeros(self.n)
        self._status = np.zeros(self.n, dtype=np.int64)
        self._t_burn = np.zeros(self.n)
        self._late = np.zeros(self.n, dtype=bool)
        # scratch results (see ``step``): read-only, so that a caller cannot corrupt them
        self._reward = np.zeros(self.n)
        self._fuel_used = np.zeros(self.n)
        self._time_s = np.zeros(self.n)
        self._nan = np.full(self.n, np.nan)
        self._no = np.zeros(self.n, dtype=bool)
        self._nan.flags.writeable = False
        self._no.flags.writeable = False
        # constants of _fuel_and_clock: the fuel reward's units and the time-limit test
        self._clock = (task.mass_ref_kg, task.propellant_ref_kg, task.time_ref_s,
                       task.time_limit_s - 1e-9 * task.dt_s)
        self._dt_nd = task.dt_nd
        self._substeps = task.substeps
        # the SpeedMinimum event (engine cut-off) is armed for engines that cannot throttle
        self._cutoff = bool(task.engine_cutoff)
        self._extra_keys = tuple(task.extra_info_keys)
        self._parallel = (self.n >= PARALLEL_MIN_BATCH if parallel is None else bool(parallel)) \
            and numba.config.NUMBA_NUM_THREADS > 1
        # the kernel's parameters, one row per lander (a plant error changes a lander's row)
        self._p = np.array(integ.params_rows(task.params_array, self.n))
        #: the landers carry episode errors (False: the model is null, nothing below runs)
        self.uncertain = (not task.uncertainty.is_null if carries_errors is None
                          else bool(carries_errors))
        self.errors = EpisodeErrors.zeros(self.n) if self.uncertain else None
        self._mass_belief = np.zeros(self.n)  # flight computer's mass minus the truth (kg)
        #: decisions taken in each lander's episode (the navigation noise's counter)
        self.decision = np.zeros(self.n, dtype=np.int64)
        self._n_angles = nu - 1  # every control channel but the last (throttle) is an angle
        self._nav: np.ndarray | None = None
        self._last_step: tuple | None = None
        self._imu_sigma = float(task.uncertainty.imu_vrw_m_s_sqrt_s / math.sqrt(task.dt_s))

    @property
    def task(self):
        """The task (:class:`~lunar_env.envs.task.LandingTask`) the batch flies (read-only)."""
        return self._task

    @property
    def uncertainty(self) -> UncertaintyModel:
        """The task's uncertainty model (read-only)."""
        return self._task.uncertainty

    def with_uncertainty(self, model: UncertaintyModel) -> LanderBatch:
        """A new batch of the same landers under ``model``: the task rebuilt with it
        (:meth:`~lunar_env.envs.task.LandingTask.with_uncertainty`), and copies of every
        lander's state, clock, initial mass, decision counter, episode errors (with the plant
        and the flight computer's mass belief they set) and last navigated state. Episodes
        under way keep the errors they drew; the new model acts on the episodes that start in
        the new batch and on the navigation noise of every decision it steps. This batch is
        left as it was.

        Raises
        ------
        ValueError
            If this batch carries no episode errors (its task's model is null).
        """
        if not self.uncertain:
            raise ValueError("with_uncertainty needs a batch with episode errors (a task with "
                             "an uncertainty model); make the env with uncertainty=...")
        new = LanderBatch(self._task.with_uncertainty(model), self.n, self._parallel,
                          carries_errors=True)
        new.y[:] = self.y
        new.t_nd[:] = self.t_nd
        new.m_start_nd[:] = self.m_start_nd
        new.decision[:] = self.decision
        new.errors = self.errors.take(slice(None))
        new._mass_belief[:] = self._mass_belief
        new._p[:] = self._p
        new._nav = None if self._nav is None else self._nav.copy()
        new._last_step = self._last_step
        return new

    # -- state ----------------------------------------------------------------------------------
    def set_state(self, i, y_nd: np.ndarray) -> None:
        """Start episode(s) ``i`` from normalised state(s) ``y_nd`` at t = 0."""
        self.y[i] = y_nd
        self.t_nd[i] = 0.0
        self.m_start_nd[i] = self.y[i, -1] if np.ndim(i) == 0 else self.y[i][:, -1]
        if self.uncertain:
            self.decision[i] = 0
            self._nav = None

    def set_errors(self, i: int, errors: EpisodeErrors) -> None:
        """Give lander ``i`` the one-row episode ``errors`` (its plant and navigation; its start
        is the caller's, see :meth:`~lunar_env.uncertainty.EpisodeErrors.true_start`)."""
        self.errors.set_row(i, errors)
        self._mass_belief[i] = -errors.mass_error_kg[0]
        self._p[i] = errors.plant_params(self._task.params).as_array()

    def navigation_states(self) -> np.ndarray:
        """The navigated states (n, n_state) of every lander now: the truth with each lander's
        navigation bias and this decision's noise (along up, downrange, crossrange; scaled by
        :func:`~lunar_env.uncertainty.radar_weight` at the true altitude), and the mass the
        flight computer believes (the planned initial mass minus the propellant burnt)
        (:meth:`~lunar_env.envs.task.LandingTask.navigation_states`). The truth itself without
        an uncertainty model."""
        if not self.uncertain:
            return self.y
        return self._task.navigation_states(self.y, self.errors, self.decision,
                                           self._mass_belief)

    def observations(self, t_s: np.ndarray | None = None) -> np.ndarray:
        """Observations (n, n_obs) float32 of every lander now (of the navigated states, see
        :meth:`navigation_states`; remembered for :attr:`last_navigation`); ``t_s`` (n,) their
        episode times (s) when already at hand (``info_arrays(...)["time_s"]``), saving a
        multiply."""
        task = self._task
        t = self.t_nd * task.time_ref_s if t_s is None else t_s
        if not self.uncertain:
            obs = task.observation(self.y, t)
        else:
            self._nav = self.navigation_states()
            obs = task.observation(self._nav, t)
        if task.sensors:
            obs = task.with_sensor_channels(obs, self.sensor_readings())
        return obs

    @property
    def last_navigation(self) -> np.ndarray:
        """The navigated states (n, n_state) the last observations encode (the truth without
        an uncertainty model); read-only."""
        if not self.uncertain:
            return self.y
        if self._nav is None:
            self._nav = self.navigation_states()
        return self._nav

    def _imu(self, measured: bool) -> np.ndarray:
        task = self._task
        out = np.zeros((self.n, task.n_axes))
        if self._last_step is None:  # no step yet: nothing flown (the errors still read)
            if not measured:
                return out
            rows, t0, c_nd = np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0)
            controls = np.zeros((0, task.model.n_control))
            y0 = np.zeros((0, task.model.n_state))
        else:
            idx, y0, t0, controls, p = self._last_step
            rows = np.arange(self.n) if idx is None else np.asarray(idx, dtype=np.int64)
            c_nd = np.ascontiguousarray(p[:, 1])
        e = self.errors
        uncertain = measured and self.uncertain
        _imu_kernel(rows, np.ascontiguousarray(y0), np.ascontiguousarray(t0), self.y,
                    self.t_nd, np.ascontiguousarray(controls, dtype=np.float64), c_nd,
                    task.n_axes, task.time_ref_s, task.velocity_ref_m_s,
                    e.noise_key if uncertain else np.zeros(self.n, dtype=np.uint64),
                    self.decision, e.imu_scale if uncertain else np.ones(self.n),
                    e.imu_bias_m_s2 if uncertain else np.zeros((self.n, 3)),
                    self._imu_sigma, uncertain, out)
        return out

    def specific_force_m_s2(self) -> np.ndarray:
        """The true specific force of every lander (n, d) (m/s²): its mean thrust acceleration
        over the last step, along the misaligned thrust axis, in the guidance frame's axes
        (horizontal..., up; the thrust direction of :mod:`lunar_env.dynamics`); 0 for
        a lander that has not flown a step of its episode. The rocket equation gives its
        magnitude exactly (the step's Δv is c·ln(m₀/m₁) whatever the throttle), its direction
        is the step's (the frame turns by a few thousandths of a degree in a step)."""
        return self._imu(measured=False)

    def sensor_readings(self) -> dict[str, np.ndarray]:
        """What the flight computer's sensors read now, per lander: ``imu`` (n, d), the
        accelerometers' specific force (m/s², guidance-frame axes): the truth
        (:meth:`specific_force_m_s2`) with the episode's IMU errors under an uncertainty model:
        gain (1 + scale-factor error) × truth + bias + white noise, its σ the velocity random
        walk over √dt, counter-based on the episode's IMU key."""
        return {"imu": self._imu(measured=True)}

    def info_arrays(self, speed: np.ndarray, miss: np.ndarray, success: np.ndarray,
                    scratch: bool = False, extras: dict | None = None
                    ) -> dict[str, np.ndarray]:
        """What every ``info`` reports, per lander (n,), keys :data:`INFO_KEYS` and the task's
        :attr:`~lunar_env.envs.task.LandingTask.extra_info_keys`.

        ``fuel_used_kg`` since the episode's start (kg), ``is_success``, ``altitude_m`` (m),
        ``time_s`` (s), ``touchdown_speed_m_s`` (m/s) and ``miss_distance_m`` (m) (``speed``,
        ``miss``: NaN where undefined, as :meth:`step` returns them); the extra keys from
        ``extras`` (e.g. :meth:`step`'s result; NaN where undefined or absent). ``scratch``:
        as in :meth:`step` (fuel and time in the batch's buffers, valid until the next call).
        """
        task = self._task
        if scratch:
            fuel, t_s = self._fuel_used, self._time_s
        else:
            fuel = np.empty(self.n)
            t_s = np.empty(self.n)
        _fuel_used_and_time(self.m_start_nd, self.y, self.t_nd, task.mass_ref_kg,
                            task.time_ref_s, fuel, t_s)
        out = {"fuel_used_kg": fuel, "is_success": success, "altitude_m": task.altitude_m(self.y),
               "time_s": t_s, "touchdown_speed_m_s": speed, "miss_distance_m": miss}
        for k in self._extra_keys:
            out[k] = extras[k] if extras is not None and k in extras else np.full(self.n, np.nan)
        return out

    # -- physics --------------------------------------------------------------------------------
    def _powered(self, idx, y0: np.ndarray, t0: np.ndarray, controls: np.ndarray,
                 p: np.ndarray):
        task = self._task
        varies = task.gate_range_m is not None
        if idx is None:
            breaks, coefs, h, rs = self._breaks, self._coefs, self._h, self._r_stop
            if varies:
                rs[:] = task.stop_radius(y0)
            parallel = self._parallel
            out = (self._y_spare, self._t_spare, self._status, self._t_burn)
        else:
            k = len(y0)
            breaks = np.empty((k, 2))
            coefs = np.empty((k, 1, controls.shape[1], 1))
            h = self._h[:k]
            rs = task.stop_radius(y0) if varies else self._r_stop[:k]
            parallel = self._parallel and k >= integ._PARALLEL_MIN_BATCH
            out = (np.empty_like(y0), np.empty(k), np.empty(k, dtype=np.int64), np.empty(k))
        _prepare(t0, self._dt_nd, controls, breaks, coefs)
        return integ.integrate_prepared(task.model, y0, t0, h, self._substeps, breaks, coefs,
                                        p, task.dry_mass_nd, rs, self._cutoff, parallel, out)

    def _resume(self, y0: np.ndarray, t0: float, t1: float, controls: np.ndarray,
                p: np.ndarray):
        """Powered flight of one lander from a speed minimum that is not a cut-off to the step's
        end ``t1``, in equal RK4 steps no longer than the regular substep."""
        task = self._task
        n = max(1, int(math.ceil((t1 - t0) / task.h_nd - 1e-9)))
        ctrl = integ.PiecewisePolynomial.constant(controls[None], np.array([t0]), np.array([t1]))
        p = integ.integrate(
            task.model, y0[None], t0_nd=t0, dt_nd=(t1 - t0) / n, n_steps=n, control=ctrl,
            params=p, dry_mass_nd=task.dry_mass_nd,
            events=(integ.RadiusCrossing(task.r_stop_nd), integ.SpeedMinimum()), parallel=False)
        return p.y_end[0], p.t_end[0], p.status[0], p.t_burnout[0]

    def _fall(self, y0: np.ndarray, t0: np.ndarray, p: np.ndarray):
        """Engine off until the landing radius (or ``max_fall_s``): the public integrator."""
        task = self._task
        k = len(y0)
        ctrl = integ.PiecewisePolynomial.constant(
            np.zeros((k, task.model.n_control)), t0, t0 + task.n_fall * task.h_nd)
        return integ.integrate(
            task.model, y0, t0_nd=t0, dt_nd=task.h_nd, n_steps=task.n_fall, control=ctrl,
            params=p, dry_mass_nd=task.dry_mass_nd,
            events=(integ.RadiusCrossing(task.r_stop_nd),),
            parallel=self._parallel and k >= integ._PARALLEL_MIN_BATCH)

    def step(self, controls: np.ndarray, idx: np.ndarray | None = None,
             scratch: bool = False) -> dict:
        """Advance landers ``idx`` (all if None) by one env step under ``controls`` (k, nu).

        ``controls`` must already be validated and mapped to radians/throttle
        (``task.controls_from_actions``). Returns a dict of arrays of length k: ``reward``,
        ``terminated`` (touchdown), ``truncated``, ``touchdown_speed_m_s`` (m/s; NaN if no
        touchdown), ``miss_distance_m`` (m; NaN unless a pinpoint episode ended),
        ``is_success``.

        ``scratch=True`` (for a caller that reads the results at once, like the single env):
        the arrays may be the batch's own read-only buffers, valid until the next call; for
        one lander, new arrays would cost as much as the step's bookkeeping.
        """
        task = self._task
        if idx is None:
            y0, t0 = self.y, self.t_nd
            p = self._p
        else:
            y0, t0 = self.y[idx], self.t_nd[idx]
            p = self._p[idx] if self.uncertain else self._p[:len(idx)]
        if self.uncertain:
            # the engine points where commanded plus its misalignment (gimbal-angle biases)
            controls = self.errors.misaligned(controls, self._n_angles, idx)
            self._nav = None
            if idx is None:
                self.decision += 1
            else:
                self.decision[idx] += 1
        # what the IMU measured over this step is read from these (sensor_readings): the
        # arrays stay untouched until the next step
        self._last_step = (idx, y0, t0, controls, p)
        y_end, t_end, status, t_burn = self._powered(idx, y0, t0, controls, p)
        k = len(y_end)
        reward = self._reward[:k] if scratch else np.empty(k)
        late = self._late[:k]  # internal: the returned flags are built from it
        if not _fuel_and_clock(y0, y_end, t_end, status, t_burn, *self._clock, reward, late):
            # no event, engine on, time left (every step of an episode but its last): the fuel
            # term is the whole outcome
            self._store(idx, y_end, t_end)
            if scratch:
                no, nan = self._no[:k], self._nan[:k]
                out = {"reward": reward, "terminated": no, "truncated": no,
                       "touchdown_speed_m_s": nan, "miss_distance_m": nan, "is_success": no}
                for key in self._extra_keys:
                    out[key] = nan
                return out
            nan = self._nan[:k]
            out = {"reward": reward, "terminated": np.zeros(k, dtype=bool),
                   "truncated": np.zeros(k, dtype=bool), "touchdown_speed_m_s": nan.copy(),
                   "miss_distance_m": nan.copy(), "is_success": np.zeros(k, dtype=bool)}
            for key in self._extra_keys:
                out[key] = nan.copy()
            return out
        t_step_end = t0 + task.dt_nd
        burnt = ~np.isnan(t_burn)
        # A speed minimum above the cut-off speed is not an engine cut-off (the cut-off logic is
        # armed only in the terminal phase): keep burning to the end of the step.
        for _ in range(_MAX_RESUMES):
            resume = (status == integ.STATUS_SPEED_MIN) & ~burnt
            if not resume.any():
                break
            resume &= task.speed_m_s(y_end) > task.cutoff_speed_m_s
            resume &= t_end < t_step_end - 1e-12 * task.dt_nd
            if not resume.any():
                break
            for j in np.flatnonzero(resume):  # rare: one lander at a time, batch-independent
                y_end[j], t_end[j], status[j], tb = self._resume(
                    y_end[j], t_end[j], t_step_end[j], controls[j], p[j:j + 1])
                burnt[j] |= not np.isnan(tb)
        touchdown = status == integ.STATUS_RADIUS
        if task.gate_range_m is not None:
            # pinpoint v2: a lander that enters the target zone under the gate (it flew below
            # 2 km elsewhere) ends there, scored at its current speed and position
            touchdown |= task.below_gate_in_zone(y_end) & ~burnt
        engine_off = (status == integ.STATUS_SPEED_MIN) | (burnt & ~touchdown)
        lost = np.zeros_like(touchdown)
        if engine_off.any():
            j = np.flatnonzero(engine_off)
            fall = self._fall(y_end[j], t_end[j], p[j])
            y_end[j] = fall.y_end
            t_end[j] = fall.t_end
            landed = fall.status == integ.STATUS_RADIUS
            touchdown[j] = landed
            lost[j] = ~landed
        self._store(idx, y_end, t_end)
        _fuel_and_clock(y0, y_end, t_end, status, t_burn, *self._clock, reward, late)
        truncated = ~touchdown & (lost | late)
        ended = touchdown | truncated
        speed = np.full(len(y_end), np.nan)
        miss = np.full(len(y_end), np.nan)
        success = np.zeros(len(y_end), dtype=bool)
        extras = {key: np.full(len(y_end), np.nan) for key in self._extra_keys}
        if ended.any():
            e = np.flatnonzero(ended)
            td = touchdown[e]
            sp, ms = task.landing_metrics(y_end[e], touched_down=td)
            reward[e] -= task.terminal_penalty(y_end[e], sp, ms, td)
            speed[e[td]] = sp[td]
            if ms is not None:
                miss[e] = ms
            if self._extra_keys and td.any():
                for key, v in task.touchdown_info(y_end[e[td]]).items():
                    extras[key][e[td]] = v
            ok = td & task.landed_within_limits(y_end[e], sp, ms)
            success[e] = ok
            if task.charge_propellant_on_failure and not ok.all():
                # pinpoint v1: a failed landing loses the propellant left with the vehicle
                f = e[~ok]
                reward[f] -= (y_end[f, -1] - task.dry_mass_nd) * task.mass_ref_kg \
                    / task.propellant_ref_kg
        return {"reward": reward, "terminated": touchdown, "truncated": truncated,
                "touchdown_speed_m_s": speed, "miss_distance_m": miss, "is_success": success,
                **extras}

    def _store(self, idx, y_end: np.ndarray, t_end: np.ndarray) -> None:
        if idx is None:  # y_end, t_end are the spare buffers: swap
            self._y_spare, self.y = self.y, y_end
            self._t_spare, self.t_nd = self.t_nd, t_end
        else:
            self.y[idx] = y_end
            self.t_nd[idx] = t_end
