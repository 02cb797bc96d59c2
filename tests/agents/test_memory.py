"""Policies with memory: the stacked history (layout, per-row reset, the same inputs in training
and in flight), the recurrent law (LSTM state per row, reset per row at ``episode_start``), the
sequence evaluation of the LSTM policy, training, saving, loading and flying both as laws, and
refusals of bad settings."""

from __future__ import annotations

import sys

import gymnasium as gym
import numpy as np
import pytest
import yaml
from gymnasium import spaces
from stable_baselines3.common.vec_env import VecEnv

import lunar_env  # noqa: F401  (registers the ids)
from agents import train as tr
from agents.features.history import (
    MAX_HISTORY,
    HistoryStack,
    HistoryWrapper,
    history_space,
    validate_history,
)
from agents.laws import SB3Law, law_from_spec
from guidance.flight import decide, navigation, rollout
from guidance.law import FlightComputer
from guidance.registry import LawContext, LawSpec

pytest.importorskip("sb3_contrib")

ENV_ID = "LunarSoftLanding-v0"
ENV_KWARGS = {"dt_s": 2.5}
SEEDS = (21, 22, 23)
#: a tiny configuration of train.py: 4 landers x 64 steps, one rollout, no curriculum
TINY = ["--quick", "--no-progress", "--no-tensorboard", "--torch-threads", "1", "--seed", "5",
        "-n", "256", "--n-envs", "4", "--hyperparams", "n_steps=64", "batch_size=128",
        "curriculum=null"]


# ----------------------------------------------------------------------------- history


def test_history_stack_layout_and_per_row_reset():
    """Inputs oldest first, then actions oldest first; a started row holds its first input in
    every slot and zero actions; only the rows named advance or restart."""
    h = HistoryStack(n=2, k=3, n_obs=2, n_act=1)
    o0 = np.array([[1, 10], [2, 20]], dtype=np.float32)
    h.start(o0)
    np.testing.assert_array_equal(h.stacked(), [[1, 10, 1, 10, 1, 10, 0, 0, 0],
                                                [2, 20, 2, 20, 2, 20, 0, 0, 0]])
    h.push(o0 + 1, np.array([[0.5], [-0.5]]))
    h.push(o0 + 2, np.array([[0.25], [-0.25]]))
    np.testing.assert_array_equal(h.stacked()[0], [1, 10, 2, 11, 3, 12, 0, 0.5, 0.25])
    h.push(o0 + 3, np.array([[0.125], [-0.125]]), rows=np.array([True, False]))
    h.start(o0 + 7, rows=np.array([False, True]))
    np.testing.assert_array_equal(h.stacked(), [[2, 11, 3, 12, 4, 13, 0.5, 0.25, 0.125],
                                                [9, 27, 9, 27, 9, 27, 0, 0, 0]])
    assert h.width == 9
    box = history_space(spaces.Box(-1, 2, (2,)), spaces.Box(-1, 1, (1,)), 3)
    assert box.shape == (9,) and box.low.tolist() == [-1] * 9
    assert box.high.tolist() == [2] * 6 + [1] * 3
    with pytest.raises(ValueError, match=r"obs has shape \(1, 2\); expected \(2, 2\)"):
        h.start(o0[:1])


class _Counter(VecEnv):
    """Sub-env i observes (i, its step count in the episode); its episode ends at the steps
    ``ends[i]`` (same-step reset: the terminal observation in ``info``)."""

    def __init__(self, ends):
        self.ends = ends
        self.t = np.zeros(len(ends))
        super().__init__(len(ends), spaces.Box(-100, 100, (2,)), spaces.Box(-1, 1, (1,)))

    def _obs(self):
        return np.stack([np.arange(self.num_envs), self.t], axis=1).astype(np.float32)

    def reset(self):
        self.t[:] = 0
        return self._obs()

    def step_async(self, actions):
        self.actions = actions

    def step_wait(self):
        self.t += 1
        done = np.array([self.t[i] in self.ends[i] for i in range(self.num_envs)])
        infos = [{} for _ in range(self.num_envs)]
        last = self._obs()
        for i in np.flatnonzero(done):
            infos[i]["terminal_observation"] = last[i]
            self.t[i] = 0
        return self._obs(), np.zeros(self.num_envs), done, infos

    def close(self):
        pass

    def get_attr(self, name, indices=None):
        return [getattr(self, name, None)] * self.num_envs

    def set_attr(self, name, value, indices=None):
        pass

    def env_method(self, name, *args, indices=None, **kwargs):
        return []

    def env_is_wrapped(self, wrapper_class, indices=None):
        return [False] * self.num_envs


def test_history_wrapper_restarts_a_row_in_the_step_its_episode_ends():
    """Sub-env 1 ends at its second step: its next row is a fresh history of its next
    episode's first observation, its terminal observation the ended episode's history advanced
    by the last action; sub-env 0 keeps its history."""
    venv = HistoryWrapper(_Counter([(), (2,)]), k=2)
    assert venv.observation_space.shape == (6,)
    first = venv.reset()
    np.testing.assert_array_equal(first, [[0, 0, 0, 0, 0, 0], [1, 0, 1, 0, 0, 0]])
    venv.step(np.array([[0.1], [0.2]]))
    obs, _, done, infos = venv.step(np.array([[0.3], [0.4]]))
    assert done.tolist() == [False, True]
    np.testing.assert_allclose(obs[0], [0, 1, 0, 2, 0.1, 0.3])
    np.testing.assert_allclose(obs[1], [1, 0, 1, 0, 0, 0])
    np.testing.assert_allclose(infos[1]["terminal_observation"], [1, 1, 1, 2, 0.2, 0.4])
    obs, *_ = venv.step(np.array([[0.5], [0.6]]))
    np.testing.assert_allclose(obs[1], [1, 0, 1, 1, 0, 0.6])


class _SpyModel:
    """A deterministic 'model': its action is a fixed function of its input row; it records
    every batch of inputs it is given."""

    def __init__(self, observation_space):
        self.observation_space = observation_space
        self.seen = []
        n = observation_space.shape[0]
        self.w = np.random.default_rng(0).normal(size=(n, 1)).astype(np.float32) / np.sqrt(n)

    def predict(self, obs, deterministic=True, **kwargs):
        self.seen.append(np.array(obs, copy=True))
        return np.tanh(obs @ self.w).astype(np.float32), None


def test_the_history_law_rebuilds_the_training_inputs_from_nav_and_its_own_actions():
    """The rows the law's model is given in flight are the rows the wrapper gave it in training:
    same episodes, same actions, row for row and decision for decision."""
    from agents.common.vec_env import make_sb3_vec_env

    k, n, decisions = 4, 2, 6
    train_env = HistoryWrapper(make_sb3_vec_env(ENV_ID, n, seed=SEEDS[0], **ENV_KWARGS), k)
    spy = _SpyModel(train_env.observation_space)
    obs = train_env.reset()
    trained_on = []
    for _ in range(decisions):
        trained_on.append(obs)
        obs, *_ = train_env.step(spy.predict(obs)[0])
    train_env.close()

    law = SB3Law(_SpyModel(train_env.observation_space), None, history=k)
    law.model.w = spy.w
    v = gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", **ENV_KWARGS)
    obs, _ = v.reset(seed=SEEDS[0])
    core = v.unwrapped
    computer = FlightComputer.of(core, ENV_ID)
    law.reset(computer, np.arange(n))
    start = np.ones(n, dtype=bool)
    for _ in range(decisions):
        nav, _ = navigation(core, computer, obs, np.ones(n, bool), start)
        obs, *_ = v.step(decide(law, nav))
        start[:] = False
    v.close()
    np.testing.assert_array_equal(np.stack(law.model.seen), np.stack(trained_on))


def _flight(law, case_ids, decisions, restart_row=None, flag_start=True):
    """The actions (decisions + 1, N, n_act) of ``law`` on the cases ``case_ids`` (seeds of
    SEEDS): ``decisions`` decisions, then one more, before which ``restart_row`` (if given) is
    put back at its start, with ``episode_start`` set for it if ``flag_start``."""
    seeds = [SEEDS[c] for c in case_ids]
    v = gym.make_vec(ENV_ID, num_envs=len(seeds), vectorization_mode="vector_entry_point",
                     **ENV_KWARGS)
    obs, _ = v.reset(seed=seeds)
    core = v.unwrapped
    computer = FlightComputer.of(core, ENV_ID)
    law.reset(computer, np.asarray(case_ids))
    n = len(seeds)
    state0, t0 = core.state_nd, core.t_s.copy()
    start = np.ones(n, dtype=bool)
    out = []
    for _ in range(decisions):
        nav, _ = navigation(core, computer, obs, np.ones(n, bool), start)
        out.append(decide(law, nav))
        obs, *_ = v.step(out[-1])
        start = np.zeros(n, dtype=bool)
    if restart_row is not None:
        core.set_states([restart_row], state0[[restart_row]], t0[[restart_row]])
        obs = core.observations()
        start[restart_row] = flag_start
    nav, _ = navigation(core, computer, obs, np.ones(n, bool), start)
    out.append(decide(law, nav))
    v.close()
    return np.stack(out)


@pytest.fixture(scope="module")
def lstm_model():
    """An untrained recurrent PPO model of the planar env (LSTM of 16) whose action head is
    scaled up, so that its actions depend visibly on the LSTM state."""
    import torch

    from agents.common.runs import algo_class

    env = gym.make(ENV_ID, **ENV_KWARGS)
    model = algo_class("recurrent-ppo")("MlpLstmPolicy", env, n_steps=16, batch_size=16,
                                        seed=0, device="cpu",
                                        policy_kwargs={"lstm_hidden_size": 16})
    with torch.no_grad():
        model.policy.action_net.weight.mul_(30.0)
    return model


def test_the_recurrent_law_keeps_its_state_per_row_and_resets_a_row_at_its_episode_start(
        lstm_model):
    decisions = 4
    batch = _flight(SB3Law(lstm_model, None), [0, 1, 2], decisions, restart_row=1)
    go_on = _flight(SB3Law(lstm_model, None), [0, 1, 2], decisions)
    unflagged = _flight(SB3Law(lstm_model, None), [0, 1, 2], decisions, restart_row=1,
                        flag_start=False)
    # per row: each case flown alone is commanded as in the batch (a shared state is not)
    for row in range(3):
        alone = _flight(SB3Law(lstm_model, None), [row], decisions)
        np.testing.assert_allclose(batch[:decisions, row], alone[:decisions, 0], atol=1e-6)
    # memory matters: back at its start without episode_start, row 1 keeps its state and is
    # commanded otherwise than at its first decision (so a state not reset would be seen)
    assert np.abs(unflagged[decisions, 1] - batch[0, 1]).max() > 1e-3
    # the restarted row is commanded as at its first decision, the others as if nothing
    # happened to row 1
    np.testing.assert_allclose(batch[decisions, 1], batch[0, 1], atol=1e-6)
    np.testing.assert_allclose(batch[decisions, [0, 2]], go_on[decisions, [0, 2]], atol=1e-6)


def test_the_sequence_lstm_computes_what_sb3_contrib_computes(lstm_model):
    """One LSTM call over sequences that start episodes at their first step: the outputs,
    final states and weight gradients of sb3-contrib's step-by-step loop; a start inside a
    sequence goes through that loop."""
    import torch
    from sb3_contrib.common.recurrent.policies import RecurrentActorCriticPolicy

    from agents.common.recurrent import SequenceLstmPolicy

    policy = lstm_model.policy
    assert isinstance(policy, SequenceLstmPolicy)
    lstm = policy.lstm_actor
    gen = torch.Generator().manual_seed(0)
    n_seq, length = 5, 7
    x = torch.randn(n_seq * length, lstm.input_size, generator=gen)
    h0 = (torch.randn(1, n_seq, lstm.hidden_size, generator=gen),
          torch.randn(1, n_seq, lstm.hidden_size, generator=gen))
    # starts at sequences' first steps only; then one inside a sequence
    for starts_at in ([0, 2 * length, 4 * length], [0, 3 * length + 2]):
        starts = torch.zeros(n_seq * length)
        starts[starts_at] = 1.0
        results = []
        for fn in (SequenceLstmPolicy._process_sequence,
                   RecurrentActorCriticPolicy._process_sequence):
            lstm.zero_grad()
            out, (h, c) = fn(x, h0, starts, lstm)
            (out.square().sum() + h.sum() + c.sum()).backward()
            results.append([out.detach(), h.detach(), c.detach(),
                            *[p.grad.clone() for p in lstm.parameters()]])
        for a, b in zip(*results, strict=True):
            torch.testing.assert_close(a, b, rtol=1e-5, atol=1e-6)


# ----------------------------------------------------------------------------- train and fly


def _fly_spec(name: str, run_dir) -> np.ndarray:
    """Success flags of the law ``name:run_dir`` built from its spec, on 2 cases."""
    spec = LawSpec(name=name, argument=str(run_dir), text=f"{name}:{run_dir}")
    context = LawContext(env_id=ENV_ID, env_kwargs=dict(ENV_KWARGS),
                         scenario=gym.make(ENV_ID, **ENV_KWARGS).unwrapped.scenario)
    law = law_from_spec(spec, context)
    res = rollout(ENV_ID, law, 2, seed=2026, env_kwargs=ENV_KWARGS, trace_cases=0)
    assert np.isfinite(res.fuel_used_kg).all() and res.n_decisions > 0
    return law


def test_recurrent_ppo_trains_saves_loads_evaluates_and_flies_as_a_law(tmp_path):
    from agents.common.recurrent import RecurrentPPO
    from agents.evaluate import evaluate_run

    run_dir = tmp_path / "lstm"
    assert tr.main(["--algo", "recurrent-ppo", *TINY, "--run-dir", str(run_dir),
                    "--no-eval"]) == 0
    args = yaml.safe_load((run_dir / "args.yml").read_text())
    assert args["algo"] == "recurrent-ppo"
    model, vn_path, algo = tr.load_trained(run_dir)
    assert algo == "recurrent-ppo" and isinstance(model, RecurrentPPO)
    assert vn_path is not None and model.num_timesteps == 256
    # without its run files, the model file alone says it is recurrent
    alone = tmp_path / "alone"
    alone.mkdir()
    (alone / "model.zip").write_bytes((run_dir / "model.zip").read_bytes())
    assert tr.load_trained(alone / "model.zip")[2] == "recurrent-ppo"
    law = _fly_spec("recurrent-ppo", run_dir)
    assert law.recurrent and law.name == "recurrent-ppo:lstm"
    report = evaluate_run(run_dir, n_states=2, n_expert_states=0, open_loop=False)
    assert report["rows"][0]["policy"].startswith("RECURRENT-PPO")


def test_a_history_run_records_its_history_and_flies_with_it(tmp_path):
    run_dir = tmp_path / "hist"
    assert tr.main([*TINY, "--history", "4", "--run-dir", str(run_dir), "--no-eval"]) == 0
    hp = yaml.safe_load((run_dir / "config.yml").read_text())
    assert hp["history"] == 4
    model, _, _ = tr.load_trained(run_dir)
    n_in = 5 + 7  # the planar observation and its obs_features' columns
    assert model.observation_space.shape == (4 * (n_in + 1),)
    law = _fly_spec("ppo", run_dir)
    assert law.history == 4 and not law.recurrent
    # loaded without its history, the model's inputs do not match: refused by name
    bare = SB3Law(model, run_dir / "vecnormalize.pkl", name="bare",
                  obs_features=hp["obs_features"])
    with pytest.raises(ValueError, match=r"bare: the model takes 52 inputs.*history=None gives "
                                         r"12"):
        rollout(ENV_ID, bare, 1, seed=0, env_kwargs=ENV_KWARGS, trace_cases=0)
    # a run started from it takes its inputs, history included
    tuned = tmp_path / "tuned"
    assert tr.main([*TINY, "--init-from", str(run_dir), "--run-dir", str(tuned),
                    "--no-eval"]) == 0
    assert yaml.safe_load((tuned / "config.yml").read_text())["history"] == 4


# ----------------------------------------------------------------------------- bad input


@pytest.mark.parametrize("bad", [0, -3, MAX_HISTORY + 1, 1.5, True, "8", [8]])
def test_a_bad_history_is_refused_naming_the_value_and_the_range(bad):
    with pytest.raises(ValueError, match=rf"history={bad!r}.*integer from 1 to {MAX_HISTORY}"
                       .replace("[", r"\[").replace("]", r"\]")):
        validate_history(bad)


def test_bad_history_settings_are_refused_before_any_run_directory(tmp_path, capsys):
    run_dir = tmp_path / "never"
    with pytest.raises(SystemExit):
        tr.main([*TINY, "--history", "0", "--run-dir", str(run_dir)])
    assert "--history: 0 is out of range; allowed: 1 to 256" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        tr.main([*TINY, "--hyperparams", "history=-2", "--run-dir", str(run_dir)])
    assert "history=-2: must be an integer from 1 to 256" in capsys.readouterr().err
    assert not run_dir.exists()
    assert validate_history(None) is None and validate_history(8.0) == 8
    with pytest.raises(ValueError, match="history=0"):
        SB3Law(object(), None, history=0)


def test_recurrent_ppo_without_sb3_contrib_names_the_extra(monkeypatch):
    from gymnasium.error import DependencyNotInstalled

    from agents.common.runs import algo_class

    monkeypatch.setitem(sys.modules, "sb3_contrib", None)
    monkeypatch.delitem(sys.modules, "agents.common.recurrent", raising=False)
    with pytest.raises(DependencyNotInstalled, match=r"pip install -e '\.\[memory\]'"):
        algo_class("recurrent-ppo")
    assert algo_class("ppo").__name__ == "PPO"  # the other algorithms need none of it
