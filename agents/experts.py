"""Closed-loop experts: policies that re-plan the optimal control from the current state.

:class:`PontryaginExpert` (planar landing) re-solves the minimum-fuel problem by Pontryagin
shooting (:func:`optimizers.indirect.planar.solve_planar_min_fuel`) at every call, warm-started
from its previous plan; it is the DAgger oracle of :mod:`agents.imitation` and a row of
:mod:`agents.evaluate`. It moved here from ``optimizers.pontryagin`` (a policy is an agent, and
optimizers/ must not depend on agents/).
"""

from __future__ import annotations

import math
import time

import numpy as np

from lunar_env import dynamics as dyn
from lunar_env.scenarios import PlanarScenario
from optimizers.indirect.planar import (
    PontryaginGuess,
    PontryaginSolution,
    nominal_guess,
    optimal_thrust_angle,
    solve_planar_min_fuel,
)
from optimizers.transcription.collocation import solve_planar_min_time_collocation

__all__ = ["PontryaginExpert", "STATUS_OPTIMAL", "STATUS_HOLD", "STATUS_FALLBACK",
           "STATUS_CONSTRAINED", "PinpointPontryaginExpert", "PINPOINT_LABEL_STATUSES"]

N_STATE = len(dyn.PLANAR_STATE_NAMES)

STATUS_OPTIMAL = "optimal"
STATUS_HOLD = "hold"
STATUS_FALLBACK = "fallback"
STATUS_CONSTRAINED = "constrained"


class PontryaginExpert:
    """Closed-loop re-planning expert: the optimal thrust angle *now*, from the current state.

    Each call re-solves the minimum-fuel problem from the given state (warm-started from this
    expert's previous solution for the same batch row, advanced to the current time) and returns
    φ*(0) of the new solution. Usable as a DAgger expert or as a guidance law in an env loop.

    Behaviour per row, reported in :attr:`last_status`:

    * ``"optimal"``: the shooting converged; φ is the optimal angle from this state.
    * ``"hold"``: less than ``hold_time_s`` of the previous plan is left. Shooting is
      ill-conditioned as the time to go vanishes, so the previous plan's angle at the current
      time is returned (open-loop over the last seconds).
    * ``"constrained"``: the unconstrained extremal passes below the surface; φ comes from a
      coarse collocation with the path constraint r ≥ surface radius (a direct method, ~0.1 s).
      Not remembered as a warm start.
    * ``"fallback"``: no extremal from this state (e.g. too low or too fast to land, or not
      enough propellant): best effort, full braking along the negative relative velocity,
      φ = atan2(−v, v_t) (straight up, φ = π/2, when the lander is at rest).

    Time since the previous call: ``t_s`` (mission time of the state) when given, otherwise
    the mass clock Δt = Δm/ṁ (constant thrust). A mass *higher* than at the previous call, or
    :meth:`reset`, starts a new episode (warm start from the nominal optimum again).

    Parameters
    ----------
    scenario : PlanarScenario
    n_steps, n_jac_steps : int
        Grids of :func:`solve_planar_min_fuel` (coarser than the certification defaults: the
        angle is what matters here).
    tol : float
        Shooting tolerance.
    hold_time_s : float
        See ``"hold"`` above.
    """

    def __init__(self, scenario: PlanarScenario, *, n_steps: int = 200, n_jac_steps: int = 40,
                 tol: float = 1e-11, hold_time_s: float = 3.0) -> None:
        if not isinstance(scenario, PlanarScenario):
            raise TypeError(f"scenario must be a PlanarScenario, got {type(scenario).__name__}")
        if not (math.isfinite(hold_time_s) and hold_time_s >= 0):
            raise ValueError(f"hold_time_s = {hold_time_s!r} must be finite and >= 0")
        self.scenario = scenario
        self.n_steps = int(n_steps)
        self.n_jac_steps = int(n_jac_steps)
        self.tol = float(tol)
        self.hold_time_s = float(hold_time_s)
        self._flow_kg_s = scenario.vehicle.mass_flow_kg_s
        self._memory: dict[int, tuple[PontryaginSolution, float | None, float]] = {}
        self.last_status: list[str] = []
        self.last_fuel_to_go_kg = np.empty(0)
        self.last_solve_s = np.empty(0)

    def reset(self) -> None:
        """Forget previous solutions (start of a new episode)."""
        self._memory.clear()

    def __call__(self, state_si, t_s=None):
        """Optimal thrust angle (rad) from SI state(s).

        Parameters
        ----------
        state_si : array_like, shape (5,) or (B, 5)
            (r m, vr m/s, θ rad, v_t m/s, m kg).
        t_s : float or array_like of shape (B,), optional
            Mission time of the state(s) (s); see the class docstring.

        Returns
        -------
        float (for one state) or ndarray, shape (B,)

        Raises
        ------
        ValueError
            Wrong shape or non-finite state or time.
        """
        arr = np.asarray(state_si, dtype=np.float64)
        single = arr.ndim == 1
        rows = np.atleast_2d(arr)
        if rows.ndim != 2 or rows.shape[1] != 5:
            raise ValueError(f"state_si has shape {arr.shape}; expected (5,) or (B, 5) rows "
                             "(r m, vr m/s, θ rad, v_t m/s, m kg)")
        if not np.all(np.isfinite(rows)):
            raise ValueError("state_si must be finite")
        if t_s is None:
            times = [None] * len(rows)
        else:
            tt = np.broadcast_to(np.asarray(t_s, dtype=np.float64), (len(rows),))
            if not np.all(np.isfinite(tt)):
                raise ValueError(f"t_s = {t_s!r} must be finite")
            times = [float(v) for v in tt]
        phi = np.empty(len(rows))
        status = []
        fuel = np.full(len(rows), np.nan)
        wall = np.empty(len(rows))
        for b, row in enumerate(rows):
            t0 = time.perf_counter()
            phi[b], st, fuel[b] = self._act(b, row, times[b])
            wall[b] = time.perf_counter() - t0
            status.append(st)
        self.last_status = status
        self.last_fuel_to_go_kg = fuel
        self.last_solve_s = wall
        return float(phi[0]) if single else phi

    @staticmethod
    def braking_angle(state_si: np.ndarray) -> float:
        """φ that points the thrust against the relative velocity (π/2 at rest)."""
        vr, vt = float(state_si[1]), float(state_si[3])
        if math.hypot(vr, vt) < 1e-9:
            return 0.5 * math.pi
        return math.atan2(-vr, vt)

    def _act(self, b: int, row: np.ndarray, t: float | None) -> tuple[float, str, float]:
        sc = self.scenario
        if row[0] <= 0.0 or row[4] <= sc.vehicle.dry_mass_kg:
            return self.braking_angle(row), STATUS_FALLBACK, math.nan
        prev = self._memory.get(b)
        guess: PontryaginGuess | None = None
        if prev is not None:
            sol_prev, t_prev, m_prev = prev
            if row[4] > m_prev + 1e-9:  # mass went up: a new episode
                self._memory.pop(b)
            else:
                if t is not None and t_prev is not None:
                    elapsed = t - t_prev
                else:
                    elapsed = (m_prev - row[4]) / self._flow_kg_s
                elapsed = min(max(elapsed, 0.0), sol_prev.tf_s)
                remaining = sol_prev.tf_s - elapsed
                if remaining <= self.hold_time_s:
                    return (sol_prev.thrust_angle_at(elapsed), STATUS_HOLD,
                            remaining * self._flow_kg_s)
                z = sol_prev.state_costate_at(elapsed)[0]
                guess = PontryaginGuess(z[N_STATE:], float(sc.scaling().time_nd(remaining)),
                                        z[:N_STATE])
        if guess is None:
            guess = nominal_guess(sc, self.n_steps)
        sol = solve_planar_min_fuel(sc, row, guess=guess, n_steps=self.n_steps,
                                    n_jac_steps=self.n_jac_steps, tol=self.tol, check="grid")
        if not sol.success:
            if "below the surface" in sol.message:
                # The unconstrained extremal dips under the ground: plan with r >= surface.
                col = solve_planar_min_time_collocation(
                    sc, row, n_intervals=30, tol=1e-8, min_radius_m=sc.surface_radius_m)
                if col.success and col.fuel_kg < row[4] - sc.vehicle.dry_mass_kg:
                    return float(col.phi_rad[0]), STATUS_CONSTRAINED, col.fuel_kg
            return self.braking_angle(row), STATUS_FALLBACK, math.nan
        self._memory[b] = (sol, t, float(row[4]))
        return float(optimal_thrust_angle(sol.x0_nd, sol.costates0)), STATUS_OPTIMAL, sol.fuel_kg


#: statuses of :class:`PinpointPontryaginExpert` decisions that are the extremal's law, hence
#: labels; "stale" and "fallback" (no converged solve) are guesses and are not
PINPOINT_LABEL_STATUSES = ("optimal", "nearest", "hold")


class PinpointPontryaginExpert:
    """Closed-loop optimal feedback for ``LunarPinpointLanding-v*``: at every decision the
    minimum-time extremal from the lander's current state (:class:`optimizers.indirect.
    pinpoint_feedback.PinpointFeedback`, compiled Pontryagin shooting warm-started from the
    previous decision's extremal, ~1-15 ms), flown over the env step as its mean angle.

    A policy for :func:`agents.evaluate.compare` (``reset`` / ``act``), and the labeller of the
    pinpoint datasets and of DAgger (:meth:`label`). Where the target is out of reach (a lander too
    fast to stop at it), the extremal to the nearest reachable stop on the track is flown;
    the per-decision statuses are counted in :attr:`status_counts`.

    Parameters
    ----------
    scenario : PinpointScenario
    feedback_kwargs : forwarded to :class:`PinpointFeedback` (``step_s``, ``hold_s``, ...).
    """

    name = "Pontryagin feedback expert"

    def __init__(self, scenario, **feedback_kwargs) -> None:
        from optimizers.indirect.pinpoint_feedback import PinpointFeedback

        self.scenario = scenario
        self.feedback = PinpointFeedback(scenario, **feedback_kwargs)
        self.status_counts: dict[str, int] = {}
        #: landers still flying (set by agents.evaluate.rollout; None: all)
        self.active: np.ndarray | None = None

    def reset(self, venv=None, case_ids=None) -> None:
        self.feedback.reset()

    def angles(self, states_nd: np.ndarray, t_s: np.ndarray, dt_s: float,
               active: np.ndarray | None = None) -> np.ndarray:
        """(α, β) (rad), (B, 2), of the extremals from states (B, 7) at episode times (B,)."""
        ang = self.feedback(states_nd, t_s, dt_s, active)
        act = np.ones(len(ang), dtype=bool) if active is None else np.asarray(active, bool)
        for st, a in zip(self.feedback.last_status, act, strict=True):
            if a:
                self.status_counts[st] = self.status_counts.get(st, 0) + 1
        return ang

    def label(self, venv, active: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The expert's decision at the current states of the (vector) env ``venv``.

        Returns ``(angles, actions, is_label)``: (α, β) (rad) and the env actions (float32),
        both (B, 2), and (B,) bool: the row is active (``active``, else :attr:`active`, else
        all) and its status is one of :data:`PINPOINT_LABEL_STATUSES`.
        """
        from lunar_env.envs.pinpoint_landing import action_from_angles

        core = getattr(venv, "unwrapped", venv)
        self.match_gate(core)
        rows = self.active if active is None else active
        ang = self.angles(core.state_nd, core.t_s, float(core.dt_s), rows)
        sc = core.scenario
        actions = action_from_angles(ang[:, 0], ang[:, 1], sc.alpha_bounds_rad,
                                     sc.beta_bounds_rad).astype(np.float32)
        is_label = np.isin(np.asarray(self.last_status), PINPOINT_LABEL_STATUSES)
        if rows is not None:
            is_label &= np.asarray(rows, dtype=bool)
        return ang, actions, is_label

    def act(self, obs: np.ndarray, venv, active: np.ndarray | None = None) -> np.ndarray:
        return self.label(venv, active)[1]

    def match_gate(self, env) -> None:
        """Keep the extremals above the gate where ``env`` counts it (its ``gate_range_m``:
        near the target in v2, everywhere in v0/v1)."""
        if hasattr(env, "gate_range_m"):
            self.feedback.gate_floor_range_m = env.gate_range_m

    @property
    def last_status(self) -> list[str]:
        return self.feedback.last_status
