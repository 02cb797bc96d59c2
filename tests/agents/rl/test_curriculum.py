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


def test_error_curriculum_with_a_final_scale_above_one_trains_with_a_margin():
    """final_scale > 1: the step schedule ends there and the success schedule is capped there
    (a fixed margin when start_scale == final_scale); the env flies the scaled model."""
    from agents.rl.curriculum import ErrorScaleCurriculum

    venv = make_sb3_vec_env("LunarSoftLanding-v0", 2, seed=0, dt_s=5.0, uncertainty="standard")
    cur = ErrorScaleCurriculum(venv, total_timesteps=400, start_scale=0.5, final_scale=1.5,
                               anneal_fraction=0.5)
    cur.num_timesteps = 100
    assert cur.current_scale == pytest.approx(1.0)
    cur.num_timesteps = 400
    cur.apply()
    assert cur.current_scale == 1.5 and venv.native.error_scale == 1.5
    fixed = ErrorScaleCurriculum(venv, total_timesteps=400, start_scale=1.5, final_scale=1.5)
    assert fixed.current_scale == 1.5 and venv.native.error_scale == 1.5
    by_success = ErrorScaleCurriculum(venv, total_timesteps=400, start_scale=1.0,
                                      final_scale=1.2, anneal_fraction=None,
                                      success_threshold=0.5, scale_step=0.15, window_episodes=1)
    by_success.record_episodes([True] * 5)
    assert by_success.success_scale == pytest.approx(1.2)
    with pytest.raises(ValueError, match=r"success_scale=1.3.*final_scale=1.2"):
        by_success.load_state_dict({"success_scale": 1.3})
    venv.close()


def test_error_curriculum_rejects_bad_arguments_and_an_env_without_errors():
    from agents.rl.curriculum import ErrorScaleCurriculum

    venv = make_sb3_vec_env("LunarSoftLanding-v0", 2, seed=0, uncertainty="standard")
    with pytest.raises(ValueError, match=r"start_scale=1.5 must be in \[0, final_scale=1.0\]"):
        ErrorScaleCurriculum(venv, 100, start_scale=1.5)
    for bad in (0.0, -1.0, float("inf")):
        with pytest.raises(ValueError, match="final_scale"):
            ErrorScaleCurriculum(venv, 100, final_scale=bad)
    with pytest.raises(ValueError, match="anneal_fraction"):
        ErrorScaleCurriculum(venv, 100, anneal_fraction=0.0)
    venv.close()
    plain = make_sb3_vec_env("LunarSoftLanding-v0", 2, seed=0)
    with pytest.raises(ValueError, match="uncertainty"):
        ErrorScaleCurriculum(plain, 100)
    plain.close()


def test_error_curriculum_by_success_rises_only_after_windows_that_land():
    """The success schedule: +scale_step per window of window_episodes finished episodes that
    landed at >= success_threshold, never down; the step-count schedule stays a floor."""
    from agents.rl.curriculum import ErrorScaleCurriculum

    venv = make_sb3_vec_env("LunarSoftLanding-v0", 2, seed=0, dt_s=5.0, uncertainty="standard")
    cur = ErrorScaleCurriculum(venv, total_timesteps=10_000, start_scale=0.0, anneal_fraction=1.0,
                               success_threshold=0.5, scale_step=0.25, window_episodes=4)
    native = venv.native
    cur.record_episodes([True, False, True])          # window not full: nothing moves
    assert cur.success_scale == 0.0
    cur.record_episodes([False])                      # 2 of 4 = threshold: up one step
    assert cur.success_scale == 0.25
    cur.record_episodes([False, False, False, True])  # 1 of 4: stays (never falls)
    assert cur.success_scale == 0.25
    cur.record_episodes([True] * 20)                  # five windows: capped at 1
    assert cur.success_scale == 1.0
    cur.apply()
    assert native.error_scale == 1.0
    # the floor: without successes the step count alone brings the scale to 1 at the end
    slow = ErrorScaleCurriculum(venv, total_timesteps=400, anneal_fraction=1.0,
                                success_threshold=0.9, window_episodes=1)
    slow.record_episodes([False] * 10)
    slow.num_timesteps = 200
    assert slow.success_scale == 0.0 and slow.current_scale == pytest.approx(0.5)
    # no floor: the scale moves only with the landings
    free = ErrorScaleCurriculum(venv, total_timesteps=400, anneal_fraction=None,
                                success_threshold=0.9, window_episodes=1)
    free.num_timesteps = 400
    assert free.current_scale == 0.0
    free.record_episodes([True])
    assert free.current_scale == pytest.approx(0.05)
    with pytest.raises(ValueError, match="needs a success_threshold"):
        ErrorScaleCurriculum(venv, 400, anneal_fraction=None)
    state = cur.state_dict()
    slow.load_state_dict(state)
    assert slow.success_scale == 1.0 and native.error_scale == 1.0
    with pytest.raises(ValueError, match="success_scale"):
        slow.load_state_dict({"success_scale": 1.5})
    # the wrapper counts the verdicts of the episodes that end in step_wait
    live = ErrorScaleCurriculum(venv, total_timesteps=10_000, success_threshold=0.5,
                                window_episodes=1000)
    live.reset()
    n = 0
    while n == 0:
        _, _, done, _ = live.step(np.zeros((2, 1), dtype=np.float32))
        n += int(done.sum())
    assert len(live.state_dict()["window"]) == n
    venv.close()
    for bad, match in (({"success_threshold": 0.0}, "success_threshold"),
                       ({"scale_step": 0.0}, "scale_step"),
                       ({"window_episodes": 0}, "window_episodes"),
                       ({"window_episodes": 2.5}, "window_episodes")):
        v = make_sb3_vec_env("LunarSoftLanding-v0", 2, seed=0, uncertainty="standard")
        with pytest.raises(ValueError, match=match):
            ErrorScaleCurriculum(v, 100, **bad)
        v.close()


def test_error_curriculum_entry_with_an_unknown_key_is_refused_by_name():
    from agents.rl.training import make_training_env

    with pytest.raises(ValueError, match=r"error_curriculum: unknown key\(s\) \['window'\]"):
        make_training_env("LunarSoftLanding-v0", 2, 0, {"uncertainty": "standard"},
                          error_curriculum={"window": 10}, total_timesteps=100)


def test_curriculum_starts_of_an_imu_env_keep_the_reset_reading_of_the_sensor():
    """With ``sensors=("imu",)`` a curriculum start is the task's observation of the pool
    state followed by the reset's IMU reading (the sensor's errors alone: no step flown)."""
    venv = make_sb3_vec_env("LunarPinpointLanding-v3", 4, seed=0, sensors=("imu",),
                            uncertainty="standard")
    cur = OptimalStartCurriculum(venv, total_timesteps=600, start_prob=1.0, n_trajectories=2,
                                 seed=0, progress=False)
    obs = cur.reset()
    native = venv.native
    assert obs.shape == (4, native.single_observation_space.shape[0]) == (4, 11)
    n_task = native.task.n_base_obs
    want = native.observation_from_state(np.asarray(native.state_nd), np.asarray(native.t_s))
    np.testing.assert_array_equal(obs[:, :n_task], want[:, :n_task])
    imu = native.sensor_readings()["imu"] / native.task.imu_ref_m_s2
    np.testing.assert_allclose(obs[:, n_task:], imu, rtol=0, atol=1e-6)
    assert np.all(obs[:, n_task:] != 0.0)  # the errors read, not an ideal sensor's zero
    cur.close()
