"""Task-generic single env and native vector env; the concrete envs subclass these.

A *task* (:class:`~lunar_env.envs.task.LandingTask`: ``PlanarTask``, ``PinpointTask``) owns
everything scenario-specific: spaces, the action-to-control map, observations, landing metrics
and initial states. :class:`LanderEnv` and :class:`LanderVectorEnv` own the Gymnasium protocol
and nothing else: both step through :meth:`LanderBatch.step
<lunar_env.envs.core.LanderBatch.step>` (the single env is a batch of one) and report
:meth:`~lunar_env.envs.core.LanderBatch.info_arrays`, so a vector env and N single envs do the
same arithmetic by construction.
"""

from __future__ import annotations

import math
import numbers
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ..uncertainty import EpisodeErrors, error_stream, resolve_uncertainty
from .core import LanderBatch
from .task import LandingTask

__all__ = ["LanderEnv", "LanderVectorEnv", "validate_actions", "check_reset_options",
           "RESET_OPTION_KEYS"]


def validate_actions(action, shape: tuple[int, ...]) -> np.ndarray:
    """Action(s) as float64 of ``shape``; NaN/inf or a wrong shape raise ``ValueError``.

    A shape that differs from ``shape`` only by axes of length 1 is accepted (a scalar for a
    one-channel env, ``(N,)`` for ``(N, 1)``); any other shape is refused even when the number
    of elements matches: ``(2, 4)`` for four landers with two channels each would mix the
    landers' actions up. Finite out-of-range values are *not* an error; the task clips them to
    [-1, 1]. ``None``, complex numbers, strings and other non-numbers are refused by name (not
    converted: a complex action would lose its imaginary part, ``None`` would become NaN).
    """
    if action is None:
        raise ValueError(f"action is None; expected an array of real numbers of shape {shape}")
    raw = action if type(action) is np.ndarray else None
    if raw is None:
        try:
            raw = np.asarray(action)
        except (TypeError, ValueError):  # ragged nested sequences
            raise ValueError(f"action {action!r} is not an array of numbers of shape {shape}"
                             ) from None
    kind = raw.dtype.kind
    if kind == "c":
        raise ValueError(f"action {action!r} is complex; actions are real numbers (shape "
                         f"{shape})")
    if kind not in "fiub":
        what = {"U": "text", "S": "bytes", "O": "Python objects"}.get(kind, f"dtype {raw.dtype}")
        items = raw.reshape(-1).tolist() if kind == "O" else []
        if kind == "O" and all(isinstance(v, numbers.Real) and not isinstance(v, bool)
                               for v in items):
            raw = raw.astype(np.float64)  # a list mixing ints and numpy floats, say
        elif any(v is None for v in items):
            raise ValueError(f"action {action!r} contains None; expected an array of real "
                             f"numbers of shape {shape}")
        else:
            raise ValueError(f"action {action!r} holds {what}, not real numbers; expected an "
                             f"array of real numbers of shape {shape}")
    a = raw.astype(np.float64, copy=False)
    if a.shape != shape:
        squeeze = tuple(d for d in a.shape if d != 1)
        if squeeze == tuple(d for d in shape if d != 1):
            a = a.reshape(shape)
        else:
            raise ValueError(f"action has shape {a.shape}; expected {shape} "
                             "(landers along the first axis, action channels along the last)")
    if not np.isfinite(a).all():
        raise ValueError(f"action {np.asarray(action)!r} contains NaN or inf; actions must be "
                         "finite (out-of-range finite values are clipped to [-1, 1])")
    return a


#: ``reset(options=...)`` keys every lander env understands.
RESET_OPTION_KEYS = ("state_si", "state_nd", "nominal", "errors")


def _check_state_option(key: str, value, n_state: int, num_envs: int | None) -> None:
    """Shape/finite check of a ``state_si`` / ``state_nd`` reset option (before any reset)."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"options[{key!r}] = {value!r} is not an array of numbers") from None
    ok = (n_state,) if num_envs is None else ((n_state,), (num_envs, n_state))
    if arr.shape != (n_state,) and (num_envs is None or arr.shape != (num_envs, n_state)):
        raise ValueError(f"options[{key!r}] has shape {arr.shape}; expected "
                         + " or ".join(map(str, ok if num_envs is not None else [ok])))
    if not np.isfinite(arr).all():
        raise ValueError(f"options[{key!r}] contains NaN or inf: {arr!r}")


def check_reset_options(options, n_state: int, num_envs: int | None = None,
                        uncertain: bool = False) -> None:
    """Validate ``reset(options=...)``: known keys, state rows of the right shape, finite.

    Raises ValueError naming the key (unknown keys are errors, not silently ignored).
    """
    from ..validation import require_option_keys

    require_option_keys("reset options", options, RESET_OPTION_KEYS)
    if options and options.get("errors") is not None and not uncertain:
        raise ValueError("reset option 'errors' needs an env with an uncertainty model; make "
                         "it with uncertainty=... (a set name, an UncertaintyModel or a dict)")
    for key in ("state_si", "state_nd"):
        if options and options.get(key) is not None:
            _check_state_option(key, options[key], n_state, num_envs)


def _single_info(q: dict[str, np.ndarray], has_target: bool, extra_keys: tuple = ()) -> dict:
    """Gymnasium single-env info of lander 0 of :meth:`LanderBatch.info_arrays` ``q``: Python
    scalars, and only where defined (no NaN in infos): the touchdown speed (and the task's
    ``extra_keys``) after touchdown, the miss distance at the end of a pinpoint episode."""
    # .item(): the Python scalar of a one-element array, the cheapest conversion
    info = {"fuel_used_kg": q["fuel_used_kg"].item(), "is_success": q["is_success"].item(),
            "altitude_m": q["altitude_m"].item(), "time_s": q["time_s"].item()}
    speed = q["touchdown_speed_m_s"].item()
    if speed == speed:
        info["touchdown_speed_m_s"] = speed
    miss = q["miss_distance_m"].item()
    if has_target and miss == miss:
        info["miss_distance_m"] = miss
    for k in extra_keys:
        v = q[k].item()
        if v == v:
            info[k] = v
    return info


def _vector_info(q: dict[str, np.ndarray], has_target: bool, extra_keys: tuple = ()) -> dict:
    """Gymnasium vector-env info of :meth:`LanderBatch.info_arrays` ``q``: "_key" marks the
    sub-envs where "key" is defined (touchdown speed and the task's ``extra_keys`` after a
    touchdown; miss distance at the end of a pinpoint episode), undefined entries are 0."""
    info = {k: q[k] for k in ("fuel_used_kg", "is_success", "altitude_m", "time_s")}
    mask = np.ones(len(q["time_s"]), dtype=bool)
    for k in list(info):
        info["_" + k] = mask
    keys = ("touchdown_speed_m_s", "miss_distance_m") if has_target else ("touchdown_speed_m_s",)
    for k in (*keys, *extra_keys):
        undefined = np.isnan(q[k])
        info[k] = np.where(undefined, 0.0, q[k])
        info["_" + k] = ~undefined
    return info


class _TaskDescription:
    """What policies and wrappers may rely on, for the single and the vector env alike (read
    from the env's task, a :class:`~lunar_env.envs.task.LandingTask` of class ``_task_cls``)."""

    _task_cls: type[LandingTask] = None
    _task: LandingTask

    @property
    def task(self) -> LandingTask:
        """The env's task (frozen: its settings, scaling and maps; see
        :class:`~lunar_env.envs.task.LandingTask`)."""
        return self._task

    @property
    def sensors(self) -> tuple[str, ...]:
        """The sensor channels appended to the observation (``sensors=...``; the flight
        computer reads every sensor through ``sensor_readings()`` whatever this is)."""
        return self._task.sensors

    @property
    def gate_range_m(self) -> float | None:
        """Distance from the target (m) within which the terminal gate counts; None: the
        terminal radius counts everywhere (soft landing, pinpoint v0/v1)."""
        return self._task.gate_range_m

    @classmethod
    def task_defaults(cls) -> dict:
        """Default values of the env's keyword arguments (scenario, dt_s, ...)."""
        import inspect

        return {k: v.default for k, v in inspect.signature(cls._task_cls).parameters.items()
                if v.default is not inspect.Parameter.empty}

    @property
    def dt_s(self) -> float:
        """Decision interval: each action is held for this long (s)."""
        return self._task.dt_s

    @property
    def time_limit_s(self) -> float:
        """Episode time limit (s) (truncation)."""
        return self._task.time_limit_s

    @property
    def has_target(self) -> bool:
        """True for a pinpoint task (miss distance reported)."""
        return bool(self._task.has_target)

    @property
    def success_thresholds(self) -> dict[str, float]:
        """The env's own landing verdict: ``speed_m_s`` (largest touchdown or gate speed of a
        success), for a pinpoint task ``miss_m`` (largest miss distance), and whatever limits
        the task adds (:meth:`~lunar_env.envs.task.LandingTask.success_thresholds`)."""
        return self._task.success_thresholds()

    def observation_quantities(self, obs: np.ndarray) -> dict[str, np.ndarray]:
        """SI quantities encoded in observations (B, n_obs) (the inverse of the observation
        map; see the task's :meth:`~lunar_env.envs.task.LandingTask.observation_quantities`)."""
        return self._task.observation_quantities(obs)

    @property
    def error_scale(self) -> float:
        """The factor on every σ of the env's uncertainty model now flown (1 unless
        :meth:`set_error_scale` changed it)."""
        return self._error_scale

    def set_error_scale(self, scale: float) -> None:
        """Fly the env's uncertainty model with every σ multiplied by ``scale`` >= 0
        (:meth:`~lunar_env.uncertainty.UncertaintyModel.scaled`: the same standard normals, so
        an episode's errors are ``scale`` times those it draws at 1): the errors of every
        episode that starts from now on, and the navigation noise of every lander from its next
        decision on (an episode under way keeps the entry, plant and bias errors it drew). For
        a training curriculum over the errors (:class:`agents.rl.curriculum.
        ErrorScaleCurriculum`). The env swaps its batch for one under the scaled model
        (:meth:`~lunar_env.envs.core.LanderBatch.with_uncertainty`, which rebuilds the task);
        no built task or batch is changed.

        Raises
        ------
        ValueError
            ``scale`` is not finite and >= 0, or the env was made without an uncertainty model.
        """
        from ..validation import require_number

        scale = require_number("scale", scale)
        if not (math.isfinite(scale) and scale >= 0.0):
            raise ValueError(f"scale = {scale!r} must be a finite number >= 0")
        if not self._batch.uncertain:
            raise ValueError("set_error_scale needs an env with an uncertainty model; make it "
                             "with uncertainty=... (a set name, an UncertaintyModel or a dict)")
        base = resolve_uncertainty(self._task_kwargs.get("uncertainty"))
        self._batch = self._batch.with_uncertainty(base.scaled(scale))
        self._task = self._batch.task
        self._error_scale = scale

    def physical_constants(self) -> dict[str, float]:
        """SI constants of the lander and body (see the task's
        :meth:`~lunar_env.envs.task.LandingTask.physical_constants`)."""
        return self._task.physical_constants()


class LanderEnv(_TaskDescription, gym.Env):
    """Base of the single-lander envs (see the subclasses for the manual)."""

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 10}
    _task_cls: type = None  # set by subclasses

    def __init__(self, render_mode: str | None = None, **task_kwargs: Any) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode={render_mode!r} is not supported; use one of "
                             f"{self.metadata['render_modes']} or None")
        self.render_mode = render_mode
        self._task_kwargs = dict(task_kwargs)
        self._error_scale = 1.0  # see set_error_scale
        self._task = self._task_cls(**task_kwargs)
        self.scenario = self._task.scenario
        self.action_space = self._task.action_space
        self.observation_space = self._task.observation_space
        self._batch = LanderBatch(self._task, 1)
        self._act_shape = self.action_space.shape
        self._done = True
        self._error_rng: np.random.Generator | None = None
        self._history: list = []
        self._renderer = None

    # -- public state -----------------------------------------------------------------------------

    @property
    def state_nd(self) -> np.ndarray:
        """Current normalised state of the lander, shape (n_state,) (a copy): the simulator's
        truth, for analysis and for privileged teachers; a guidance law reads
        :attr:`navigation_state_nd`."""
        return self._batch.y[0].copy()

    @property
    def navigation_state_nd(self) -> np.ndarray:
        """The navigation solution: the state the lander's flight computer is given,
        normalised, shape (n_state,) (a copy); the observation encodes it. Without an
        uncertainty model it equals :attr:`state_nd`."""
        return self._batch.last_navigation[0].copy()

    def sensor_readings(self) -> dict[str, np.ndarray]:
        """What the lander's sensors read now: ``imu`` (d,), the accelerometers' specific
        force (m/s², guidance-frame axes) (as :meth:`LanderVectorEnv.sensor_readings`)."""
        return {k: v[0].copy() for k, v in self._batch.sensor_readings().items()}

    @property
    def episode_errors(self) -> EpisodeErrors:
        """This episode's plant and navigation errors (one row; all zero and unit scales
        without an uncertainty model): the truth, for analysis and omniscient references."""
        b = self._batch
        return b.errors.take([0]) if b.uncertain else EpisodeErrors.zeros(1)

    @property
    def t_s(self) -> float:
        """Time since the start of the episode (s)."""
        return float(self._batch.t_nd[0] * self._task.time_ref_s)

    def observation_from_state(self, state_nd: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Observations of states ``state_nd`` (B, n_state) at times ``t_s`` (B,) (s).

        Returns float32 (B, obs_dim), exactly what :meth:`step` returns for those states; the
        sensor channels (``sensors=("imu",)``) read zero, an ideal sensor of a lander that has
        flown no step from them.
        """
        y = np.atleast_2d(np.asarray(state_nd, dtype=np.float64))
        t = np.broadcast_to(np.asarray(t_s, dtype=np.float64), (len(y),))
        return self._task.observation_of_states(y, t)

    # -- protocol -------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None
              ) -> tuple[np.ndarray, dict]:
        check_reset_options(options, self._task.model.n_state, None, self._batch.uncertain)
        super().reset(seed=seed)
        y0 = self._task.initial_state(self.np_random, options)
        b = self._batch
        if b.uncertain:
            if seed is not None or self._error_rng is None:
                self._error_rng = error_stream(seed)
            e = EpisodeErrors.for_reset(self._task.uncertainty, self._error_rng,
                                        (options or {}).get("errors"))
            y0 = e.true_start(self._task, y0)[0]
            b.set_errors(0, e)
        b.set_state(0, y0)
        self._done = False
        self._history = [(self._batch.y[0].copy(), None)] if self.render_mode else []
        b = self._batch
        none = np.full(1, np.nan)
        q = b.info_arrays(none, none, np.zeros(1, dtype=bool))
        obs = b.observations(q["time_s"])[0]
        info = _single_info(q, self._task.has_target, self._task.extra_info_keys)
        if b.uncertain:
            info["state_nd"] = b.y[0].copy()
            info["navigation_state_nd"] = b.last_navigation[0].copy()
        if self.render_mode == "human":
            self.render()
        return obs, info

    def step(self, action) -> tuple[np.ndarray, float, bool, bool, dict]:
        if self._done:
            raise RuntimeError("the episode has ended (or reset() was never called); call reset()")
        if (type(action) is np.ndarray and action.shape == self._act_shape
                and (action.dtype == np.float32 or action.dtype == np.float64)):
            # the common case, checked cheaply: Python floats are the fastest finite test for
            # one lander, and the compiled control map takes float32 as it is
            if not all(map(math.isfinite, action.tolist())):
                validate_actions(action, self._act_shape)  # raises with the full message
            a = action[None]
        else:
            a = validate_actions(action, self._act_shape)[None]
        b = self._batch
        controls = self._task.controls_from_actions(a)
        # scratch results: read at once below (Python scalars), so no new arrays are needed
        out = b.step(controls, scratch=True)
        q = b.info_arrays(out["touchdown_speed_m_s"], out["miss_distance_m"], out["is_success"],
                          scratch=True, extras=out)
        obs = b.observations(q["time_s"])[0]
        terminated = out["terminated"].item()
        truncated = out["truncated"].item()
        self._done = terminated or truncated
        info = _single_info(q, self._task.has_target, self._task.extra_info_keys)
        if b.uncertain:
            info["state_nd"] = b.y[0].copy()
            info["navigation_state_nd"] = b.last_navigation[0].copy()
        if self.render_mode:
            self._history.append((b.y[0].copy(), controls[0]))
            if self.render_mode == "human":
                self.render()
        return obs, out["reward"].item(), terminated, truncated, info

    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array'")
            return None
        from .rendering import Renderer

        if self._renderer is None:
            self._renderer = Renderer(self._task, self.render_mode)
        return self._renderer.draw(self._history)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __getstate__(self):
        d = self.__dict__.copy()
        d["_renderer"] = None
        return d


class LanderVectorEnv(_TaskDescription, VectorEnv):
    """Base of the native vector envs: all N landers in one compiled integrator call per step.

    The powered flight of every active lander is one call of the compiled kernel
    (:func:`lunar_env.integrators.integrate_prepared`). Only landers whose engine stops in the
    step add work: one more batched call integrates the free falls of all of them, and a
    lander that passes a speed minimum above the cut-off speed is resumed by itself (rare).

    Autoreset: ``AutoresetMode.NEXT_STEP`` (Gymnasium's default, as ``SyncVectorEnv``): the step
    after a sub-env terminated or truncated resets it, ignores its action and returns its reset
    observation with reward 0 and ``terminated = truncated = False``.

    Seeding: ``reset(seed=s)`` seeds sub-env i with ``s + i`` (as ``SyncVectorEnv`` does), each
    sub-env keeping its own generator for its later episodes, so sub-env i replays exactly what
    a single env reset with ``seed=s + i`` and then auto-reset without seed would do, through any
    number of autoresets. ``options`` given to ``reset`` apply to every sub-env (``state_si`` /
    ``state_nd`` may also be an array (N, n_state)).

    ``parallel``: use numba's parallel kernel (default: only from
    :data:`~lunar_env.envs.core.PARALLEL_MIN_BATCH` landers; an env step is so little work per
    lander that thread start-up dominates below that). Results are identical either way.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}
    _task_cls: type = None

    def __init__(self, num_envs: int, parallel: bool | None = None, **task_kwargs: Any) -> None:
        from ..validation import require_bool, require_integer

        num_envs = require_integer("num_envs", num_envs, minimum=1)
        if parallel is not None:
            parallel = require_bool("parallel", parallel)
        task_kwargs.pop("render_mode", None)
        task_kwargs.pop("max_episode_steps", None)
        self.num_envs = int(num_envs)
        self._task_kwargs = dict(task_kwargs)
        self._error_scale = 1.0  # see set_error_scale
        self._task = self._task_cls(**task_kwargs)
        self.scenario = self._task.scenario
        self.single_action_space = self._task.action_space
        self.single_observation_space = self._task.observation_space
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.render_mode = None
        self._batch = LanderBatch(self._task, self.num_envs, parallel)
        self._rngs = [seeding.np_random(None)[0] for _ in range(self.num_envs)]
        # each sub-env's error stream (:func:`~lunar_env.uncertainty.error_stream` of its seed)
        self._error_rngs: list[np.random.Generator | None] = [None] * self.num_envs
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self._act_shape = (self.num_envs, *self.single_action_space.shape)
        self._started = False  # step() before reset() is an error, not a division by zero

    def _require_started(self) -> None:
        if not self._started:
            raise RuntimeError("step() called before reset(); call reset() first")


    @property
    def state_nd(self) -> np.ndarray:
        """Normalised states, shape (N, n_state) (a copy): the simulator's truth (see
        :attr:`LanderEnv.state_nd`)."""
        return self._batch.y.copy()

    @property
    def navigation_state_nd(self) -> np.ndarray:
        """The navigation solutions, shape (N, n_state) (a copy; see
        :attr:`LanderEnv.navigation_state_nd`)."""
        return self._batch.last_navigation.copy()

    @property
    def episode_errors(self) -> EpisodeErrors:
        """The current episodes' errors, N rows (see :attr:`LanderEnv.episode_errors`)."""
        b = self._batch
        return b.errors.take(np.arange(self.num_envs)) if b.uncertain \
            else EpisodeErrors.zeros(self.num_envs)

    @property
    def t_s(self) -> np.ndarray:
        """Episode times (s), shape (N,)."""
        return self._batch.t_nd * self._task.time_ref_s

    def observation_from_state(self, state_nd: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """As :meth:`LanderEnv.observation_from_state`."""
        y = np.atleast_2d(np.asarray(state_nd, dtype=np.float64))
        t = np.broadcast_to(np.asarray(t_s, dtype=np.float64), (len(y),))
        return self._task.observation_of_states(y, t)

    def set_states(self, idx, state_nd: np.ndarray, t_s) -> None:
        """Put landers ``idx`` at normalised states ``state_nd`` (len(idx), n_state) and episode
        clocks ``t_s`` (s); their fuel count restarts there (e.g. a start-state curriculum)."""
        idx = np.atleast_1d(np.asarray(idx, dtype=np.int64))
        self._batch.set_state(idx, np.asarray(state_nd, dtype=np.float64))
        self._batch.t_nd[idx] = np.asarray(t_s, dtype=np.float64) / self._task.time_ref_s

    def reset_landers(self, idx) -> None:
        """Start new episodes for landers ``idx`` from their own generators (same-step reset,
        as SB3 expects; Gymnasium's autoreset does it on the next step instead)."""
        for i in np.atleast_1d(np.asarray(idx, dtype=np.int64)):
            self._reset_one(int(i), None)
        self._autoreset[np.atleast_1d(np.asarray(idx, dtype=np.int64))] = False

    def observations(self) -> np.ndarray:
        """Current observations of all landers, shape (N, n_obs) float32."""
        return self._batch.observations()

    def sensor_readings(self) -> dict[str, np.ndarray]:
        """What every lander's sensors read now: ``imu`` (N, d), the accelerometers' specific
        force over the last decision (m/s², guidance-frame axes: horizontal..., up; 0 plus
        the sensor's errors at an episode's first decision), with the episode's IMU errors
        under an uncertainty model (:meth:`~lunar_env.envs.core.LanderBatch.sensor_readings`).
        A flight computer always has them; ``sensors=("imu",)`` also puts them in the
        observation."""
        return self._batch.sensor_readings()

    def step_landers(self, actions) -> dict[str, np.ndarray]:
        """Advance every lander by one decision *without* autoreset (for adapters that reset in
        the same step). Returns per-lander arrays: ``reward``, ``terminated``, ``truncated``,
        ``is_success``, ``touchdown_speed_m_s`` and ``miss_distance_m`` (NaN where undefined),
        ``fuel_used_kg``, ``altitude_m``, ``time_s``."""
        self._require_started()
        a = validate_actions(actions, self._act_shape)
        out = self._batch.step(self._task.controls_from_actions(a))
        return {"reward": out["reward"], "terminated": out["terminated"],
                "truncated": out["truncated"],
                **self._batch.info_arrays(out["touchdown_speed_m_s"], out["miss_distance_m"],
                                          out["is_success"], extras=out)}

    def _initial_state(self, i: int, options: dict | None) -> np.ndarray:
        opt = options
        if options:
            opt = {}
            for k, v in options.items():
                arr = np.asarray(v) if k in ("state_si", "state_nd") else None
                opt[k] = arr[i] if arr is not None and arr.ndim == 2 else v
        return self._task.initial_state(self._rngs[i], opt)

    def _draw_errors(self, i: int, options: dict | None = None) -> EpisodeErrors:
        if self._error_rngs[i] is None:
            self._error_rngs[i] = error_stream(None)
        return EpisodeErrors.for_reset(self._task.uncertainty, self._error_rngs[i],
                                       (options or {}).get("errors"), row=i)

    def _reset_one(self, i: int, options: dict | None) -> None:
        y0 = self._initial_state(i, options)
        b = self._batch
        if b.uncertain:
            e = self._draw_errors(i, options)
            y0 = e.true_start(self._task, y0)[0]
            b.set_errors(i, e)
        b.set_state(i, y0)

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict | None = None
              ) -> tuple[np.ndarray, dict]:
        """Reset every sub-env (see the class docstring for seeds and options).

        All-or-nothing: every initial state is computed first, so a bad row of
        ``options["state_si"]`` / ``["state_nd"]`` raises ValueError naming the row and leaves
        every lander (and every generator) as it was.
        """
        check_reset_options(options, self._task.model.n_state, self.num_envs,
                            self._batch.uncertain)
        rngs = self._rngs
        if seed is not None:
            seeds = ([seed + i for i in range(self.num_envs)] if isinstance(seed, int)
                     else list(seed))
            if len(seeds) != self.num_envs:
                raise ValueError(f"{len(seeds)} seeds given for {self.num_envs} envs")
            rngs = [seeding.np_random(s)[0] for s in seeds]
        saved = [r.bit_generator.state for r in self._rngs]
        old_rngs, self._rngs = self._rngs, rngs
        b = self._batch
        old_err = self._error_rngs
        saved_err = [None if r is None else r.bit_generator.state for r in old_err]
        if seed is not None and b.uncertain:
            self._error_rngs = [error_stream(s) for s in seeds]
        y0 = np.empty_like(b.y)
        errors = []
        try:
            for i in range(self.num_envs):
                try:
                    y0[i] = self._initial_state(i, options)
                    if b.uncertain:
                        errors.append(self._draw_errors(i, options))
                        y0[i] = errors[-1].true_start(self._task, y0[i])[0]
                except ValueError as exc:
                    raise ValueError(f"reset of sub-env {i} (row {i} of the options): {exc}"
                                     ) from None
        except BaseException:
            self._rngs = old_rngs
            for r, st in zip(self._rngs, saved, strict=True):
                r.bit_generator.state = st
            self._error_rngs = old_err
            for r, st in zip(old_err, saved_err, strict=True):
                if r is not None:
                    r.bit_generator.state = st
            raise
        for i, e in enumerate(errors):
            b.set_errors(i, e)
        b.set_state(np.arange(self.num_envs), y0)
        self._autoreset[:] = False
        self._started = True
        n = self.num_envs
        return self._observe_and_info(np.full(n, np.nan), np.full(n, np.nan), np.zeros(n, bool))

    def step(self, actions) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        self._require_started()
        a = validate_actions(actions, self._act_shape)
        controls = self._task.controls_from_actions(a)
        n = self.num_envs
        reward = np.zeros(n)
        terminated = np.zeros(n, dtype=bool)
        truncated = np.zeros(n, dtype=bool)
        speed = np.full(n, np.nan)
        miss = np.full(n, np.nan)
        success = np.zeros(n, dtype=bool)
        extra_keys = self._task.extra_info_keys
        extras = {k: np.full(n, np.nan) for k in extra_keys}
        reset_idx = np.flatnonzero(self._autoreset)
        if len(reset_idx) == 0:
            out = self._batch.step(controls)
            reward, terminated, truncated = out["reward"], out["terminated"], out["truncated"]
            speed, miss, success = (out["touchdown_speed_m_s"], out["miss_distance_m"],
                                    out["is_success"])
            extras = {k: out[k] for k in extra_keys}
        else:
            act = np.flatnonzero(~self._autoreset)
            if len(act):
                out = self._batch.step(controls[act], act)
                reward[act] = out["reward"]
                terminated[act] = out["terminated"]
                truncated[act] = out["truncated"]
                speed[act] = out["touchdown_speed_m_s"]
                miss[act] = out["miss_distance_m"]
                success[act] = out["is_success"]
                for k in extra_keys:
                    extras[k][act] = out[k]
            for i in reset_idx:
                self._reset_one(int(i), None)
        self._autoreset = terminated | truncated
        obs, info = self._observe_and_info(speed, miss, success, extras)
        return obs, reward, terminated, truncated, info

    def _observe_and_info(self, speed: np.ndarray, miss: np.ndarray, success: np.ndarray,
                          extras: dict | None = None) -> tuple[np.ndarray, dict]:
        b = self._batch
        q = b.info_arrays(speed, miss, success, extras=extras)
        obs = b.observations(q["time_s"])
        info = _vector_info(q, self._task.has_target, self._task.extra_info_keys)
        if b.uncertain:
            info["state_nd"] = b.y.copy()
            info["navigation_state_nd"] = b.last_navigation.copy()
            info["_state_nd"] = info["_navigation_state_nd"] = info["_time_s"]
        return obs, info
