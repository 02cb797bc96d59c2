"""Minari export of the certified optimal flights (agents.imitation.minari_data): written by
``lunar dataset --minari``, read back bit for bit in a fresh process, the env
recovered from the dataset replays it, and BC reads it through ``--dataset minari:ID``."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("minari")

from agents.imitation import cli as im  # noqa: E402
from agents.imitation import make_dataset as dataset_cli  # noqa: E402
from agents.imitation.data import load_dataset  # noqa: E402
from agents.imitation.minari_data import (  # noqa: E402
    _episode_rows,
    minari_dataset_id,
    record_episodes,
    write_minari,
)
from agents.imitation.sources import open_dataset  # noqa: E402

REPO = Path(__file__).resolve().parents[3]
ENV_ID = "LunarSoftLanding-v0"
DATASET_ID = f"lunar/{ENV_ID}/optimal-v0"


@pytest.fixture(scope="module")
def exported(minari_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("ds") / "small.npz"
    assert dataset_cli.main(["--n", "5", "--seed", "4", "--workers", "1", "--shard-size", "5",
                             "--out", str(out), "--no-progress", "--minari", "optimal-v0"]) == 0
    return out, load_dataset(out)


def test_dataset_id_names_the_env_and_a_version():
    assert minari_dataset_id(ENV_ID, "optimal-v0") == DATASET_ID
    with pytest.raises(ValueError, match="'optimal'"):
        minari_dataset_id(ENV_ID, "optimal")


def test_fresh_process_reads_the_episodes_bit_for_bit(exported, minari_dir, tmp_path):
    path, ds = exported
    ids, seqs, x0 = _episode_rows(ds)
    expected = record_episodes(ENV_ID, {}, x0, seqs)
    dump = tmp_path / "dump.npz"
    code = (
        "import sys, numpy as np, minari\n"
        f"d = minari.load_dataset({DATASET_ID!r})\n"
        "arrs = {}\n"
        "for k, ep in enumerate(d.iterate_episodes()):\n"
        "    for f in ('observations', 'actions', 'rewards', 'terminations', 'truncations'):\n"
        "        arrs[f'{k}_{f}'] = np.asarray(getattr(ep, f))\n"
        "    arrs[f'{k}_fuel'] = np.asarray(ep.infos['optimum_fuel_kg'])\n"
        "np.savez(sys.argv[1], **arrs)\n"
        "m = d.storage.metadata\n"
        "print(m['ref_min_score'], m['ref_max_score'], d.total_episodes)\n")
    env = dict(os.environ, PYTHONPATH=str(REPO), MINARI_DATASETS_PATH=str(minari_dir))
    proc = subprocess.run([sys.executable, "-c", code, str(dump)], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    lo, hi, n = proc.stdout.split()
    assert int(n) == len(ids) == 5
    got = np.load(dump)
    for k, ep in enumerate(expected):
        for f, arr in ep.items():
            back = got[f"{k}_{f}"]
            assert back.dtype == arr.dtype and back.shape == arr.shape, f
            assert np.array_equal(back, arr), f"episode {k} {f} differs"
        assert got[f"{k}_fuel"][0] == ds.arrays["fuel_kg"][ids[k]]
        # a real landing: one termination at the end, the episode's last step
        assert ep["terminations"][-1] and not ep["terminations"][:-1].any()
    # reference scores: the optimum's mean return above the random law's
    returns = [ep["rewards"].sum() for ep in expected]
    assert float(hi) == pytest.approx(np.mean(returns))
    assert float(lo) < float(hi)


def test_recovered_env_replays_the_episodes(exported):
    import minari

    _, ds = exported
    _, _, x0 = _episode_rows(ds)
    mds = minari.load_dataset(DATASET_ID)
    env = mds.recover_environment()
    for k, ep in enumerate(mds.iterate_episodes()):
        obs, _ = env.reset(seed=k, options={"state_nd": x0[k]})
        np.testing.assert_allclose(obs, ep.observations[0], rtol=0, atol=1e-6)
        for t, a in enumerate(ep.actions):
            obs, r, term, trunc, _ = env.step(a)
            assert r == pytest.approx(ep.rewards[t], rel=1e-6, abs=1e-9)
            assert term == ep.terminations[t] and trunc == ep.truncations[t]
        np.testing.assert_allclose(obs, ep.observations[-1], rtol=0, atol=1e-5)
    env.close()


def test_minari_dataset_reads_as_the_imitation_dataset_it_came_from(exported):
    _, ds = exported
    back = open_dataset(f"minari:{DATASET_ID}")
    assert back.meta["env_id"] == ENV_ID and back.meta["scenario"] == ds.meta["scenario"]
    a = ds.arrays
    for i in np.unique(a["traj_index"]):
        src = np.flatnonzero(a["traj_index"] == i)
        dst = np.flatnonzero(back.arrays["traj_index"] == i)
        # the labelled steps carry the dataset's actions exactly, the observations re-flown
        # in the env agree with the optimum's to the integrator's accuracy
        assert len(dst) >= len(src)
        assert np.array_equal(back.actions[dst[:len(src)]], a["actions"][src])
        np.testing.assert_allclose(back.observations[dst[:len(src)]], a["observations"][src],
                                   rtol=0, atol=1e-4)


def test_existing_id_is_refused_without_overwrite(exported):
    _, ds = exported
    with pytest.raises(ValueError, match="exists locally"):
        write_minari(ds, DATASET_ID)


def test_noisy_expert_dataset_is_refused_with_the_reason(exported):
    _, ds = exported
    noisy = type(ds)(dict(ds.meta, solver={"action_noise": 0.02}), ds.arrays)
    with pytest.raises(ValueError, match="action noise 0.02"):
        write_minari(noisy, f"lunar/{ENV_ID}/noisy-v0")


def test_bc_trains_from_the_minari_dataset(exported, tmp_path):
    out = tmp_path / "bc"
    assert im.main(["bc", "--quick", "--dataset", f"minari:{DATASET_ID}", "--run-dir",
                    str(out), "--seed", "0", "--no-progress", "--no-tensorboard",
                    "--hyperparams", "bc.n_epochs=1"]) == 0
    assert (out / "model.zip").is_file()
    args = json.loads(json.dumps(__import__("yaml").safe_load((out / "args.yml").read_text())))
    assert args["dataset"] == f"minari:{DATASET_ID}"


@pytest.mark.slow
def test_pinpoint_noise_free_export_gives_bc_the_same_data_and_policy(minari_dir, tmp_path):
    """Pinpoint without action noise: the Minari episodes are the expert's flights themselves,
    so BC from ``minari:ID`` and BC from the ``.npz`` train on identical arrays and end with
    identical weights (same seed)."""
    import torch as th

    env_id = "LunarPinpointLanding-v2"
    out = tmp_path / "pin.npz"
    assert dataset_cli.main(["--env", env_id, "--n", "2", "--seed", "5", "--noise", "0",
                             "--workers", "1", "--out", str(out), "--no-progress",
                             "--minari", "optimal-v0"]) == 0
    a = load_dataset(out)
    b = open_dataset(f"minari:lunar/{env_id}/optimal-v0")
    assert np.array_equal(a.observations, b.observations)
    assert np.array_equal(a.actions, b.actions)
    assert np.array_equal(a.arrays["traj_index"], b.arrays["traj_index"])
    weights = []
    for name, src in (("npz", str(out)), ("minari", f"minari:lunar/{env_id}/optimal-v0")):
        run = tmp_path / name
        assert im.main(["bc", "--quick", "--env", env_id, "--dataset", src, "--run-dir",
                        str(run), "--seed", "1", "--no-progress", "--no-tensorboard",
                        "--hyperparams", "bc.n_epochs=2"]) == 0
        from stable_baselines3 import PPO

        weights.append(PPO.load(run / "model.zip", device="cpu").policy.state_dict())
    for k, v in weights[0].items():
        assert th.equal(v, weights[1][k]), k
