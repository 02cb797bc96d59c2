"""Optimal-start curriculum: starts on optimal trajectories, consistent clock, annealing."""

import numpy as np
import pytest

from agents.common.vec_env import make_sb3_vec_env
from agents.rl.curriculum import OptimalStartCurriculum


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


def test_start_noise_perturbs_pinpoint_starts_off_the_optimal_trajectories():
    venv = make_sb3_vec_env("LunarPinpointLanding-v2", 64, seed=0, dt_s=2.0)
    cur = OptimalStartCurriculum(venv, total_timesteps=10_000, start_prob=1.0,
                                 n_trajectories=2, seed=0, progress=False,
                                 start_noise={"position_m": 100.0, "velocity_m_s": 1.0})
    cur.reset()
    s = venv.native.scenario.scaling()
    y = np.asarray(venv.native.state_nd)
    t = np.asarray(venv.native.t_s)
    # the nearest pool point at the same clock: the perturbation's size in metres and m/s
    dp, dv = [], []
    for i in range(64):
        k, j = np.argwhere(np.isclose(cur.pool_times, t[i], rtol=0, atol=1e-9))[0]
        d = y[i] - cur.pool_states[k, j]
        dp.append(np.linalg.norm(d[:3]) * s.length_m)
        dv.append(np.linalg.norm(d[3:6]) * s.velocity_m_s)
        assert d[6] == 0.0  # the mass is not perturbed
    # |N(0, σ² I₃)| has mean σ·2√(2/π) ≈ 1.6 σ
    assert 100.0 < np.mean(dp) < 220.0 and 1.0 < np.mean(dv) < 2.2
    cur.close()
    soft = make_sb3_vec_env("LunarSoftLanding-v0", 2, seed=0)
    with pytest.raises(ValueError, match="start_noise is not available for the planar"):
        OptimalStartCurriculum(soft, 100, n_trajectories=2, progress=False,
                               start_noise={"position_m": 1.0})
    soft.close()


def test_error_curriculum_anneals_the_uncertainty_in_and_then_flies_the_full_set():
    from agents.rl.curriculum import ErrorScaleCurriculum

    venv = make_sb3_vec_env("LunarSoftLanding-v0", 4, seed=0, dt_s=5.0, uncertainty="standard")
    cur = ErrorScaleCurriculum(venv, total_timesteps=400, start_scale=0.2, anneal_fraction=0.5)
    native = venv.native
    assert cur.current_scale == pytest.approx(0.2) and native.error_scale == pytest.approx(0.2)
    cur.reset()
    scales = []
    for _ in range(60):  # 240 env steps: the scale reaches 1 at step 200
        cur.step(np.zeros((4, 1), dtype=np.float32))
        scales.append(native.error_scale)
    assert all(b >= a for a, b in zip(scales, scales[1:], strict=False))
    assert scales[0] == pytest.approx(0.2 + 0.8 * 4 / 200, abs=ErrorScaleCurriculum.STEP)
    assert native.error_scale == 1.0 and cur.current_scale == 1.0
    cur.close()


def test_error_curriculum_rejects_bad_arguments_and_an_env_without_errors():
    from agents.rl.curriculum import ErrorScaleCurriculum

    venv = make_sb3_vec_env("LunarSoftLanding-v0", 2, seed=0, uncertainty="standard")
    with pytest.raises(ValueError, match="start_scale"):
        ErrorScaleCurriculum(venv, 100, start_scale=1.5)
    with pytest.raises(ValueError, match="anneal_fraction"):
        ErrorScaleCurriculum(venv, 100, anneal_fraction=0.0)
    venv.close()
    plain = make_sb3_vec_env("LunarSoftLanding-v0", 2, seed=0)
    with pytest.raises(ValueError, match="uncertainty"):
        ErrorScaleCurriculum(plain, 100)
    plain.close()
