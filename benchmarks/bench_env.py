"""Env throughput: our single env, SyncVectorEnv over it, the native vector env at N = 256 and
4096, against Gymnasium's LunarLander-v3 (Box2D) timed in the same run.

    python benchmarks/bench_env.py [--quick] [--json FILE] [--env LunarSoftLanding-v0]

Prints env-steps per second (one lander advanced by one env step = one env-step; the best of
short timing chunks, as ``timeit`` does, to resist other work on the machine) and ratios to the
peer's single-env rate. Targets: native vector env >= 1000x the peer's single env; one env step
< 20 µs; the native vector env under the ``standard`` uncertainty set (plant, navigation and
sensor errors), with and without the IMU's observation channels (``sensors=("imu",)``), at
>= 80 % of its nominal throughput, all timed here in alternating chunks so that other work on
the machine hits them alike. Timings depend on that work; run it on an idle machine for the
record.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time

import gymnasium as gym
import numpy as np

import lunar_env  # noqa: F401  (registers the ids)


def _warm_up(env, actions: np.ndarray, n_steps: int = 1500) -> None:
    """Run whole episodes first: compiled kernels load from numba's cache on first use."""
    env.reset(seed=0)
    for k in range(n_steps):
        out = env.step(actions[k % len(actions)])
        if np.all(np.logical_or(out[2], out[3])):
            env.reset()


def _time_single(env, actions: np.ndarray, min_s: float) -> float:
    """env-steps/s of one env, resetting on episode end."""
    _warm_up(env, actions)
    env.reset(seed=0)
    n = 0
    k = len(actions)
    best = 0.0
    t_start = time.perf_counter()
    while time.perf_counter() - t_start < min_s:
        t0 = time.perf_counter()
        for _ in range(500):
            _, _, term, trunc, _ = env.step(actions[n % k])
            n += 1
            if term or trunc:
                env.reset()
        best = max(best, 500 / (time.perf_counter() - t0))
    return best


def _time_vector(venv, actions: np.ndarray, min_s: float) -> float:
    """env-steps/s of a vector env (num_envs landers per call)."""
    _warm_up(venv, actions, 30)
    venv.reset(seed=0)
    n = 0
    k = len(actions)
    best = 0.0
    t_start = time.perf_counter()
    while time.perf_counter() - t_start < min_s:
        t0 = time.perf_counter()
        for _ in range(5):
            venv.step(actions[n % k])
            n += 1
        best = max(best, 5 * venv.num_envs / (time.perf_counter() - t0))
    return best


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="short timings (CI smoke run)")
    ap.add_argument("--json", metavar="FILE", help="write the results as JSON")
    ap.add_argument("--env", default="LunarSoftLanding-v0")
    args = ap.parse_args(argv)
    min_s = 0.3 if args.quick else 2.0
    sizes = (256, 4096)
    rng = np.random.default_rng(0)

    rows: list[tuple[str, float]] = []

    def record(name: str, rate: float) -> None:
        rows.append((name, rate))
        print(f"  {name:<48s} {rate:14,.0f} env-steps/s", flush=True)

    print(f"machine: {platform.processor() or platform.machine()}, python {sys.version.split()[0]}"
          f"; env {args.env}")
    # peer: Gymnasium's LunarLander-v3 (Box2D), random discrete actions
    peer = gym.make("LunarLander-v3")
    peer_actions = rng.integers(0, 4, 1000)
    peer_rate = _time_single(peer, peer_actions, min_s)
    record("peer LunarLander-v3, one env (gym.make)", peer_rate)

    env = gym.make(args.env)
    dim = env.action_space.shape[0]
    acts = rng.uniform(-1, 1, (1000, dim)).astype(np.float32)
    record(f"{args.env}, one env (gym.make)", _time_single(env, acts, min_s))
    record(f"{args.env}, one env (unwrapped)", _time_single(env.unwrapped, acts, min_s))
    n_sync = 16
    sync = gym.vector.SyncVectorEnv([lambda: gym.make(args.env) for _ in range(n_sync)])
    record(f"SyncVectorEnv x{n_sync} over {args.env}",
           _time_vector(sync, rng.uniform(-1, 1, (100, n_sync, dim)).astype(np.float32), min_s))
    for n in sizes:
        venv = gym.make_vec(args.env, num_envs=n, vectorization_mode="vector_entry_point")
        record(f"native vector env N={n}",
               _time_vector(venv, rng.uniform(-1, 1, (20, n, dim)).astype(np.float32), min_s))
    n = sizes[-1]
    for label, kw in ((f"native vector env N={n}, parallel kernel", dict(parallel=True)),
                      (f"native vector env N={n}, substeps=1", dict(substeps=1))):
        venv = gym.make_vec(args.env, num_envs=n, vectorization_mode="vector_entry_point", **kw)
        record(label, _time_vector(venv, rng.uniform(-1, 1, (20, n, dim)).astype(np.float32),
                                   min_s))

    # the uncertainty model's cost: nominal and standard vector envs timed in alternation
    unc_ratio = {}
    imu_ratio = {}
    for n_unc in sizes:
        acts_u = rng.uniform(-1, 1, (20, n_unc, dim)).astype(np.float32)
        nominal = gym.make_vec(args.env, num_envs=n_unc, vectorization_mode="vector_entry_point")
        standard = gym.make_vec(args.env, num_envs=n_unc, vectorization_mode="vector_entry_point",
                                uncertainty="standard")
        imu = gym.make_vec(args.env, num_envs=n_unc, vectorization_mode="vector_entry_point",
                           uncertainty="standard", sensors=("imu",))
        rates = {"nominal": 0.0, "standard": 0.0, "imu": 0.0}
        for _ in range(3):
            rates["nominal"] = max(rates["nominal"], _time_vector(nominal, acts_u, min_s / 2))
            rates["standard"] = max(rates["standard"], _time_vector(standard, acts_u, min_s / 2))
            rates["imu"] = max(rates["imu"], _time_vector(imu, acts_u, min_s / 2))
        record(f"native vector env N={n_unc}, uncertainty='standard'", rates["standard"])
        record(f"native vector env N={n_unc}, 'standard' + IMU channels", rates["imu"])
        unc_ratio[n_unc] = rates["standard"] / rates["nominal"]
        imu_ratio[n_unc] = rates["imu"] / rates["nominal"]

    print()
    print(f"{'configuration':<50s} {'env-steps/s':>14s} {'x peer':>9s} {'µs/env-step':>12s}")
    out = []
    for name, rate in rows:
        ratio = rate / peer_rate
        print(f"{name:<50s} {rate:14,.0f} {ratio:9.1f} {1e6 / rate:12.2f}")
        out.append({"configuration": name, "env_steps_per_s": rate, "ratio_to_peer": ratio,
                    "us_per_env_step": 1e6 / rate})
    single_us = 1e6 / rows[2][1]
    best_native = max(r for name, r in rows if name.startswith("native")
                      and "standard" not in name)
    print()
    print(f"one env step (unwrapped): {single_us:.1f} µs (target < 20 µs)")
    print(f"best native vector env: {best_native / peer_rate:,.0f}x the peer's single env "
          "(target >= 1000x)")
    for n_unc, ratio in unc_ratio.items():
        print(f"native vector env N={n_unc} with uncertainty='standard': {ratio:.2f}x its "
              "nominal throughput (target >= 0.80)")
    for n_unc, ratio in imu_ratio.items():
        print(f"native vector env N={n_unc} with 'standard' and the IMU channels: {ratio:.2f}x "
              "its nominal throughput (target >= 0.80)")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"env": args.env, "quick": args.quick, "peer": "LunarLander-v3",
                       "results": out, "single_env_step_us": single_us,
                       "native_over_peer": best_native / peer_rate,
                       "standard_over_nominal": {str(k): v for k, v in unc_ratio.items()},
                       "imu_over_nominal": {str(k): v for k, v in imu_ratio.items()}},
                      f, indent=2)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
