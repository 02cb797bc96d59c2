"""Fuzz the envs' public inputs: construction arguments, reset options and actions.

Every input must either *work* (the env keeps exactly the value asked for, observations lie in
the observation space, rewards and infos are finite, a rejected action leaves the state as it
was) or raise an error that *names* it (a ``ValueError``/``TypeError``/``RuntimeError`` whose
message contains the argument's name). Anything else is counted:

- ``silent``: accepted but not honoured (a value coerced, NaN or an out-of-space observation
  escaped, a rejected action changed the state);
- ``unclear``: an error that does not name the argument, or of another type (IndexError,
  ZeroDivisionError, ...).

::

    python benchmarks/fuzz_inputs.py                 # 2000 cases, prints the counts
    python benchmarks/fuzz_inputs.py --quick --json fuzz.json

``tests/test_reliability.py`` runs the same checker under hypothesis (a quick version in the
default run, a long one marked ``slow``) and fails on the first silent or unclear case, shrunk.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
import warnings
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np
from hypothesis import strategies as st

import lunar_env  # noqa: F401  (registers the ids)

ENV_IDS = ("LunarSoftLanding-v0", "LunarPinpointLanding-v0")
_NUMERIC = ("dt_s", "time_limit_s", "success_speed_m_s", "max_fall_s", "cutoff_speed_m_s",
            "success_miss_m")
_NONE_STORED_AS = {"cutoff_speed_m_s": 0.0, "success_miss_m": float("inf")}
_ARGS = (*_NUMERIC, "substeps", "throttle_channel", "scenario")
_OK_ERRORS = (ValueError, TypeError, RuntimeError, KeyError)


# ----------------------------------------------------------------------------- strategies

_special = st.sampled_from([0.0, -0.0, -1.0, 1e-9, 0.25, 1.0, 2.0, 2.5, 30.0, 1e6, math.nan,
                            math.inf, -math.inf])
values = st.one_of(
    _special,
    st.floats(min_value=-1e3, max_value=1e3, allow_nan=False),
    st.integers(min_value=-3, max_value=12),
    st.booleans(),
    st.none(),
    st.sampled_from(["no", "yes", "1", "", "zhu2007", "peng2012", "wang2003", "mars"]),
    st.lists(st.floats(allow_nan=False, min_value=-10, max_value=10), max_size=3),
    st.sampled_from([np.float32(0.5), np.int64(3), np.bool_(True), np.array([1.0, 2.0])]),
)


@st.composite
def env_kwargs(draw, env_id: str):
    names = list(_ARGS) + (["success_miss_m"] if "Pinpoint" in env_id else [])
    chosen = draw(st.lists(st.sampled_from(names), unique=True, max_size=3))
    kw = {n: draw(values) for n in chosen}
    if draw(st.integers(0, 19)) == 0:
        kw[draw(st.sampled_from(["dt", "substep", "throttle", "scenarios"]))] = 1.0
    return kw


@st.composite
def reset_options(draw, n_state: int, num_envs: int | None):
    kind = draw(st.sampled_from(["none", "nominal", "state_si", "state_nd", "unknown",
                                 "not_a_dict"]))
    if kind == "none":
        return None
    if kind == "nominal":
        return {"nominal": draw(st.one_of(st.booleans(), st.just(1)))}
    if kind == "unknown":
        return {draw(st.sampled_from(["state", "State_si", "seed", "nominl"])): 1}
    if kind == "not_a_dict":
        return draw(st.sampled_from([[("nominal", True)], "nominal", 3]))
    length = draw(st.sampled_from([n_state, n_state, n_state - 1, n_state + 1, 0]))
    rows = draw(st.sampled_from([1, 1, num_envs or 1, 2 if num_envs != 2 else 3]))
    mode = draw(st.sampled_from(["near", "near", "random", "nan"]))
    return {kind: _state_rows(draw, kind, n_state, length, rows, mode, num_envs)}


def _state_rows(draw, kind, n_state, length, rows, mode, num_envs):
    seed = draw(st.integers(0, 2**16))
    rng = np.random.default_rng(seed)
    if mode == "random":
        arr = rng.uniform(-2e6, 2e6, size=(rows, length))
    else:
        # around the nominal start of each env (filled in by the checker: a marker)
        arr = np.full((rows, length), np.nan if mode == "nan" else 0.0)
        if mode != "nan":
            arr = ("near", seed, rows, length)
            return arr
    return arr if rows > 1 or num_envs is None or draw(st.booleans()) else arr[0]


actions = st.one_of(
    st.sampled_from(["valid", "valid", "valid", "big", "nan", "inf", "shape", "transposed",
                     "string", "list"]),
)


# ----------------------------------------------------------------------------- checker


@dataclass
class Tally:
    inputs: int = 0
    ok: int = 0
    clear_errors: int = 0
    silent: int = 0
    unclear: int = 0
    examples: list = field(default_factory=list)

    def add(self, outcome: str, what: str, detail: str = "") -> None:
        self.inputs += 1
        if outcome == "ok":
            self.ok += 1
        elif outcome == "clear":
            self.clear_errors += 1
        else:
            setattr(self, outcome, getattr(self, outcome) + 1)
            if len(self.examples) < 20:
                self.examples.append(f"{outcome}: {what}: {detail}")

    def as_dict(self) -> dict[str, Any]:
        return {"inputs_tried": self.inputs, "worked": self.ok,
                "clear_errors": self.clear_errors, "silent_failures": self.silent,
                "unclear_errors": self.unclear, "examples": self.examples}


def _names_it(exc: BaseException, names) -> bool:
    msg = str(exc)
    return isinstance(exc, _OK_ERRORS) and any(n in msg for n in names)


def _expected_kept(env, kw) -> str | None:
    """None if every accepted argument is kept exactly; else what was changed."""
    task = env.task
    for name, v in kw.items():
        if name in _NUMERIC:
            if v is None and name in ("time_limit_s", "max_fall_s"):
                continue  # None: the documented default
            got = getattr(task, name)
            if v is None and name in _NONE_STORED_AS:
                # None: no cut-off at a speed minimum (stored as 0), no miss criterion (inf)
                if got != _NONE_STORED_AS[name]:
                    return f"{name}=None became {got!r}"
                continue
            if float(np.asarray(v).reshape(())) != got:
                return f"{name}={v!r} became {got!r}"
        elif name == "substeps" and task.substeps != v:
            return f"substeps={v!r} became {task.substeps!r}"
        elif name == "throttle_channel" and task.throttle_channel is not bool(v):
            return f"throttle_channel={v!r} became {task.throttle_channel!r}"
        elif name == "throttle_channel" and not isinstance(v, (bool, np.bool_, int)):
            return f"throttle_channel={v!r} accepted"
    return None


def _finite_info(info) -> bool:
    for k, v in info.items():
        if k.startswith("_"):
            continue
        a = np.asarray(v)
        if a.dtype.kind in "fc" and not np.isfinite(a).all():
            return False
    return True


def _materialise(opts, env, vector):
    """Turn the "near nominal" marker into real rows (SI or normalised)."""
    if not isinstance(opts, dict):
        return opts
    out = dict(opts)
    for key in ("state_si", "state_nd"):
        v = out.get(key)
        if isinstance(v, tuple) and v[0] == "near":
            _, seed, rows, length = v
            sc = env.scenario
            rng = np.random.default_rng(seed)
            if "Pinpoint" in type(env).__name__:
                nd = np.stack([sc.state_nd(s, env.task.scaling)
                               for s in sc.sample_initial(rng, rows)])
                si = nd.copy()
                s = env.task.scaling
                si[:, :3] *= s.length_m
                si[:, 3:6] *= s.velocity_m_s
                si[:, 6] *= s.mass_kg
            else:
                si = sc.sample_initial(rng, rows)
                nd = sc.si_to_nd(si, env.task.scaling)
            arr = si if key == "state_si" else nd
            if length != arr.shape[1]:
                arr = np.resize(arr, (rows, length))
            out[key] = arr if (rows > 1 or vector) else arr[0]
    return out


def _action(kind, shape, rng):
    if kind == "valid":
        return rng.uniform(-1, 1, size=shape).astype(np.float32)
    if kind == "big":
        return rng.uniform(-1e6, 1e6, size=shape)
    if kind in ("nan", "inf"):
        a = rng.uniform(-1, 1, size=shape)
        a.flat[rng.integers(a.size)] = np.nan if kind == "nan" else -np.inf
        return a
    if kind == "shape":
        return np.zeros((*shape, 2))
    if kind == "transposed":
        return np.zeros(shape[::-1]) if len(shape) == 2 and shape[0] != shape[1] else \
            np.zeros(shape[:-1] + (shape[-1] + 1,))
    if kind == "string":
        return "up"
    return list(rng.uniform(-1, 1, size=shape).ravel())


def check_case(tally: Tally, env_id: str, num_envs: int | None, kw: dict, opts, seed,
               action_kinds: list[str], action_seed: int) -> None:
    """Run one fuzz case and record every input's outcome in ``tally``."""
    what = f"{env_id} num_envs={num_envs} kwargs={kw!r}"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            env = (gym.make(env_id, **kw).unwrapped if num_envs is None else
                   gym.make_vec(env_id, num_envs=num_envs,
                                vectorization_mode="vector_entry_point", **kw))
        except Exception as exc:  # noqa: BLE001 (classified)
            names = list(kw) or ["scenario"]
            tally.add("clear" if _names_it(exc, names) else "unclear", what,
                      f"{type(exc).__name__}: {exc}")
            return
    changed = _expected_kept(env, kw)
    if changed:
        tally.add("silent", what, changed)
        return
    tally.add("ok", what)
    vector = num_envs is not None
    opts = _materialise(opts, env, vector)
    what_r = f"{what} reset(seed={seed}, options={opts!r})"
    state_before = env.state_nd.copy()
    try:
        obs, info = env.reset(seed=seed, options=opts)
    except Exception as exc:  # noqa: BLE001
        keys = ["options", "reset", "state_si", "state_nd", "nominal", "initial state"]
        clear = _names_it(exc, keys)
        if clear and not np.array_equal(env.state_nd, state_before, equal_nan=True):
            tally.add("silent", what_r, "a failed reset changed the state")
        else:
            tally.add("clear" if clear else "unclear", what_r, f"{type(exc).__name__}: {exc}")
        obs, info = env.reset(seed=0)
    else:
        bad = _bad_obs(env, obs, info, vector)
        if not bad and isinstance(opts, dict) and opts.get("state_nd") is not None:
            req = np.asarray(opts["state_nd"], float)
            try:
                want = np.broadcast_to(req, env.state_nd.shape)
            except ValueError:
                bad = f"state_nd rows of shape {req.shape} accepted for {env.state_nd.shape}"
            else:
                if not np.array_equal(env.state_nd, want):
                    bad = "reset state_nd not honoured"
        tally.add("silent" if bad else "ok", what_r, bad or "")
    rng = np.random.default_rng(action_seed)
    shape = env.action_space.shape
    done = False
    for kind in action_kinds:
        a = _action(kind, shape, rng)
        what_a = f"{what} step({kind} {np.asarray(a, dtype=object).shape})"
        y0 = env.state_nd.copy()
        try:
            obs, reward, term, trunc, info = env.step(a)
        except Exception as exc:  # noqa: BLE001
            if done and isinstance(exc, RuntimeError) and "reset" in str(exc):
                tally.add("clear", what_a)
                env.reset(seed=0)
                done = False
                continue
            clear = _names_it(exc, ["action"])
            if clear and not np.array_equal(env.state_nd, y0):
                tally.add("silent", what_a, "a rejected action changed the state")
            else:
                tally.add("clear" if clear else "unclear", what_a,
                          f"{type(exc).__name__}: {exc}")
            continue
        invalid = kind in ("nan", "inf", "shape", "string")
        if kind == "transposed":  # refused unless it differs only by axes of length 1
            invalid = ([d for d in np.shape(a) if d != 1] != [d for d in shape if d != 1])
        if invalid:
            tally.add("silent", what_a, "an invalid action was accepted")
            continue
        bad = _bad_obs(env, obs, info, vector)
        if not bad and not np.isfinite(np.asarray(reward, dtype=float)).all():
            bad = f"reward {reward!r}"
        tally.add("silent" if bad else "ok", what_a, bad or "")
        done = bool(np.any(term) or np.any(trunc)) and not vector


def _bad_obs(env, obs, info, vector) -> str | None:
    space = env.observation_space
    obs = np.asarray(obs)
    if obs.shape != space.shape or obs.dtype != space.dtype:
        return f"observation shape/dtype {obs.shape} {obs.dtype}"
    if not np.isfinite(obs).all():
        return f"non-finite observation {obs!r}"
    if not space.contains(obs):
        return f"observation outside the space {obs!r}"
    if not _finite_info(info):
        return f"non-finite info {info!r}"
    return None


@st.composite
def cases(draw):
    env_id = draw(st.sampled_from(ENV_IDS))
    num_envs = draw(st.sampled_from([None, None, 1, 2, 3]))
    kw = draw(env_kwargs(env_id))
    n_state = 5 if "Soft" in env_id else 7
    opts = draw(reset_options(n_state, num_envs))
    seed = draw(st.one_of(st.none(), st.integers(0, 2**31 - 1)))
    kinds = draw(st.lists(actions, min_size=1, max_size=4))
    return env_id, num_envs, kw, opts, seed, kinds, draw(st.integers(0, 2**16))


def run(n_cases: int, seed: int = 0) -> Tally:
    """``n_cases`` hypothesis-drawn cases (deterministic for a seed); returns the tally."""
    from hypothesis import HealthCheck, given, settings
    from hypothesis import seed as hseed

    tally = Tally()

    @hseed(seed)
    @settings(max_examples=n_cases, deadline=None, database=None,
              suppress_health_check=list(HealthCheck), phases=["generate"])
    @given(cases())
    def _one(case):
        check_case(tally, *case)

    _one()
    return tally


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", type=int, default=2000)
    ap.add_argument("--quick", action="store_true", help="200 cases")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    n = 200 if args.quick else args.cases
    t0 = time.perf_counter()
    tally = run(n, args.seed)
    res = {"cases": n, "seed": args.seed, **tally.as_dict(),
           "wall_s": time.perf_counter() - t0}
    print(f"fuzz cases {n} (hypothesis seed {args.seed}): inputs tried {tally.inputs}, "
          f"worked {tally.ok}, clear errors {tally.clear_errors}, silent failures "
          f"{tally.silent}, unclear errors {tally.unclear}  ({res['wall_s']:.0f} s)")
    for e in tally.examples:
        print("  ", e[:400])
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(res, fh, indent=1)
    return 0 if tally.silent == tally.unclear == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
