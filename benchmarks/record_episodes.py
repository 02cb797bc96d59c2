"""Seeded episodes of every registered env id, recorded for bit-for-bit comparisons.

A refactor of the env step, or a new env option that must leave the nominal world unchanged
(``uncertainty="none"``), is checked by recording before and after and comparing::

    python benchmarks/record_episodes.py record before.npz      # on the old commit
    python benchmarks/record_episodes.py record after.npz       # on the new one
    python benchmarks/record_episodes.py compare before.npz after.npz

Each id is flown in six settings (defaults, a throttle channel, 2 s decisions with 3
substeps, a 40 s time limit so truncations happen, and the ``standard`` uncertainty set with
and without the throttle channel): three seeded single-env episodes with
seeded random actions (observations, rewards, flags, every info key with its type and value),
and a 5-lander native vector env over 900 steps through autoresets (every info key and mask)
plus 400 steps of ``step_landers`` / ``reset_landers`` / ``observations``. ``compare`` exits 1
and lists the arrays that differ in dtype, shape or any bit.
"""

from __future__ import annotations

import argparse
import sys

import gymnasium as gym
import numpy as np

import lunar_env  # noqa: F401  (registers the ids)

SETTINGS = (({}, ""), ({"throttle_channel": True}, "+thr"),
            ({"dt_s": 2.0, "substeps": 3}, "+dt2"), ({"time_limit_s": 40.0}, "+tl"),
            ({"uncertainty": "standard"}, "+std"),
            ({"uncertainty": "standard", "throttle_channel": True}, "+std+thr"))


def ids() -> list[str]:
    """Every registered lunar_env id."""
    return sorted(k for k, s in gym.registry.items()
                  if k.startswith("Lunar") and str(s.entry_point).startswith("lunar_env"))

def run_single(env_id, kw, tag, store, n_steps=1300, seeds=(0, 1, 2)):
    env = gym.make(env_id, **kw)
    rng = np.random.default_rng(123)
    shape = env.action_space.shape
    obs_l, rew, term, trunc, infos = [], [], [], [], []
    k = 0
    for s in seeds:
        obs, info = env.reset(seed=s)
        obs_l.append(obs)
        infos.append(("reset", k, sorted(info.items())))
        for _ in range(n_steps):
            # biased random actions: some episodes land
            a = np.clip(rng.normal(0.3, 0.5, shape), -1.2, 1.2).astype(np.float32)
            obs, r, te, tr, info = env.step(a)
            obs_l.append(obs)
            rew.append(r)
            term.append(te)
            trunc.append(tr)
            infos.append(("step", k, sorted(info.items())))
            k += 1
            if te or tr:
                break
    key = f"{tag}"
    store[key + "/obs"] = np.array(obs_l)
    store[key + "/rew"] = np.array(rew)
    store[key + "/term"] = np.array(term)
    store[key + "/trunc"] = np.array(trunc)
    store[key + "/infokeys"] = np.array([";".join(f"{a}:{type(b).__name__}" for a, b in it)
                                         for _, _, it in infos])
    rows = [np.concatenate([np.ravel(np.asarray(b, dtype=np.float64)) for _, b in it])
            for _, _, it in infos]
    width = max(len(r) for r in rows)
    store[key + "/infovals"] = np.array([np.pad(r, (0, width - len(r)), constant_values=np.nan)
                                         for r in rows])

def run_vec(env_id, kw, tag, store, n=5, n_steps=900):
    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kw)
    rng = np.random.default_rng(7)
    shape = venv.action_space.shape
    obs, info = venv.reset(seed=3)
    obs_l, rew, term, trunc = [obs], [], [], []
    infos = {k: [v] for k, v in info.items()}
    for _ in range(n_steps):
        a = np.clip(rng.normal(0.3, 0.5, shape), -1.2, 1.2).astype(np.float32)
        obs, r, te, tr, info = venv.step(a)
        obs_l.append(obs)
        rew.append(r)
        term.append(te)
        trunc.append(tr)
        if sorted(info) != sorted(infos):
            raise RuntimeError(f"info keys changed: {sorted(info)} vs {sorted(infos)}")
        for k, v in info.items():
            infos[k].append(v)
    store[tag + "/obs"] = np.array(obs_l)
    store[tag + "/rew"] = np.array(rew)
    store[tag + "/term"] = np.array(term)
    store[tag + "/trunc"] = np.array(trunc)
    for k, v in infos.items():
        store[tag + "/info/" + k] = np.array(v)
    # step_landers (no autoreset)
    obs, info = venv.reset(seed=11)
    for _ in range(400):
        a = np.clip(rng.normal(0.3, 0.5, shape), -1.2, 1.2).astype(np.float32)
        out = venv.unwrapped.step_landers(a)
        for k, v in out.items():
            store.setdefault(tag + "/landers/" + k, []).append(np.asarray(v))
        done = out["terminated"] | out["truncated"]
        if done.any():
            venv.unwrapped.reset_landers(np.flatnonzero(done))
        store.setdefault(tag + "/landers/obs", []).append(venv.unwrapped.observations())
    for k in [k for k in store if k.startswith(tag + "/landers/")]:
        store[k] = np.array(store[k])

def record(out: str) -> int:
    store: dict = {}
    for env_id in ids():
        for kw, tag in SETTINGS:
            run_single(env_id, kw, f"single/{env_id}{tag}", store)
            run_vec(env_id, kw, f"vec/{env_id}{tag}", store)
        print(env_id, flush=True)
    np.savez(out, **store)
    print(f"saved {out}: {len(store)} arrays")
    return 0


def compare(path_a: str, path_b: str) -> int:
    a, b = np.load(path_a), np.load(path_b)
    ka, kb = set(a.files), set(b.files)
    bad = sorted(ka ^ kb)
    for k in sorted(ka & kb):
        x, y = a[k], b[k]
        if x.dtype != y.dtype or x.shape != y.shape or not np.array_equal(
                x, y, equal_nan=x.dtype.kind in "fc"):
            bad.append(k)
    print(f"arrays: {len(ka)} / {len(kb)}, mismatches: {len(bad)}")
    for k in bad[:30]:
        print("  ", k)
    return 1 if bad else 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python benchmarks/record_episodes.py",
                                description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("record", help="record every id's seeded episodes into an .npz")
    r.add_argument("out")
    c = sub.add_parser("compare", help="compare two recordings bit for bit")
    c.add_argument("a")
    c.add_argument("b")
    args = p.parse_args(argv)
    return record(args.out) if args.cmd == "record" else compare(args.a, args.b)


if __name__ == "__main__":
    sys.exit(main())
