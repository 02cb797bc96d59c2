"""The planar soft-landing expert and laws (``LunarSoftLanding-v0``).

- :class:`PontryaginExpert` re-solves the minimum-fuel problem by Pontryagin shooting from the
  current state (the DAgger oracle);
- :class:`PlanarReplanningLaw` flies it as a guidance law, on the navigation solution.

The replay of each case's optimum is :class:`guidance.families.planar.PlanarOpenLoopLaw`.
"""

from __future__ import annotations

import math
import time

import numpy as np

from guidance.law import GuidanceLaw, Navigation
from lunar_env import dynamics as dyn
from lunar_env.scenarios import PlanarScenario
from lunar_env.states import planar_nd_to_si
from optimizers.indirect.planar import (
    PontryaginGuess,
    PontryaginSolution,
    nominal_guess,
    solve_planar_min_fuel,
)
from optimizers.indirect.planar_system import optimal_thrust_angle
from optimizers.transcription.collocation import solve_planar_min_time_collocation

__all__ = ["PontryaginExpert", "PlanarReplanningLaw", "planar_state_si", "STATUS_OPTIMAL",
           "STATUS_HOLD", "STATUS_FALLBACK", "STATUS_CONSTRAINED"]

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

    def plan(self, row: int = 0) -> PontryaginSolution | None:
        """The plan (optimal solution from the last converged call) remembered for batch row
        ``row``, or None."""
        mem = self._memory.get(int(row))
        return None if mem is None else mem[0]

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


def planar_state_si(scenario, state_nd: np.ndarray) -> np.ndarray:
    """Normalised planar states (r, vr, θ, ω, m) -> SI rows (r m, vr m/s, θ rad, v_t m/s, m kg)
    (:func:`lunar_env.states.planar_nd_to_si` with the scenario's scaling)."""
    return planar_nd_to_si(state_nd, scenario.scaling())


class PlanarReplanningLaw(GuidanceLaw):
    """The closed-loop re-planning expert as a guidance law: one :class:`PontryaginExpert` per
    case (each re-plan warm-started from that case's previous plan), called once per decision
    of a lander still flying with its navigated SI state and its mission clock.

    Parameters
    ----------
    scenario : PlanarScenario
        The nominal scenario the expert plans with.
    **expert_kwargs
        Forwarded to :class:`PontryaginExpert`.
    """

    name = "Pontryagin re-planning"

    def __init__(self, scenario, **expert_kwargs) -> None:
        self.scenario = scenario
        self.expert_kwargs = expert_kwargs
        self.experts: list[PontryaginExpert] = []

    def reset(self, computer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        self.experts = [PontryaginExpert(self.scenario, **self.expert_kwargs)
                        for _ in range(len(case_ids))]

    def act(self, nav: Navigation) -> np.ndarray:
        for k in np.flatnonzero(nav.episode_start):  # a new episode: no plan to warm-start
            self.experts[k].reset()
        si = planar_state_si(self.scenario, nav.state_nd)
        phi = np.zeros(len(si))
        for k in np.flatnonzero(nav.active):
            phi[k] = float(self.experts[k](si[k], t_s=float(nav.t_s[k])))
        return self.computer.actions_from_controls(np.stack([phi, np.ones(len(phi))], axis=1))
