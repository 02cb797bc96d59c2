"""Imitation from optimal trajectories: dataset format and resume, BC into SB3 PPO, DAgger,
evaluation — the quick end-to-end version of ``lunar dataset`` / ``agents.imitation``."""

from __future__ import annotations

import json

import numpy as np
import pytest

from agents.imitation import cli as im
from agents.imitation import data as dsm_data
from agents.imitation import dataset as dsm
from agents.imitation.policy import build_model

ENV_ID = "LunarSoftLanding-v0"


@pytest.fixture(scope="module")
def small_dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("ds") / "small.npz"
    ds = dsm.generate(out, n=6, seed=3, n_workers=1, shard_size=3, progress=False)
    assert ds is not None
    return out, ds


@pytest.fixture(scope="module")
def bc_dir(small_dataset, tmp_path_factory):
    """A one-epoch BC run on the small dataset (the initial policy of the fine-tuning tests)."""
    path, _ = small_dataset
    out = tmp_path_factory.mktemp("bc_run") / "bc"
    assert im.main(["bc", "--quick", "--dataset", str(path), "--run-dir", str(out),
                    "--seed", "0", "--no-progress", "--no-tensorboard",
                    "--hyperparams", "bc.n_epochs=1"]) == 0
    return out


def test_dataset_samples_are_certified_and_in_env_spaces(small_dataset):
    import gymnasium as gym

    import lunar_env  # noqa: F401

    path, ds = small_dataset
    a = ds.arrays
    assert ds.n_trajectories == 6 and a["certified"].all()
    assert np.all(a["terminal_error_speed_m_s"] < 1e-3)
    assert np.all(a["replay_success"])
    # the labels replayed open-loop in the env cost the optimum's fuel (to 0.05 kg)
    assert np.all(np.abs(a["replay_fuel_gap_kg"]) < 0.05)
    env = gym.make(ENV_ID)
    assert all(env.observation_space.contains(o) for o in ds.observations[::50])
    assert all(env.action_space.contains(x) for x in ds.actions[::50])
    # sample 0 of each trajectory is exactly the env's first observation from that state
    for i in range(ds.n_trajectories):
        obs0, _ = env.reset(options={"state_si": a["initial_state_si"][i]})
        first = np.flatnonzero(a["traj_index"] == i)[0]
        np.testing.assert_allclose(ds.observations[first], obs0, rtol=1e-6, atol=1e-6)
    # samples per trajectory: one per env step before tf
    for i in range(ds.n_trajectories):
        k = int(np.sum(a["traj_index"] == i))
        assert k == int(np.ceil(a["tf_s"][i] / ds.meta["dt_s"]))
    env.close()


def test_dataset_round_trip_and_version_check(small_dataset, tmp_path):
    path, ds = small_dataset
    again = dsm_data.load_dataset(path)
    assert again.meta["format_version"] == dsm_data.FORMAT_VERSION
    assert again.meta["scenario"] == "zhu2007" and again.meta["env_id"] == ENV_ID
    assert again.meta["solver"]["name"] == "optimizers.indirect.batch.solve_many"
    for k, v in ds.arrays.items():
        np.testing.assert_array_equal(again.arrays[k], v)
    # re-save and reload: identical
    p2 = dsm_data.save_dataset(tmp_path / "copy.npz", again.meta, again.arrays)
    np.testing.assert_array_equal(dsm_data.load_dataset(p2).actions, ds.actions)
    # another format version is refused with a clear message
    meta = dict(again.meta)
    bad = tmp_path / "bad.npz"
    np.savez(bad, meta=np.array(json.dumps(dict(meta, format_version=999))), **again.arrays)
    with pytest.raises(ValueError, match="format_version"):
        dsm_data.load_dataset(bad)
    np.savez(tmp_path / "nometa.npz", x=np.zeros(3))
    with pytest.raises(ValueError, match="meta"):
        dsm_data.load_dataset(tmp_path / "nometa.npz")


def test_dataset_resume_skips_finished_shards(tmp_path):
    out = tmp_path / "r.npz"
    assert dsm.generate(out, n=4, seed=5, n_workers=1, shard_size=2, progress=False,
                        max_shards=1) is None  # "interrupted" after one shard
    # the shards are a ResultStore: results/<TaskKey filename>.npz
    (shard0,) = (tmp_path / "r.npz.shards" / "results").glob("*.npz")
    assert shard0.name.endswith("__seed5__000000.npz") and not out.exists()
    stat0 = shard0.stat()
    ds = dsm.generate(out, n=4, seed=5, n_workers=1, shard_size=2, progress=False)
    assert ds is not None and ds.n_trajectories == 4 and ds.arrays["certified"].all()
    st = shard0.stat()
    assert (st.st_mtime_ns, st.st_ino) == (stat0.st_mtime_ns, stat0.st_ino)  # not redone
    timing = json.loads((tmp_path / "r.npz.shards" / "timing.json").read_text())
    assert [t["new_shards"] for t in timing] == [1, 1]
    # other settings on the same shard directory are refused
    with pytest.raises(ValueError, match="other settings"):
        dsm.generate(out, n=4, seed=6, n_workers=1, shard_size=2, progress=False)


def test_bc_dagger_end_to_end(small_dataset, tmp_path):
    import torch as th
    from stable_baselines3 import PPO

    from agents.laws import SB3Law
    from guidance.evaluation.compare import compare

    path, ds = small_dataset
    bc_dir = tmp_path / "bc"
    assert im.main(["bc", "--quick", "--dataset", str(path), "--run-dir", str(bc_dir),
                    "--seed", "0", "--no-progress", "--no-tensorboard",
                    "--hyperparams", "bc.n_epochs=3"]) == 0
    # the cloned policy is a PPO model that SB3 loads, with the cloned weights
    model = PPO.load(bc_dir / "model.zip")
    ck = th.load(bc_dir / "checkpoints" / "bc_epoch_2.pt", weights_only=False)
    for k, v in ck["policy"].items():
        np.testing.assert_array_equal(model.policy.state_dict()[k].numpy(), v.numpy())
    pred, _ = model.predict(ds.observations[:500], deterministic=True)
    err_bc = float(np.sqrt(np.mean((pred - ds.actions[:500]) ** 2)))
    fresh = build_model(ENV_ID, {}, {"net_arch": {"pi": [64, 64], "vf": [64, 64]},
                                        "activation_fn": "tanh"}, seed=0)
    p0, _ = fresh.predict(ds.observations[:500], deterministic=True)
    err0 = float(np.sqrt(np.mean((p0 - ds.actions[:500]) ** 2)))
    assert err_bc < 0.5 * err0, (err_bc, err0)
    # resume: one more epoch continues from the last checkpoint
    import yaml

    cfg = yaml.safe_load((bc_dir / "config.yml").read_text())
    cfg["bc"]["n_epochs"] = 4
    (bc_dir / "config.yml").write_text(yaml.safe_dump(cfg))
    assert im.main(["bc", "--resume", str(bc_dir), "--no-progress"]) == 0
    assert (bc_dir / "checkpoints" / "bc_epoch_3.pt").exists()

    dg_dir = tmp_path / "dagger"
    assert im.main(["dagger", "--quick", "--dataset", str(path), "--init", str(bc_dir),
                    "--run-dir", str(dg_dir), "--seed", "0", "--no-progress",
                    "--no-tensorboard", "--hyperparams", "dagger.n_episodes=1",
                    "dagger.label_every=100", "dagger.dense_tail_s=0"]) == 0
    hist = yaml.safe_load((dg_dir / "dagger_history.yml").read_text())
    assert len(hist) == 1 and hist[0]["n_labels"] > 0
    with np.load(dg_dir / "labels" / "iter_000.npz") as z:
        assert z["obs"].shape[1] == 5 and np.all(np.abs(z["actions"]) <= 1.0)
    # DAgger resume with everything done: loads the last iteration, trains nothing new
    assert im.main(["dagger", "--resume", str(dg_dir), "--no-progress"]) == 0
    model = PPO.load(dg_dir / "model.zip")
    # the same evaluation as the RL policies, on a few states
    rep = compare(ENV_ID, [SB3Law(model, None, name="DAgger")], n_states=3, seed=2026,
                  open_loop=False, n_expert_states=0, progress=False)
    row = rep["rows"][0]
    assert row["policy"] == "DAgger" and row["n_cases"] == 3
    assert np.isfinite(row["fuel_mean_kg"]) and row["us_per_decision"] > 0


def test_train_init_from_bc_starts_from_cloned_weights(bc_dir, tmp_path):
    """``train.py --init-from <bc run>``: PPO starts from the cloned policy (learning rate 0 here,
    so the saved model must still hold exactly the cloned weights, except PPO's own log_std)."""
    import yaml
    from stable_baselines3 import PPO

    from agents import train

    ft_dir = tmp_path / "ft"
    assert train.main(["--quick", "--init-from", str(bc_dir), "--run-dir", str(ft_dir),
                       "--seed", "0", "--no-eval", "--no-progress", "--no-tensorboard",
                       "-n", "1024", "--verbose", "0", "--hyperparams", "curriculum=null",
                       "env_kwargs={dt_s: 1.0}", "learning_rate=0.0"]) == 0
    assert yaml.safe_load((ft_dir / "args.yml").read_text())["init_from"] == str(bc_dir)
    bc = PPO.load(bc_dir / "model.zip").policy.state_dict()
    ft = PPO.load(ft_dir / "model.zip").policy.state_dict()
    for k, v in bc.items():
        if k != "log_std":
            np.testing.assert_array_equal(ft[k].numpy(), v.numpy(), err_msg=k)
    vn = ft_dir / "vecnormalize.pkl"
    if vn.exists():  # reward normalisation may stay; observations must reach the policy raw
        import pickle

        with open(vn, "rb") as fh:
            assert pickle.load(fh).norm_obs is False


def test_critic_warmup_holds_the_cloned_actor_and_trains_the_value(bc_dir, tmp_path):
    """``critic_warmup_steps``: while it lasts PPO's updates (learning rate > 0 here) leave the
    cloned actor and log_std exactly as they were and fit only the value function."""
    from stable_baselines3 import PPO

    from agents import train

    ft_dir = tmp_path / "ft"
    assert train.main(["--quick", "--init-from", str(bc_dir), "--run-dir", str(ft_dir),
                       "--seed", "0", "--no-eval", "--no-progress", "--no-tensorboard",
                       "-n", "2048", "--verbose", "0", "--hyperparams", "curriculum=null",
                       "env_kwargs={dt_s: 1.0}", "learning_rate=0.001",
                       "critic_warmup_steps=100000"]) == 0
    bc = PPO.load(bc_dir / "model.zip").policy.state_dict()
    ft = PPO.load(ft_dir / "model.zip").policy.state_dict()
    actor = [k for k in bc if k.startswith(("mlp_extractor.policy_net", "action_net"))]
    critic = [k for k in bc if k.startswith(("mlp_extractor.value_net", "value_net"))]
    assert actor and critic
    for k in actor:
        np.testing.assert_array_equal(ft[k].numpy(), bc[k].numpy(), err_msg=k)
    assert any(not np.array_equal(ft[k].numpy(), bc[k].numpy()) for k in critic)
    with pytest.raises(ValueError, match="critic_warmup_steps"):
        train.main(["--quick", "--run-dir", str(tmp_path / "bad"), "--no-eval",
                    "--no-progress", "--no-tensorboard", "-n", "64",
                    "--hyperparams", "critic_warmup_steps=-1"])


#: tasks run by :func:`_counting_label_chunk` (module level: the executor refuses closures),
#: and the real task it delegates to
_LABEL_CALLS: list[int] = []
_REAL_LABEL_CHUNK: list = []


def _counting_label_chunk(job):
    _LABEL_CALLS.append(len(job["episodes"]))
    return _REAL_LABEL_CHUNK[0](job)


def test_dagger_label_parts_resume_from_the_result_store(small_dataset, tmp_path, monkeypatch):
    """Planar DAgger labels are executor tasks with a ResultStore: a re-run reuses every stored
    part and labels only the missing ones (a kill loses only the tasks in flight), with the
    same labels."""
    import agents.imitation.families.planar as pd
    from lunar_env import get_scenario

    _, ds = small_dataset
    eps = []
    for j in range(2):  # two optimal trajectories of the dataset as "roll-outs"
        m = ds.arrays["traj_index"] == j
        eps.append({"obs": ds.observations[m], "state_nd": ds.arrays["state_nd"][m],
                    "t_s": ds.arrays["t_s"][m]})
    sc = get_scenario(ds.meta["scenario"])
    args = (eps, sc.name, float(ds.meta["dt_s"]), 40, 0.0)
    kw = {"progress": False, "velocity_ref_m_s": sc.scaling().velocity_m_s}
    store = tmp_path / "parts"
    _REAL_LABEL_CHUNK[:] = [pd.label_chunk]
    monkeypatch.setattr(pd, "label_chunk", _counting_label_chunk)
    _LABEL_CALLS.clear()
    first = pd.label_episodes(*args, cache_dir=store, **kw)
    assert _LABEL_CALLS == [1, 1] and len(first["obs"]) > 0
    parts = sorted((store / "results").glob("*.pkl"))
    assert len(parts) == 2
    parts[1].unlink()  # as if killed while the second task ran
    _LABEL_CALLS.clear()
    again = pd.label_episodes(*args, cache_dir=store, **kw)
    assert _LABEL_CALLS == [1]  # only the missing part was labelled again
    for k in first:
        np.testing.assert_array_equal(again[k], first[k], err_msg=k)
    # labels of other settings never mix with the stored ones
    with pytest.raises(ValueError, match="label_every"):
        pd.label_episodes(eps, sc.name, float(ds.meta["dt_s"]), 20, 0.0, cache_dir=store, **kw)
    # another family's scenario is refused by name
    with pytest.raises(ValueError, match="'wang2001_transfer' is not a planar scenario"):
        pd.label_episodes(eps, "wang2001_transfer", 1.0, 40, 0.0, progress=False)


def test_dagger_under_uncertainty_records_its_env_kwargs(small_dataset, bc_dir, tmp_path):
    """``--config robust`` (env_kwargs {uncertainty: standard} merged over the dataset's) and
    ``dagger.teacher=navigated``: the roll-outs fly under the errors, and config.yml keeps the
    merged env arguments (what loading the run later flies); a run may not change the
    dataset's decision interval."""
    import yaml

    from agents.common.runs import read_run

    path, _ = small_dataset
    dg_dir = tmp_path / "dagger_robust"
    # only each roll-out's first state is labelled (no tail): the 1-epoch clone's later states
    # are unlandable, and the expert spends seconds on each before its fallback
    quick = ["dagger.n_iterations=1", "dagger.n_episodes=2", "dagger.n_epochs=1",
             "dagger.label_every=100000", "dagger.dense_tail_s=-1", "dagger.n_label_workers=1",
             "dagger.batch_size=256"]
    assert im.main(["dagger", "--config", "robust", "--dataset", str(path), "--init", str(bc_dir),
                    "--run-dir", str(dg_dir), "--seed", "0", "--no-progress",
                    "--no-tensorboard", "--hyperparams", "dagger.teacher=navigated",
                    *quick]) == 0
    cfg = yaml.safe_load((dg_dir / "config.yml").read_text())
    assert cfg["env_kwargs"] == {"uncertainty": "standard"}
    assert cfg["dagger"]["teacher"] == "navigated"
    assert read_run(dg_dir)[1]["env_kwargs"] == {"uncertainty": "standard"}
    hist = yaml.safe_load((dg_dir / "dagger_history.yml").read_text())
    assert len(hist) == 1 and hist[0]["n_labels"] == 2
    with pytest.raises(SystemExit):
        im.main(["dagger", "--config", "robust", "--dataset", str(path), "--init", str(bc_dir),
                 "--run-dir", str(tmp_path / "bad"), "--no-progress", "--no-tensorboard",
                 "--hyperparams", "env_kwargs.dt_s=2.5", *quick])
    assert not (tmp_path / "bad").exists()
