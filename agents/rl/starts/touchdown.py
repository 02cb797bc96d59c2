"""The touchdown family's curriculum starts (``LunarPinpointLanding-v3``): states along the
certified optimal landings of dispersed cases, and their position and velocity perturbation."""

from __future__ import annotations

import numpy as np

from agents.rl.starts.pinpoint import PinpointStarts

__all__ = ["TouchdownStarts", "MIN_ALTITUDE_KEPT"]

#: a perturbed start keeps at least this fraction of its unperturbed altitude (a choice: a
#: position error drawn for the start never puts the lander at or under the surface it is to
#: land on, where its episode would end before its first decision)
MIN_ALTITUDE_KEPT = 0.5


class TouchdownStarts(PinpointStarts):
    """Start states of the pinpoint landing to touchdown."""

    #: the env the optimal landings are flown in (the family's)
    env_id = "LunarPinpointLanding-v3"

    def start_pool(self, scenario, n_trajectories: int, seed: int, n_points: int = 101,
                   progress: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """States along the certified optimum of each dispersed start
        (:func:`optimizers.optimum.touchdown.touchdown_optima`: two methods that agree, ~1 s a
        case, cached on disk), flown open loop in the env at its 1 s decisions (each step the
        optimum's mean control, :class:`guidance.laws.touchdown_baselines.
        TouchdownOpenLoopLaw`): ``n_points`` decisions equally spaced in each flight (touchdown
        excluded), shape (n_ok, n_points, 7), and their times (s). The flown states are the
        env's own, within the 1 s hold's error of the optimum (0.7 m and 2.4 m/s at touchdown at
        most over 39 dispersed cases, less before)."""
        from guidance.flight import fly
        from guidance.laws.touchdown_baselines import TouchdownOpenLoopLaw
        from optimizers.optimum.touchdown import touchdown_optima

        s = scenario.scaling()
        rows = scenario.sample_initial(np.random.default_rng(seed), int(n_trajectories))
        x0 = np.array([scenario.state_nd(r, scaling=s) for r in rows])
        optima = touchdown_optima(scenario, x0, progress=progress)
        ok = [i for i, o in enumerate(optima) if o.success]
        if not ok:
            raise RuntimeError("no certified optimal landing; cannot build the curriculum")
        out = fly(self.env_id, TouchdownOpenLoopLaw([optima[i] for i in ok]), len(ok),
                  seed=0, env_kwargs={"scenario": scenario, "dt_s": 1.0},
                  reset_options={"state_nd": x0[ok]}, record=range(len(ok)))
        states, times = [], []
        for k in range(len(ok)):
            rec = out.records[k]
            keep = np.round(np.linspace(0, len(rec["t_s"]) - 1, int(n_points))).astype(int)
            states.append(rec["state_nd"][keep])
            times.append(rec["t_s"][keep])
        return np.asarray(states), np.asarray(times)

    def start_noise_nd(self, scenario, noise: dict[str, float]) -> tuple[float, float, float]:
        """The pinpoint family's ``{position_m, velocity_m_s}`` as normalised standard
        deviations, and the landing surface's normalised radius (:meth:`perturb_starts` keeps
        the starts above it)."""
        from optimizers.optimum.touchdown import touchdown_ocp

        sig_r, sig_v = super().start_noise_nd(scenario, noise)
        return sig_r, sig_v, float(np.linalg.norm(touchdown_ocp(scenario).target_position_nd))

    def perturb_starts(self, states_nd: np.ndarray, sigma_nd: tuple[float, float, float],
                       rng: np.random.Generator) -> np.ndarray:
        """Gaussian position and velocity errors (σ from :meth:`start_noise_nd`) added to
        curriculum starts (M, 7), each start then kept at :data:`MIN_ALTITUDE_KEPT` of its
        unperturbed altitude or above (moved along its radius); a copy."""
        sig_r, sig_v, r_surface = sigma_nd
        x = np.asarray(states_nd, dtype=np.float64)
        y = super().perturb_starts(x, (sig_r, sig_v), rng)
        floor = r_surface + MIN_ALTITUDE_KEPT * (np.linalg.norm(x[:, 0:3], axis=1) - r_surface)
        r = np.linalg.norm(y[:, 0:3], axis=1)
        low = r < floor
        y[low, 0:3] *= (floor[low] / r[low])[:, None]
        return y
