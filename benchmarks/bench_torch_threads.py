"""PPO training on 1 against 2 torch threads: rollout and update time of the shipped entries.

Does training use what the machine has? ``train.py`` sets ``torch.set_num_threads`` from
``--torch-threads`` (default 1). This benchmark trains the shipped PPO entry of each env (the
hyperparameters, observation features and reward shaping of ``agents/hyperparams/ppo.yml``;
no start-state curriculum and no checkpoint selection, which cost the same under both settings)
with 1 and with 2 torch threads, in alternating rounds (1, 2, 1, 2, ...) so that other work on
the machine hits both alike, and reports per setting the time spent collecting rollouts (env
stepping and the policy's forward passes) and the time spent in the gradient updates, as the
median over the rounds, with the ratios 2 threads / 1 thread (< 1: two threads are faster).

    python benchmarks/bench_torch_threads.py [--quick] [--json FILE] [--env ID ...]
                                             [--rollouts K] [--rounds R]

Run it on an otherwise idle machine: with another job on the second core, a second torch
thread only waits for it.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

ENV_IDS = ("LunarSoftLanding-v0", "LunarPinpointLanding-v2")


def _entry(env_id: str, quick: bool) -> tuple[dict, dict]:
    """The shipped PPO entry of ``env_id`` (its ``@quick`` sizes with ``quick``) and its SB3
    keyword arguments."""
    from agents.hyperparams import default_hyperparams_path, load_hyperparams, resolve_algo_kwargs

    hp = load_hyperparams(default_hyperparams_path("ppo"), env_id)
    if quick:
        hp.update(n_envs=8, n_steps=128, batch_size=256, n_epochs=2)
    return hp, resolve_algo_kwargs(hp, "ppo")


def _time_round(env_id: str, hp: dict, kwargs: dict, threads: int, rollouts: int,
                seed: int) -> dict:
    """One training of ``rollouts`` rollouts + updates on ``threads`` torch threads (after one
    untimed warm-up rollout and update): seconds in rollouts and in updates."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecNormalize

    from agents.rl.training import make_training_env

    class PhaseTimer(BaseCallback):
        """Rollout = on_rollout_start .. on_rollout_end; update = on_rollout_end .. the next
        on_rollout_start (or the end of ``learn``)."""

        def __init__(self) -> None:
            super().__init__()
            self.rollout_s = self.update_s = 0.0
            self._t: float | None = None

        def _on_rollout_start(self) -> None:
            now = time.perf_counter()
            if self._t is not None:
                self.update_s += now - self._t
            self._t = now

        def _on_rollout_end(self) -> None:
            now = time.perf_counter()
            self.rollout_s += now - self._t
            self._t = now

        def _on_training_end(self) -> None:
            self.update_s += time.perf_counter() - self._t

        def _on_step(self) -> bool:
            return True

    torch.set_num_threads(threads)
    venv = make_training_env(env_id, hp["n_envs"], seed, hp.get("env_kwargs"),
                             progress=False, obs_features=hp.get("obs_features"),
                             reward_shaping=hp.get("reward_shaping"),
                             gamma=float(hp.get("gamma", 0.99)))
    venv = VecNormalize(venv, gamma=kwargs.get("gamma", 0.99))
    model = PPO("MlpPolicy", venv, seed=seed, device="cpu", verbose=0, **kwargs)
    per_rollout = model.n_steps * venv.num_envs
    model.learn(total_timesteps=per_rollout)  # warm-up: numba cache, torch lazy init
    timer = PhaseTimer()
    model.learn(total_timesteps=rollouts * per_rollout, callback=timer,
                reset_num_timesteps=True)
    venv.close()
    steps = model.num_timesteps
    return {"steps": int(steps), "rollout_s": timer.rollout_s, "update_s": timer.update_s,
            "steps_per_s": steps / (timer.rollout_s + timer.update_s)}


def _median(rounds: list[dict], key: str) -> float:
    return statistics.median(r[key] for r in rounds)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--quick", action="store_true", help="short run (CI): @quick sizes")
    p.add_argument("--json", default=None, help="write the results to this JSON file")
    p.add_argument("--env", nargs="+", default=list(ENV_IDS), choices=ENV_IDS)
    p.add_argument("--rollouts", type=int, default=None,
                   help="timed rollouts per round (default 10; 2 with --quick)")
    p.add_argument("--rounds", type=int, default=None,
                   help="rounds per setting, alternating (default 3; 1 with --quick)")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    rollouts = args.rollouts or (2 if args.quick else 10)
    n_rounds = args.rounds or (1 if args.quick else 3)
    for name, v in (("--rollouts", rollouts), ("--rounds", n_rounds)):
        if v < 1:
            raise SystemExit(f"{name} = {v} is not allowed; it must be >= 1")

    import lunar_env  # noqa: F401

    out: dict = {"rollouts": rollouts, "rounds": n_rounds, "quick": bool(args.quick), "envs": {},
                 "machine": {"python": platform.python_version(),
                             "processor": platform.processor(),
                             "load_at_start": list(_loadavg())}}
    for env_id in args.env:
        hp, kwargs = _entry(env_id, args.quick)
        print(f"PPO on {env_id} {hp.get('env_kwargs') or ''}: {hp['n_envs']} envs, n_steps="
              f"{kwargs['n_steps']}, n_epochs={kwargs['n_epochs']}, batch_size="
              f"{kwargs['batch_size']}, net {kwargs.get('policy_kwargs', {}).get('net_arch')}; "
              f"{n_rounds} round(s) of {rollouts} rollouts per setting")
        rounds: dict[int, list[dict]] = {1: [], 2: []}
        for _ in range(n_rounds):
            for threads in (1, 2):
                rounds[threads].append(_time_round(env_id, hp, kwargs, threads, rollouts,
                                                   args.seed))
        res = {}
        for threads in (1, 2):
            res[threads] = {k: _median(rounds[threads], k)
                            for k in ("rollout_s", "update_s", "steps_per_s")}
            print(f"  {threads} thread(s): rollouts {res[threads]['rollout_s']:7.2f} s, updates "
                  f"{res[threads]['update_s']:7.2f} s, {res[threads]['steps_per_s']:8.0f} steps/s")
        ratios = {k: res[2][k] / res[1][k] for k in ("rollout_s", "update_s")}
        ratios["training_time"] = res[1]["steps_per_s"] / res[2]["steps_per_s"]
        print(f"  2 threads / 1 thread: rollout time x{ratios['rollout_s']:.2f}, update time "
              f"x{ratios['update_s']:.2f}, training time x{ratios['training_time']:.2f} "
              "(< 1: two threads faster)")
        out["envs"][env_id] = {"one_thread": res[1], "two_threads": res[2], "ratios": ratios,
                               "rounds": {str(k): v for k, v in rounds.items()}}
    out["machine"]["load_at_end"] = list(_loadavg())
    if args.json:
        from optimizers.common.checkpoint import atomic_write_bytes

        atomic_write_bytes(args.json, json.dumps(out, indent=1).encode())
    return 0


def _loadavg() -> tuple[float, float, float]:
    try:
        import os

        return os.getloadavg()
    except OSError:  # not available on this platform
        return (float("nan"),) * 3


if __name__ == "__main__":
    raise SystemExit(main())
