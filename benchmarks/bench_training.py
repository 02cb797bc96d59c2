"""PPO training throughput: our native batched vector env vs ``SubprocVecEnv`` of single envs.

Both runs use the same PPO hyperparameters (the shipped ``LunarSoftLanding-v0`` entry of
``agents/hyperparams/ppo.yml``, or its ``@quick`` profile sizes with ``--quick``), the same
number of envs and the same seed; the only difference is how the envs are stepped:

- ``native``: :func:`agents.common.vec_env.make_sb3_vec_env` — all landers advanced in one call of
the
  compiled dynamics core (what ``train.py`` uses);
- ``subproc``: SB3 ``SubprocVecEnv`` of ``gym.make(env_id)`` single envs (one process each,
  the usual way to parallelise Gymnasium envs for SB3).

Reported: environment steps per second during ``model.learn`` (rollout collection *and* the
gradient updates, i.e. what a user waits for), the rollout-only rate, and the ratio
native / subproc. With other processes on the cores the absolute numbers are noisy; the
ratio is from the same run.

    python benchmarks/bench_training.py [--quick] [--json FILE] [--n-timesteps N] [--n-envs K]
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

ENV_ID = "LunarSoftLanding-v0"


def _hp(n_envs: int | None):
    from agents.hyperparams import default_hyperparams_path, load_hyperparams, resolve_algo_kwargs

    hp = load_hyperparams(default_hyperparams_path("ppo"), ENV_ID)
    if n_envs is not None:
        hp["n_envs"] = int(n_envs)
    kwargs = resolve_algo_kwargs(hp, "ppo")
    return hp, kwargs


def _time_ppo(venv, kwargs, n_timesteps: int, seed: int) -> dict:
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecNormalize

    class RolloutTimer(BaseCallback):
        def __init__(self):
            super().__init__()
            self.rollout_s = 0.0
            self._t = None

        def _on_rollout_start(self):
            self._t = time.perf_counter()

        def _on_rollout_end(self):
            self.rollout_s += time.perf_counter() - self._t

        def _on_step(self):
            return True

    venv = VecNormalize(venv, gamma=kwargs.get("gamma", 0.99))
    model = PPO("MlpPolicy", venv, seed=seed, device="cpu", verbose=0, **kwargs)
    # warm-up: one rollout + update (numba kernels, torch lazy init, subprocess start)
    model.learn(total_timesteps=model.n_steps * venv.num_envs)
    timer = RolloutTimer()
    t0 = time.perf_counter()
    model.learn(total_timesteps=n_timesteps, callback=timer, reset_num_timesteps=True)
    wall = time.perf_counter() - t0
    steps = model.num_timesteps
    venv.close()
    return {"steps": int(steps), "wall_s": wall, "steps_per_s": steps / wall,
            "rollout_s": timer.rollout_s,
            "rollout_steps_per_s": steps / timer.rollout_s if timer.rollout_s else float("nan")}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--quick", action="store_true", help="short run (CI)")
    p.add_argument("--json", default=None, help="write the results to this JSON file")
    p.add_argument("--n-timesteps", type=int, default=None)
    p.add_argument("--n-envs", type=int, default=None,
                   help="envs in both runs (default: the shipped config's n_envs; 8 with --quick)")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)

    import torch
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    import lunar_env  # noqa: F401
    from agents.common.vec_env import make_sb3_vec_env

    torch.set_num_threads(1)
    n_envs = args.n_envs or (8 if args.quick else None)
    hp, kwargs = _hp(n_envs)
    n_envs = hp["n_envs"]
    if args.quick:
        kwargs.update(n_steps=128, batch_size=256, n_epochs=2)
    n_timesteps = args.n_timesteps or (4 if args.quick else 20) * kwargs["n_steps"] * n_envs
    print(f"PPO on {ENV_ID} {hp.get('env_kwargs') or ''}: {n_envs} envs, "
          f"n_steps={kwargs['n_steps']}, "
          f"n_epochs={kwargs['n_epochs']}, batch_size={kwargs['batch_size']}, "
          f"{n_timesteps} timed steps (after one warm-up rollout)")
    env_kwargs = dict(hp.get("env_kwargs") or {})
    native = _time_ppo(make_sb3_vec_env(ENV_ID, n_envs, seed=args.seed, **env_kwargs), kwargs,
                       n_timesteps, args.seed)
    print(f"  native batched vector env : {native['steps_per_s']:8.0f} steps/s "
          f"(rollout only {native['rollout_steps_per_s']:8.0f} steps/s)")
    # "lunar_env:" makes each subprocess import (and register) the package
    sub = _time_ppo(make_vec_env(f"lunar_env:{ENV_ID}", n_envs=n_envs, seed=args.seed,
                                 env_kwargs=env_kwargs,
                                 vec_env_cls=SubprocVecEnv,
                                 vec_env_kwargs={"start_method": "forkserver"}),
                    kwargs, n_timesteps, args.seed)
    print(f"  SubprocVecEnv, single envs: {sub['steps_per_s']:8.0f} steps/s "
          f"(rollout only {sub['rollout_steps_per_s']:8.0f} steps/s)")
    ratio = native["steps_per_s"] / sub["steps_per_s"]
    ratio_roll = native["rollout_steps_per_s"] / sub["rollout_steps_per_s"]
    print(f"  ratio native / subproc    : {ratio:8.2f}x training, {ratio_roll:.2f}x rollout")
    out = {"env_id": ENV_ID, "env_kwargs": env_kwargs, "n_envs": n_envs, "n_timesteps": n_timesteps,
           "ppo": {k: kwargs[k] for k in ("n_steps", "batch_size", "n_epochs")},
           "native": native, "subproc": sub, "ratio_training": ratio,
           "ratio_rollout": ratio_roll, "quick": bool(args.quick),
           "machine": {"python": platform.python_version(), "processor": platform.processor(),
                       "note": "shared machine; timings are noisy"}}
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
