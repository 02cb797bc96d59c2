"""Reward ranking of the pinpoint env: does the fuel-optimal landing earn the best return?

Flies reference strategies from the nominal start of a ``LunarPinpointLanding`` env and prints
their returns (undiscounted and discounted), gate speed, miss distance, fuel and the env's
success verdict:

- the Pontryagin feedback law (:class:`guidance.laws.pontryagin_pinpoint.
  PinpointPontryaginExpert`: the extremal
  re-solved from every state, the optimum in closed loop);
- [001]'s optimum (GPM + direct shooting) replayed open loop, its law averaged over each step;
- the local optima a learner may fall into: diving (α at its lower bound), braking along the
  track (α = 0), climbing / hovering (α high), flying past (the optimal law with α + 20°),
  short (α − 5°), and the best of 20 uniformly random policies.

The reward is right for RL when the closed-loop optimum ranks first and every failure below
the optimum's open-loop replay. The column "with success bonus" adds the terminal reward that
PPO's ``reward_shaping.success_bonus`` pays a success (:mod:`agents.rl.shaping`; the potential
part of the shaping is the same −Φ(s₀) for every strategy from one start, up to discounting).
``python -m agents.rl.reward_ranking --env LunarPinpointLanding-v2`` prints the table
(``--json
FILE`` also writes it); ``tests/test_env_pinpoint.py`` (slow) asserts the ranking.
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = ["rank_strategies", "markdown_table", "main"]

#: the default discount of the table's "discounted" column (the 1 s PPO entries' γ)
DEFAULT_GAMMA = 0.999


def _fly(env, policy: Callable[[int], np.ndarray], gamma: float, bonus: float
         ) -> dict[str, Any]:
    env.reset(options={"nominal": True})
    ret = disc = 0.0
    k = 0
    info: dict[str, Any] = {}
    while True:
        _, r, term, trunc, info = env.step(policy(k))
        ret += float(r)
        disc += gamma ** k * float(r)
        k += 1
        if term or trunc:
            break
    success = bool(info.get("is_success", False))
    return {"return": ret, "discounted": disc, "return_with_bonus": ret + bonus * success,
            "gate_speed_m_s": float(info.get("touchdown_speed_m_s", math.nan)),
            "miss_m": float(info.get("miss_distance_m", math.nan)),
            "fuel_kg": float(info.get("fuel_used_kg", math.nan)),
            "success": success, "steps": k}


def rank_strategies(env_id: str = "LunarPinpointLanding-v2", *, n_random: int = 20,
                    gamma: float = DEFAULT_GAMMA, seed: int = 0,
                    env_kwargs: dict[str, Any] | None = None,
                    success_bonus: float | str | None = "auto") -> dict[str, dict[str, Any]]:
    """Fly the reference strategies from the nominal start; ``{name: metrics}`` in table order.

    Metrics: ``return``, ``discounted`` (Σ γᵏ rₖ), ``return_with_bonus`` (the return plus
    ``success_bonus``, :func:`agents.rl.shaping.resolve_success_bonus`, for a success),
    ``gate_speed_m_s``, ``miss_m``, ``fuel_kg``, ``success``, ``steps``. Raises
    ``ValueError`` for an env that is not a pinpoint env.
    """
    import gymnasium as gym

    import lunar_env  # noqa: F401
    from agents.rl.shaping import resolve_success_bonus
    from guidance.law import FlightComputer
    from guidance.laws.pontryagin_pinpoint import PinpointPontryaginExpert
    from lunar_env.envs.pinpoint_landing import action_from_angles, angles_from_action
    from lunar_env.families import family_name
    from optimizers.reproduce.peng2012 import get_solver

    if not 0.0 < gamma <= 1.0:
        raise ValueError(f"gamma={gamma}: must be in (0, 1]")
    env = gym.make(env_id, **(env_kwargs or {})).unwrapped
    scenario = env.scenario
    if family_name(scenario) != "pinpoint":  # the strategies below are 3D ones
        raise ValueError(f"{env_id!r} is not a pinpoint env (scenario {scenario.name!r})")
    solver = get_solver(scenario)
    solver.build()
    nominal = solver.solve()
    ssol = nominal.extra["shooting_solution"]
    law = ssol.control_law()
    t_ref = solver.ocp.scaling.time_s
    dt = float(env.dt_s)
    ab, bb = scenario.alpha_bounds_rad, scenario.beta_bounds_rad
    bonus = resolve_success_bonus(success_bonus, env.success_thresholds)

    def optimal(k: int) -> np.ndarray:  # the law averaged over the step (8 midpoints)
        ts = (k + (np.arange(8) + 0.5) / 8) * dt
        u = law(np.minimum(ts / t_ref, ssol.tf_nd)[None, :])[0].mean(axis=0)
        return action_from_angles(u[0], u[1], ab, bb).astype(np.float32)

    def shifted(d_alpha_deg: float) -> Callable[[int], np.ndarray]:
        def policy(k: int) -> np.ndarray:
            al, be = angles_from_action(optimal(k).astype(np.float64), ab, bb)
            return action_from_angles(al + math.radians(d_alpha_deg), be, ab, bb
                                      ).astype(np.float32)
        return policy

    expert = PinpointPontryaginExpert(scenario)

    def feedback(k: int) -> np.ndarray:
        # the nominal world: the lander's state is its navigation solution
        if k == 0:
            expert.reset(FlightComputer.of(env, env_id), np.arange(1))
        return expert.labels(env.state_nd[None], np.array([env.t_s]))[1][0]

    def constant(alpha_rad: float) -> Callable[[int], np.ndarray]:
        a = action_from_angles(alpha_rad, math.pi, ab, bb).astype(np.float32)
        return lambda k: a

    out = {"Pontryagin feedback (closed loop)": _fly(env, feedback, gamma, bonus),
           f"optimum, open loop ({dt:g} s holds)": _fly(env, optimal, gamma, bonus),
           "diving (α at its lower bound)": _fly(env, constant(ab[0]), gamma, bonus),
           "braking along the track (α = 0)": _fly(env, constant(0.0), gamma, bonus),
           "climbing / hovering (α at its upper bound)": _fly(env, constant(ab[1]), gamma, bonus),
           "flying past (optimal α + 20°)": _fly(env, shifted(20.0), gamma, bonus),
           "short (optimal α − 5°)": _fly(env, shifted(-5.0), gamma, bonus)}
    rng = np.random.default_rng(seed)
    rand = [_fly(env, lambda k: rng.uniform(-1, 1, 2).astype(np.float32), gamma, bonus)
            for _ in range(int(n_random))]
    if rand:
        out[f"best of {len(rand)} random"] = max(rand, key=lambda m: m["return"])
    env.close()
    return out


def markdown_table(ranking: dict[str, dict[str, Any]]) -> str:
    """The ranking as a Markdown table, best return first."""
    def f(x: float, spec: str) -> str:
        return "–" if not math.isfinite(x) else format(x, spec)

    lines = ["| strategy | return | discounted | with success bonus | gate speed (m/s) | "
             "miss (km) | fuel (kg) | success |", "|---|---|---|---|---|---|---|---|"]
    for name, m in sorted(ranking.items(), key=lambda kv: -kv[1]["return"]):
        lines.append(f"| {name} | {m['return']:.2f} | {m['discounted']:.2f} | "
                     f"{m['return_with_bonus']:.2f} | "
                     f"{f(m['gate_speed_m_s'], '.2f')} | {f(m['miss_m'] / 1e3, '.3f')} | "
                     f"{f(m['fuel_kg'], '.1f')} | {m['success']} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m agents.rl.reward_ranking",
                                description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--env", default="LunarPinpointLanding-v2")
    p.add_argument("--gamma", type=float, default=DEFAULT_GAMMA)
    p.add_argument("--n-random", type=int, default=20)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", default=None, help="also write the ranking as JSON")
    args = p.parse_args(argv)
    ranking = rank_strategies(args.env, n_random=args.n_random, gamma=args.gamma,
                              seed=args.seed)
    print(f"{args.env}, nominal start, γ = {args.gamma}:\n")
    print(markdown_table(ranking))
    if args.json:
        from agents.common.runs import write_text_atomic

        write_text_atomic(args.json, json.dumps({"env_id": args.env, "gamma": args.gamma,
                                                 "ranking": ranking}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
