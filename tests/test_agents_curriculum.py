"""Optimal-start curriculum: starts on optimal trajectories, consistent clock, annealing."""

import numpy as np
import pytest

from agents.curriculum import OptimalStartCurriculum
from agents.vec_env import make_sb3_vec_env


def test_curriculum_starts_on_optimal_trajectories_and_anneals():
    venv = make_sb3_vec_env("LunarSoftLanding-v0", 6, seed=0, dt_s=5.0)
    cur = OptimalStartCurriculum(venv, total_timesteps=600, start_prob=1.0, anneal_fraction=0.5,
                                 n_trajectories=4, min_time_fraction=0.5, seed=0, progress=False)
    obs = cur.reset()
    native = venv.native
    y = np.asarray(native.state_nd)
    t = np.asarray(native.t_s)
    # every sub-env starts at a pool point of the second half of an optimal flight ...
    pool = cur.pool_states.reshape(-1, 5)
    for i in range(6):
        assert np.min(np.abs(pool - y[i]).max(axis=1)) == 0.0
    assert np.all(t >= 0.5 * cur.pool_times[:, -1].min() - 1e-9)
    # ... with the observation of that state and time
    np.testing.assert_allclose(obs, native.observation_from_state(y, t), rtol=0, atol=0)
    assert cur.current_prob == 1.0
    for _ in range(100):  # 600 env steps: p decays to 0 at 300
        obs, _, done, infos = cur.step(np.zeros((6, 1), dtype=np.float32))
    assert cur.current_prob == 0.0
    assert cur.n_curriculum_starts >= 6
    cur.close()


def test_curriculum_rejects_bad_arguments():
    venv = make_sb3_vec_env("LunarSoftLanding-v0", 2, seed=0)
    with pytest.raises(ValueError, match="start_prob"):
        OptimalStartCurriculum(venv, 100, start_prob=1.5, n_trajectories=2, progress=False)
    with pytest.raises(ValueError, match="min_time_fraction"):
        OptimalStartCurriculum(venv, 100, min_time_fraction=0.9, max_time_fraction=0.5,
                               n_trajectories=2, progress=False)
    venv.close()
