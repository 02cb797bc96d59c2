"""The certified optimal flights as Minari datasets (Farama's offline-RL format).

::

    lunar dataset --n 1000 --minari optimal-v0
    # -> lunar/LunarSoftLanding-v0/optimal-v0 in $MINARI_DATASETS_PATH (~/.minari/datasets)
    lunar dataset --env LunarPinpointLanding-v2 --n 200 --noise 0 --minari optimal-v0
    python -m agents.imitation bc --dataset minari:lunar/LunarSoftLanding-v0/optimal-v0

    >>> import minari
    >>> ds = minari.load_dataset("lunar/LunarSoftLanding-v0/optimal-v0")   # doctest: +SKIP
    >>> env = ds.recover_environment()                                      # doctest: +SKIP

Episodes (:func:`write_minari`): every certified trajectory of an imitation dataset
(:mod:`agents.imitation.dataset`) that starts from the env's initial-state dispersion is flown
again in the env: the native vector env is reset to the trajectory's first state
(``options={"state_nd": ...}``, episode ``i`` seeded ``i``; both are stored with the episode,
so ``env.reset(seed=episode.seed, options=...)`` on the recovered env starts it again), and
the dataset's action labels are flown open loop (the last one held if the landing needs more
steps: the dataset's own certification replay). Observations, actions, rewards, terminations
and truncations are those env transitions (``observations`` one longer than ``actions``: the
final observation is included). ``infos`` (one row per observation) carry the case's optimum:
``optimum_fuel_kg``, ``optimum_tf_s`` and the imitation dataset's ``trajectory_index``.

Which datasets: the soft-landing datasets (labels from the certified Pontryagin optimum), and
pinpoint datasets flown without action noise (``--noise 0``: the expert's flights are then
the flown actions themselves, and the replay reproduces them exactly). A noisy pinpoint
dataset stores the expert's clean labels but not the noisy actions it flew, so its flights
cannot be re-flown and it is refused; mid-flight restarts (``parent_index >= 0``) do not start
from the env's reset distribution and are left out.

Reference scores (Minari's ``get_normalized_score``): ``ref_min_score`` is the mean return of
:class:`guidance.laws.random.RandomLaw` flown from the same starts, ``ref_max_score`` the
mean return of the optimal episodes themselves. Minari accepts ``expert_policy`` only
instead of ``ref_max_score`` (to estimate it by rolling the policy out) and does not store it;
the exact value is given instead.

Reading back (:func:`load_minari`): any Minari dataset of a ``lunar_env`` id becomes an
:class:`agents.imitation.data.ImitationDataset` (``observations`` without each episode's final
one, ``actions``, ``traj_index``), which BC and DAgger read through
``--dataset minari:<dataset id>``.
"""

from __future__ import annotations

import json
import math
import time
from typing import Any

import numpy as np

from agents.imitation.data import ImitationDataset

__all__ = ["MINARI_SCHEME", "NAMESPACE", "minari_dataset_id", "record_episodes",
           "write_minari", "load_minari"]

#: prefix of a Minari dataset id where a dataset path is expected (``--dataset minari:ID``)
MINARI_SCHEME = "minari:"
#: namespace of the project's datasets
NAMESPACE = "lunar"
#: project metadata key inside the Minari dataset's ``description`` JSON
_META_KEY = "lunar_descent_guidance"


def _require_minari():
    try:
        import minari
    except ImportError:
        from gymnasium.error import DependencyNotInstalled

        raise DependencyNotInstalled(
            "Minari datasets need the 'minari' extra: pip install -e '.[minari]'") from None
    return minari


def minari_dataset_id(env_id: str, name: str) -> str:
    """``lunar/<env id>/<name>``; ``name`` must look like ``optimal-v0`` (a version suffix)."""
    import re

    if not re.fullmatch(r"[A-Za-z0-9_.]+(-[A-Za-z0-9_.]+)*-v\d+", name):
        raise ValueError(f"Minari dataset name {name!r}: expected NAME-v<version> with letters, "
                         "digits, '_', '.' and '-', e.g. 'optimal-v0'")
    return f"{NAMESPACE}/{env_id}/{name}"


def _episode_rows(ds: ImitationDataset) -> tuple[np.ndarray, list[np.ndarray], np.ndarray]:
    """The trajectories to fly: dataset indices, their action sequences and first states."""
    a = ds.arrays
    solver = ds.meta.get("solver") or {}
    noise = float(solver.get("action_noise", 0.0) or 0.0)
    if noise > 0:
        raise ValueError(
            f"this dataset's flights were flown with action noise {noise:g} and only the "
            "expert's clean labels are stored, so they cannot be re-flown as env transitions; "
            "make the dataset with --noise 0 for a Minari export")
    tid = a["traj_index"]
    keep = a["certified"].astype(bool)
    if "parent_index" in a:
        keep &= a["parent_index"] < 0
    if "start_time_s" in a:
        keep &= a["start_time_s"] == 0
    ids = [i for i in np.flatnonzero(keep) if np.any(tid == i)]
    if not ids:
        raise ValueError("the dataset has no certified trajectory from the env's dispersion to "
                         "export")
    seqs, x0 = [], []
    for i in ids:
        rows = np.flatnonzero(tid == i)
        rows = rows[np.argsort(a["t_s"][rows], kind="stable")]
        seqs.append(np.asarray(a["actions"][rows], dtype=np.float32))
        x0.append(np.asarray(a["state_nd"][rows[0]], dtype=np.float64))
    return np.asarray(ids, dtype=np.int64), seqs, np.stack(x0)


def record_episodes(env_id: str, env_kwargs: dict[str, Any] | None, x0_nd: np.ndarray,
                    action_seqs: list[np.ndarray], max_steps: int | None = None
                    ) -> list[dict[str, np.ndarray]]:
    """Fly each action sequence open loop from its start; return the env transitions.

    Case ``i`` is sub-env ``i`` of one native vector env reset with ``seed=0`` (so seeded
    ``i``) and ``options={"state_nd": x0_nd}``; after its sequence ends its last action is held.

    Returns
    -------
    list of dict
        Per case: ``observations`` (T+1, n_obs) float32 (the final one included),
        ``actions`` (T, n_act) float32, ``rewards`` (T,) float64, ``terminations`` and
        ``truncations`` (T,) bool.

    Raises
    ------
    RuntimeError
        A case did not end within ``max_steps`` (default: the env's time limit / dt + 10).
    """
    from guidance.flight import make_vec

    n = len(action_seqs)
    venv = make_vec(env_id, n, env_kwargs)
    try:
        obs, _ = venv.reset(seed=0, options={"state_nd": np.asarray(x0_nd, dtype=np.float64)})
        core = venv.unwrapped
        if max_steps is None:
            max_steps = int(math.ceil(core.time_limit_s / core.dt_s)) + 10
        hist = [{"observations": [np.array(obs[i], copy=True)], "actions": [], "rewards": [],
                 "terminations": [], "truncations": []} for i in range(n)]
        active = np.ones(n, dtype=bool)
        n_act = int(np.prod(venv.single_action_space.shape))
        for k in range(max_steps):
            act = np.stack([s[min(k, len(s) - 1)] for s in action_seqs]).astype(np.float32)
            act = act.reshape(n, n_act)
            obs, rew, term, trunc, _ = venv.step(act)
            for i in np.flatnonzero(active):
                h = hist[i]
                h["actions"].append(act[i].copy())
                h["observations"].append(np.array(obs[i], copy=True))
                h["rewards"].append(float(rew[i]))
                h["terminations"].append(bool(term[i]))
                h["truncations"].append(bool(trunc[i]))
            active &= ~(np.asarray(term) | np.asarray(trunc))
            if not active.any():
                break
        else:
            raise RuntimeError(f"{int(active.sum())} replayed cases did not end within "
                               f"{max_steps} steps")
    finally:
        venv.close()
    return [{"observations": np.asarray(h["observations"], dtype=np.float32),
             "actions": np.asarray(h["actions"], dtype=np.float32),
             "rewards": np.asarray(h["rewards"], dtype=np.float64),
             "terminations": np.asarray(h["terminations"], dtype=bool),
             "truncations": np.asarray(h["truncations"], dtype=bool)} for h in hist]


def write_minari(ds: ImitationDataset, dataset_id: str, *, source: str | None = None,
                 overwrite: bool = False):
    """Write the certified optimal flights of ``ds`` as the Minari dataset ``dataset_id``.

    Parameters
    ----------
    ds : ImitationDataset
        A soft-landing dataset, or a pinpoint one made with ``--noise 0`` (module docstring).
    dataset_id : str
        E.g. ``lunar/LunarSoftLanding-v0/optimal-v0`` (:func:`minari_dataset_id`); stored under
        Minari's local datasets directory (``$MINARI_DATASETS_PATH``, default
        ``~/.minari/datasets``).
    source : str, optional
        The ``.npz`` it was made from (recorded in the metadata).
    overwrite : bool
        Replace an existing local dataset of that id (else ``ValueError``).

    Returns
    -------
    minari.MinariDataset

    Raises
    ------
    ValueError
        The id exists and ``overwrite`` is False; the dataset is a noisy-expert one; nothing
        to export.
    """
    minari = _require_minari()
    import gymnasium as gym

    import lunar_env  # noqa: F401  (registers the ids)
    from guidance.flight import fly
    from guidance.laws.random import RandomLaw

    env_id = ds.meta["env_id"]
    env_kwargs = dict(ds.meta.get("env_kwargs") or {})
    if dataset_id in minari.list_local_datasets():
        if not overwrite:
            raise ValueError(f"Minari dataset {dataset_id!r} exists locally; pass overwrite "
                             "(--minari-overwrite) or choose another name/version")
        minari.delete_dataset(dataset_id)
    t0 = time.perf_counter()
    ids, seqs, x0 = _episode_rows(ds)
    episodes = record_episodes(env_id, env_kwargs, x0, seqs)
    a = ds.arrays
    buffers = []
    from minari.data_collector import EpisodeBuffer

    for k, (i, ep) in enumerate(zip(ids, episodes, strict=True)):
        n_obs = len(ep["observations"])
        infos = {"optimum_fuel_kg": np.full(n_obs, float(a["fuel_kg"][i])),
                 "optimum_tf_s": np.full(n_obs, float(a["tf_s"][i])),
                 "trajectory_index": np.full(n_obs, int(i), dtype=np.int64)}
        buffers.append(EpisodeBuffer(id=k, seed=k, options={"state_nd": x0[k]},
                                     observations=ep["observations"], actions=ep["actions"],
                                     rewards=ep["rewards"], terminations=ep["terminations"],
                                     truncations=ep["truncations"], infos=infos))
    returns = np.array([ep["rewards"].sum() for ep in episodes])
    rand = fly(env_id, RandomLaw(), len(ids), seed=0, env_kwargs=env_kwargs,
               reset_options={"state_nd": x0})
    record_s = time.perf_counter() - t0
    env = gym.make(env_id, **env_kwargs)
    project = {"source": source, "imitation_meta": {k: ds.meta.get(k) for k in (
        "env_id", "env_kwargs", "scenario", "seed", "n_trajectories", "dt_s", "label_rule",
        "solver", "certification", "observation_names")},
        "n_episodes": len(ids), "record_wall_s": record_s,
        "optimum_return_mean": float(returns.mean()),
        "random_return_mean": float(np.mean(rand.episode_return))}
    description = (
        f"Certified minimum-fuel landings of {env_id} (lunar-descent-guidance): each episode is "
        "the open-loop replay in the env of one certified optimal trajectory's action labels, "
        "from the trajectory's initial state (episode seed and reset options stored). infos: "
        "optimum_fuel_kg, optimum_tf_s (the case's optimum), trajectory_index. ref_min_score: "
        "uniform-random actions from the same starts; ref_max_score: these episodes' mean "
        "return.\n" + json.dumps({_META_KEY: project}, default=_json_default))
    out = minari.create_dataset_from_buffers(
        dataset_id, buffers, env=env, eval_env=env.spec, algorithm_name="certified-optimum-replay",
        code_permalink="https://github.com/lunar-descent-guidance (agents/imitation/"
                       "minari_data.py)",
        author="lunar-descent-guidance", author_email="none@localhost",
        ref_min_score=float(np.mean(rand.episode_return)),
        ref_max_score=float(returns.mean()), num_episodes_average_score=len(ids),
        description=description, requirements=["lunar-descent-guidance"])
    env.close()
    return out


def _json_default(x: Any):
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")


def load_minari(dataset_id: str) -> ImitationDataset:
    """A Minari dataset of a ``lunar_env`` id as an :class:`~agents.imitation.data.
    ImitationDataset` for BC and DAgger.

    ``observations`` (M, n_obs) are each episode's observations without its final one,
    ``actions`` (M, n_act) the actions taken at them, ``traj_index`` (M,) the episode's
    ``trajectory_index`` info if it has one, else its position; ``meta`` has ``env_id``,
    ``env_kwargs`` (from the dataset's env spec), ``scenario`` and ``minari_id``.

    Raises
    ------
    ValueError
        No local dataset of that id, or its env is not a ``lunar_env`` id.
    """
    minari = _require_minari()
    import gymnasium as gym

    import lunar_env  # noqa: F401

    if dataset_id.startswith(MINARI_SCHEME):
        dataset_id = dataset_id[len(MINARI_SCHEME):]
    local = minari.list_local_datasets()
    if dataset_id not in local:
        raise ValueError(f"no local Minari dataset {dataset_id!r} (datasets directory from "
                         f"MINARI_DATASETS_PATH); local datasets: {sorted(local) or 'none'}")
    mds = minari.load_dataset(dataset_id)
    spec = mds.spec.env_spec
    if spec is None or not str(spec.entry_point).startswith("lunar_env"):
        raise ValueError(f"Minari dataset {dataset_id!r} is not of a lunar_env env "
                         f"(env spec {getattr(spec, 'id', None)!r})")
    registered = gym.spec(spec.id).kwargs
    env_kwargs = {k: v for k, v in spec.kwargs.items()
                  if k != "render_mode" and registered.get(k, object()) != v}
    env = gym.make(spec.id, **env_kwargs)
    scenario = env.unwrapped.scenario.name
    dt_s = float(env.unwrapped.dt_s)
    env.close()
    obs, act, tid, fuel, tf = [], [], [], [], []
    for k, ep in enumerate(mds.iterate_episodes()):
        o = np.asarray(ep.observations, dtype=np.float32)
        obs.append(o[:-1])
        act.append(np.asarray(ep.actions, dtype=np.float32).reshape(len(o) - 1, -1))
        info = ep.infos or {}
        i = int(np.asarray(info["trajectory_index"])[0]) if "trajectory_index" in info else k
        tid.append(np.full(len(o) - 1, i, dtype=np.int64))
        fuel.append(float(np.asarray(info["optimum_fuel_kg"])[0])
                    if "optimum_fuel_kg" in info else np.nan)
        tf.append(float(np.asarray(info["optimum_tf_s"])[0]) if "optimum_tf_s" in info
                  else np.nan)
    arrays = {"observations": np.concatenate(obs), "actions": np.concatenate(act),
              "traj_index": np.concatenate(tid), "fuel_kg": np.asarray(fuel),
              "tf_s": np.asarray(tf), "certified": np.ones(len(fuel), dtype=bool)}
    meta = {"env_id": spec.id, "env_kwargs": env_kwargs, "scenario": scenario, "dt_s": dt_s,
            "minari_id": dataset_id, "n_trajectories": len(fuel)}
    return ImitationDataset(meta, arrays)
