"""Env throughput: our single env, SyncVectorEnv over it, the native vector env at N = 256 and
4096, against Gymnasium's LunarLander-v3 (Box2D) timed in the same run.

    python benchmarks/bench_env.py [--quick] [--json FILE] [--env ID [ID ...]]

Prints env-steps per second (one lander advanced by one env step = one env-step; the best of
short timing chunks, as ``timeit`` does, to resist other work on the machine) and ratios to the
peer's single-env rate. Targets: native vector env >= 1000x the peer's single env; one env step
< 20 µs; the native vector env under the ``standard`` uncertainty set (plant, navigation and
sensor errors), with and without the IMU's observation channels (``sensors=("imu",)``), at
>= 80 % of its nominal throughput, all timed here in alternating chunks so that other work on
the machine hits them alike; LunarPinpointLanding-v3 (pinpoint landing to touchdown): its
native vector env at N = 4096 >= 50x the peer's single env. Timings depend on that work; run
it on an idle machine for the record.
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


#: the peer ratio each env's native vector env must reach at N = 4096 (env-steps per second
#: over the peer's single env); None: only the best-native target below
NATIVE_4096_TARGET = {"LunarPinpointLanding-v3": 50.0}


def _bench_env(env_id: str, min_s: float, rng: np.random.Generator, record) -> dict:
    """Time one env id in every configuration; returns the per-env summary."""
    sizes = (256, 4096)
    env = gym.make(env_id)
    dim = env.action_space.shape[0]
    acts = rng.uniform(-1, 1, (1000, dim)).astype(np.float32)
    record(env_id, f"{env_id}, one env (gym.make)", _time_single(env, acts, min_s))
    single = _time_single(env.unwrapped, acts, min_s)
    record(env_id, f"{env_id}, one env (unwrapped)", single)
    n_sync = 16
    sync = gym.vector.SyncVectorEnv([lambda: gym.make(env_id) for _ in range(n_sync)])
    record(env_id, f"SyncVectorEnv x{n_sync} over {env_id}",
           _time_vector(sync, rng.uniform(-1, 1, (100, n_sync, dim)).astype(np.float32), min_s))
    native = {}
    for n in sizes:
        venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point")
        native[n] = _time_vector(venv, rng.uniform(-1, 1, (20, n, dim)).astype(np.float32),
                                 min_s)
        record(env_id, f"{env_id}, native vector env N={n}", native[n])
    n = sizes[-1]
    for label, kw in ((f"{env_id}, native vector env N={n}, parallel kernel",
                       dict(parallel=True)),
                      (f"{env_id}, native vector env N={n}, substeps=1", dict(substeps=1))):
        venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kw)
        native[label] = _time_vector(venv, rng.uniform(-1, 1, (20, n, dim)).astype(np.float32),
                                     min_s)
        record(env_id, label, native[label])

    # the uncertainty model's cost: nominal and standard vector envs timed in alternation
    unc_ratio = {}
    imu_ratio = {}
    for n_unc in sizes:
        acts_u = rng.uniform(-1, 1, (20, n_unc, dim)).astype(np.float32)
        nominal = gym.make_vec(env_id, num_envs=n_unc, vectorization_mode="vector_entry_point")
        standard = gym.make_vec(env_id, num_envs=n_unc, vectorization_mode="vector_entry_point",
                                uncertainty="standard")
        imu = gym.make_vec(env_id, num_envs=n_unc, vectorization_mode="vector_entry_point",
                           uncertainty="standard", sensors=("imu",))
        rates = {"nominal": 0.0, "standard": 0.0, "imu": 0.0}
        for _ in range(3):
            rates["nominal"] = max(rates["nominal"], _time_vector(nominal, acts_u, min_s / 2))
            rates["standard"] = max(rates["standard"], _time_vector(standard, acts_u, min_s / 2))
            rates["imu"] = max(rates["imu"], _time_vector(imu, acts_u, min_s / 2))
        record(env_id, f"{env_id}, native vector env N={n_unc}, uncertainty='standard'",
               rates["standard"])
        record(env_id, f"{env_id}, native vector env N={n_unc}, 'standard' + IMU channels",
               rates["imu"])
        unc_ratio[n_unc] = rates["standard"] / rates["nominal"]
        imu_ratio[n_unc] = rates["imu"] / rates["nominal"]
    return {"single_env_step_us": 1e6 / single, "best_native": max(native.values()),
            "native_4096": native[4096], "standard_over_nominal": unc_ratio,
            "imu_over_nominal": imu_ratio}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="short timings (CI smoke run)")
    ap.add_argument("--json", metavar="FILE", help="write the results as JSON")
    ap.add_argument("--env", nargs="+", default=["LunarSoftLanding-v0", "LunarPinpointLanding-v3"],
                    help="env ids to time (default: the soft landing and the touchdown env)")
    args = ap.parse_args(argv)
    min_s = 0.3 if args.quick else 2.0
    rng = np.random.default_rng(0)

    rows: list[tuple[str, str, float]] = []

    def record(env_id: str, name: str, rate: float) -> None:
        rows.append((env_id, name, rate))
        print(f"  {name:<72s} {rate:14,.0f} env-steps/s", flush=True)

    print(f"machine: {platform.processor() or platform.machine()}, python {sys.version.split()[0]}"
          f"; envs {', '.join(args.env)}")
    # peer: Gymnasium's LunarLander-v3 (Box2D), random discrete actions
    peer = gym.make("LunarLander-v3")
    peer_actions = rng.integers(0, 4, 1000)
    peer_rate = _time_single(peer, peer_actions, min_s)
    record("peer", "peer LunarLander-v3, one env (gym.make)", peer_rate)
    summaries = {env_id: _bench_env(env_id, min_s, rng, record) for env_id in args.env}

    print()
    print(f"{'configuration':<74s} {'env-steps/s':>14s} {'x peer':>9s} {'µs/env-step':>12s}")
    out = []
    for env_id, name, rate in rows:
        ratio = rate / peer_rate
        print(f"{name:<74s} {rate:14,.0f} {ratio:9.1f} {1e6 / rate:12.2f}")
        out.append({"env": env_id, "configuration": name, "env_steps_per_s": rate,
                    "ratio_to_peer": ratio, "us_per_env_step": 1e6 / rate})
    print()
    for env_id, sm in summaries.items():
        print(f"{env_id}: one env step (unwrapped) {sm['single_env_step_us']:.1f} µs "
              "(target < 20 µs)")
        print(f"{env_id}: best native vector env {sm['best_native'] / peer_rate:,.0f}x the "
              "peer's single env (target >= 1000x)")
        target = NATIVE_4096_TARGET.get(env_id)
        if target is not None:
            print(f"{env_id}: native vector env N=4096 {sm['native_4096'] / peer_rate:,.0f}x the "
                  f"peer's single env (target >= {target:g}x)")
        for n_unc, ratio in sm["standard_over_nominal"].items():
            print(f"{env_id}: native vector env N={n_unc} with uncertainty='standard': "
                  f"{ratio:.2f}x its nominal throughput (target >= 0.80)")
        for n_unc, ratio in sm["imu_over_nominal"].items():
            print(f"{env_id}: native vector env N={n_unc} with 'standard' and the IMU channels: "
                  f"{ratio:.2f}x its nominal throughput (target >= 0.80)")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"envs": args.env, "quick": args.quick, "peer": "LunarLander-v3",
                       "peer_env_steps_per_s": peer_rate, "results": out,
                       "summaries": {e: {"single_env_step_us": sm["single_env_step_us"],
                                         "native_over_peer": sm["best_native"] / peer_rate,
                                         "native_4096_over_peer": sm["native_4096"] / peer_rate,
                                         "standard_over_nominal": {
                                             str(k): v for k, v in
                                             sm["standard_over_nominal"].items()},
                                         "imu_over_nominal": {
                                             str(k): v for k, v in
                                             sm["imu_over_nominal"].items()}}
                                     for e, sm in summaries.items()}},
                      f, indent=2)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
