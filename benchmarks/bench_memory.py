"""Training throughput of the policies with memory, as ratios to the PPO MLP timed in the same run.

One run trains, for the same number of env steps each, on ``LunarPinpointLanding-v2`` under the
``standard`` plant and navigation errors, with the native batched vector env (32 landers) and
one torch thread:

- ``PPO MLP``: the shipped PPO entry (``agents/hyperparams/ppo.yml``: 4096-step rollouts, 10
  epochs of 1024-step minibatches, 128x128 tanh networks, the observation features and the
  reward shaping);
- ``PPO, 8-frame history``: the same with ``history: 8`` (the last 8 inputs and actions,
  :mod:`agents.features.history`);
- ``RecurrentPPO, LSTM 64``: the shipped ``agents/hyperparams/recurrent-ppo.yml`` entry (the
  same settings, the MLPs fed by an LSTM of 64 in actor and critic;
  :class:`agents.common.recurrent.SequenceLstmPolicy`).

With ``--variants`` it also trains the recurrent configurations that trade cost for capacity or
update work: sb3-contrib's own ``MlpLstmPolicy`` (the LSTM stepped one time step at a time in
training), an LSTM of 32, one LSTM shared by actor and critic, a critic without LSTM, 5 epochs,
4096-step minibatches, and two torch threads.

Reported per configuration: env steps per second over ``model.learn`` (rollouts and updates,
what a user waits for), the seconds spent collecting rollouts and in the updates, and the ratio
of steps/s to the PPO MLP's (> 1: faster). The start-state curriculum and the checkpoint
selection of the shipped entries are left out: they cost every configuration the same. Each
configuration is warmed up by one rollout and update first (numba kernels, torch). On a shared
machine the absolute numbers move with the load; the ratios are from one run. ``--rounds R``
repeats the configurations in alternation and reports medians.

    python benchmarks/bench_memory.py [--steps 65536] [--variants] [--rounds 1] [--json FILE]
                                      [--only LABEL ...] [--profile LABEL]
"""

from __future__ import annotations

import argparse
import cProfile
import io
import json
import platform
import pstats
import statistics
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

ENV_ID = "LunarPinpointLanding-v2"
ENV_KWARGS = {"dt_s": 2.0, "uncertainty": "standard"}
N_ENVS = 32

#: label -> (algo, hyperparameter overrides (dotted keys), torch threads, sb3-contrib's policy)
BASE = {
    "PPO MLP": ("ppo", {}, 1, False),
    "PPO, 8-frame history": ("ppo", {"history": 8}, 1, False),
    "RecurrentPPO, LSTM 64": ("recurrent-ppo", {}, 1, False),
}
VARIANTS = {
    "RecurrentPPO, LSTM 64, sb3-contrib's step loop": ("recurrent-ppo", {}, 1, True),
    "RecurrentPPO, LSTM 32": ("recurrent-ppo", {"policy_kwargs.lstm_hidden_size": 32}, 1,
                              False),
    "RecurrentPPO, LSTM 64 shared by actor and critic": (
        "recurrent-ppo", {"policy_kwargs.shared_lstm": True,
                          "policy_kwargs.enable_critic_lstm": False}, 1, False),
    "RecurrentPPO, LSTM 64, critic without LSTM": (
        "recurrent-ppo", {"policy_kwargs.enable_critic_lstm": False}, 1, False),
    "RecurrentPPO, LSTM 64, 5 epochs": ("recurrent-ppo", {"n_epochs": 5}, 1, False),
    "RecurrentPPO, LSTM 64, 4096-step minibatches": ("recurrent-ppo", {"batch_size": 4096}, 1,
                                                     False),
    "RecurrentPPO, LSTM 64, 2 torch threads": ("recurrent-ppo", {}, 2, False),
}


def _config(algo: str, overrides: dict[str, Any]) -> tuple[dict, dict]:
    """The shipped entry of ``algo`` for the env with ``overrides``, and its SB3 arguments."""
    from agents.hyperparams import (
        apply_overrides,
        default_hyperparams_path,
        load_hyperparams,
        resolve_algo_kwargs,
    )

    hp = apply_overrides(load_hyperparams(default_hyperparams_path(algo), ENV_ID), overrides)
    hp["n_envs"] = N_ENVS
    return hp, resolve_algo_kwargs(hp, algo)


def _train(label: str, steps: int, seed: int, profile: bool) -> dict[str, Any]:
    """Build the configuration ``label``, warm it up, then time ``steps`` env steps of
    ``learn``: steps/s, rollout and update seconds (and a cProfile summary if ``profile``)."""
    import torch
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecNormalize

    from agents.common.runs import algo_class
    from agents.rl.training import DEFAULT_POLICY, make_training_env

    algo, overrides, threads, stock = {**BASE, **VARIANTS}[label]
    torch.set_num_threads(threads)
    hp, kwargs = _config(algo, overrides)
    venv = make_training_env(ENV_ID, N_ENVS, seed, {**hp.get("env_kwargs", {}), **ENV_KWARGS},
                             obs_features=hp.get("obs_features"),
                             reward_shaping=hp.get("reward_shaping"),
                             gamma=float(hp.get("gamma", 0.99)), history=hp.get("history"))
    venv = VecNormalize(venv, gamma=float(hp.get("gamma", 0.99)))
    policy: Any = hp.get("policy", DEFAULT_POLICY[algo])
    if stock:
        from sb3_contrib.common.recurrent.policies import RecurrentActorCriticPolicy

        policy = RecurrentActorCriticPolicy
    model = algo_class(algo)(policy, venv, seed=seed, device="cpu", verbose=0, **kwargs)

    class PhaseTimer(BaseCallback):
        """Rollout: on_rollout_start .. on_rollout_end; the rest of ``learn`` is updates."""

        def __init__(self) -> None:
            super().__init__()
            self.rollout_s = 0.0
            self._t0 = 0.0

        def _on_rollout_start(self) -> None:
            self._t0 = time.perf_counter()

        def _on_rollout_end(self) -> None:
            self.rollout_s += time.perf_counter() - self._t0

        def _on_step(self) -> bool:
            return True

    model.learn(total_timesteps=model.n_steps * N_ENVS)  # warm-up
    timer = PhaseTimer()
    prof = cProfile.Profile() if profile else None
    t0 = time.perf_counter()
    if prof is not None:
        prof.enable()
    model.learn(total_timesteps=steps, callback=timer, reset_num_timesteps=True)
    if prof is not None:
        prof.disable()
    wall = time.perf_counter() - t0
    done = int(model.num_timesteps)
    venv.close()
    torch.set_num_threads(1)
    out = {"algo": algo, "overrides": overrides, "torch_threads": threads,
           "sb3_contrib_policy": stock, "steps": done, "wall_s": wall,
           "steps_per_s": done / wall, "rollout_s": timer.rollout_s,
           "update_s": wall - timer.rollout_s}
    if prof is not None:
        text = io.StringIO()
        pstats.Stats(prof, stream=text).sort_stats("tottime").print_stats(15)
        out["profile"] = text.getvalue()
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--steps", type=int, default=65_536,
                   help="timed env steps per configuration (default 65536)")
    p.add_argument("--variants", action="store_true",
                   help="also time the recurrent variants (see the module docstring)")
    p.add_argument("--rounds", type=int, default=1,
                   help="repeat the configurations in alternation; medians are reported")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--only", nargs="+", default=None, metavar="LABEL",
                   help="time only these configurations (and the PPO MLP, the reference)")
    p.add_argument("--profile", default=None, metavar="LABEL",
                   help="print the cProfile summary (top 15 by own time) of this configuration")
    p.add_argument("--json", default=None, help="write the results to this JSON file")
    args = p.parse_args(argv)
    labels = list(BASE) + (list(VARIANTS) if args.variants else [])
    if args.only is not None:
        unknown = sorted(set(args.only) - set(BASE) - set(VARIANTS))
        if unknown:
            p.error(f"--only {unknown}: the configurations are {list(BASE) + list(VARIANTS)}")
        labels = ["PPO MLP"] + [x for x in {**BASE, **VARIANTS} if x in args.only
                                and x != "PPO MLP"]
    if args.steps < 1 or args.rounds < 1:
        p.error(f"--steps {args.steps} and --rounds {args.rounds} must be >= 1")
    if args.profile is not None and args.profile not in labels:
        p.error(f"--profile {args.profile!r}: one of {labels}")

    print(f"{ENV_ID} {ENV_KWARGS}, native vector env of {N_ENVS} landers, {args.steps} timed "
          f"steps per configuration, {args.rounds} round(s)")
    runs: dict[str, list[dict[str, Any]]] = {label: [] for label in labels}
    for _ in range(args.rounds):
        for label in labels:
            runs[label].append(_train(label, args.steps, args.seed, label == args.profile))
    summary = {}
    for label in labels:
        rs = runs[label]
        summary[label] = {**{k: v for k, v in rs[0].items() if k != "profile"},
                          **{k: statistics.median(r[k] for r in rs)
                             for k in ("wall_s", "steps_per_s", "rollout_s", "update_s")}}
    ref = summary["PPO MLP"]["steps_per_s"]
    width = max(map(len, labels))
    print(f"\n| {'configuration':<{width}} | steps/s | rollout s | update s | ratio to MLP |")
    print(f"|{'-' * (width + 2)}|---------|-----------|----------|--------------|")
    for label in labels:
        s = summary[label]
        s["ratio_to_mlp"] = s["steps_per_s"] / ref
        print(f"| {label:<{width}} | {s['steps_per_s']:7.0f} | {s['rollout_s']:9.1f} | "
              f"{s['update_s']:8.1f} | {s['ratio_to_mlp']:12.3f} |")
    for label in labels:
        if "profile" in runs[label][-1]:
            print(f"\nProfile of {label} (own time):\n{runs[label][-1]['profile']}")
    if args.json:
        out = {"env_id": ENV_ID, "env_kwargs": ENV_KWARGS, "n_envs": N_ENVS,
               "steps": args.steps, "rounds": args.rounds, "results": summary,
               "machine": {"python": platform.python_version(),
                           "processor": platform.processor(),
                           "note": "shared machine; ratios are from one run"}}
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
