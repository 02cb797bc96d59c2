"""The normalised benchmark score (guidance.evaluation.score) and the episode return of fly."""

from __future__ import annotations

import numpy as np
import pytest

from guidance.evaluation.score import RandomLaw, normalised_score
from guidance.flight import PolicyResult, fly
from guidance.law import CallableLaw


def test_score_is_0_at_random_and_100_at_optimum_per_case():
    lo = np.array([-8.0, -7.0, -9.0])
    hi = np.array([-2.0, -1.0, -3.0])
    assert np.allclose(normalised_score(lo, lo, hi).per_case, 0.0)
    assert np.allclose(normalised_score(hi, lo, hi).per_case, 100.0)
    mid = normalised_score(np.array([-5.0, -4.0, -3.0]), lo, hi)
    assert np.allclose(mid.per_case, [50.0, 50.0, 100.0])
    assert mid.mean == pytest.approx(200.0 / 3.0)
    assert mid.n_cases == 3


def test_score_leaves_out_missing_and_degenerate_references():
    sc = normalised_score(np.array([1.0, 1.0, 1.0]), np.array([0.0, np.nan, 2.0]),
                          np.array([2.0, 2.0, 2.0]))
    assert sc.n_cases == 1
    assert sc.per_case[0] == pytest.approx(50.0)
    assert np.isnan(sc.per_case[1:]).all()
    assert normalised_score(np.array([1.0]), np.array([np.nan]), np.array([1.0])).mean != 0.0


def test_score_refuses_mismatched_shapes():
    with pytest.raises(ValueError, match="same length"):
        normalised_score(np.zeros(3), np.zeros(2), np.zeros(3))


def test_fly_episode_return_is_the_sum_of_env_rewards():
    import gymnasium as gym

    import lunar_env  # noqa: F401

    law = CallableLaw(lambda nav: np.full((nav.n, 1), 0.3), name="constant")
    out = fly("LunarSoftLanding-v0", law, 2, seed=5, env_kwargs={"dt_s": 5.0})
    res = PolicyResult.from_rollout("x", np.arange(2), out, {})
    for i in range(2):
        env = gym.make("LunarSoftLanding-v0", dt_s=5.0)
        env.reset(seed=5 + i)
        total, done = 0.0, False
        while not done:
            _, r, term, trunc, _ = env.step(np.array([0.3], dtype=np.float32))
            total += float(r)
            done = term or trunc
        env.close()
        assert res.episode_return[i] == pytest.approx(total, rel=1e-9, abs=1e-9)


def test_random_law_is_seeded_per_case():
    a = fly("LunarSoftLanding-v0", RandomLaw(seed=1), 3, seed=7, env_kwargs={"dt_s": 5.0})
    b = fly("LunarSoftLanding-v0", RandomLaw(seed=1), 2, seed=7, env_kwargs={"dt_s": 5.0})
    assert np.array_equal(a.episode_return[:2], b.episode_return)
    c = fly("LunarSoftLanding-v0", RandomLaw(seed=2), 2, seed=7, env_kwargs={"dt_s": 5.0})
    assert not np.array_equal(c.episode_return, b.episode_return)
