"""Every registered law meets the contract (the twin of the env registry's test).

For each law name of the registry, on the env families it flies: its commands are valid actions
of the env's space (shape, dtype, finite, inside the bounds), a case's command does not depend
on the batch it flies in nor on the order of the cases, a row that starts a new episode
(``episode_start``) is commanded as at its first decision whatever the law remembers, and an
ordinary law is handed the navigation solution, never the truth.
"""

from __future__ import annotations

import numpy as np
import pytest

from guidance.flight import decide, navigation
from guidance.law import FlightComputer, Navigation, PrivilegedLaw
from guidance.registry import LawContext, build_law, law_names
from optimizers.optimum import optimum_family

PLANAR = ("LunarSoftLanding-v0", {"dt_s": 2.5})
PINPOINT = ("LunarPinpointLanding-v2", {"dt_s": 2.0, "throttle_channel": True})
TOUCHDOWN = ("LunarPinpointLanding-v3", {})
SEEDS = (11, 12, 13)
DECISIONS = 3

#: law spec -> the envs it is checked on (every registered name appears: the test below
#: fails when a new law is registered without a conformance entry)
SPECS = {
    "apollo": (PLANAR, PINPOINT, TOUCHDOWN),
    "zem-zev": (PLANAR, PINPOINT, TOUCHDOWN),
    "zem-zev:high_gate=0,low_gate=50": (TOUCHDOWN,),
    "zem-zev:min_time_slack=50000": (TOUCHDOWN,),
    "min-time": (TOUCHDOWN,),
    "gravity-turn": (PLANAR, PINPOINT, TOUCHDOWN),
    "open-loop": (PLANAR, TOUCHDOWN),
    "feedback": (PLANAR, PINPOINT, TOUCHDOWN),
    "feedback:thrust_reserve=0.05,estimate_thrust=1": (PINPOINT,),
    "convex": (PLANAR,),
    "random": (PLANAR, PINPOINT, TOUCHDOWN),
    "ppo:RUN": (PLANAR,),
    "ppo:RUN_HISTORY": (PLANAR,),
    "recurrent-ppo:RUN_LSTM": (PLANAR,),
    "sac:RUN": (PLANAR,),
    "td3:RUN": (PLANAR,),
    "bc:RUN": (PLANAR,),
    "dagger:RUN": (PLANAR,),
}


#: the run a learned law's spec flies (its argument), built by the fixture ``run_dir``
RUNS = ("RUN", "RUN_HISTORY", "RUN_LSTM")


def test_every_registered_law_has_a_conformance_entry():
    names = {spec.partition(":")[0] for spec in SPECS}
    registered = set(law_names())
    assert not registered - names, "a registered law without a conformance entry"
    assert not names - registered, (
        f"{sorted(names - registered)} not registered: a law of the package's entry points "
        "is registered once the package is installed again (pip install -e .)")


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """Run directories with (untrained) models of the planar env, by the spec argument: PPO
    (``RUN``), PPO given its last 3 inputs and actions (``RUN_HISTORY``) and recurrent PPO, an
    LSTM of 16 (``RUN_LSTM``)."""
    import gymnasium as gym
    import yaml
    from stable_baselines3 import PPO

    import lunar_env  # noqa: F401
    from agents.common.runs import algo_class
    from agents.rl.training import make_training_env

    def run(name, algo, model, **config):
        d = tmp_path_factory.mktemp(name)
        model.save(d / "model.zip")
        (d / "args.yml").write_text(yaml.safe_dump({"algo": algo, "env": PLANAR[0]}))
        (d / "config.yml").write_text(yaml.safe_dump({"env_kwargs": PLANAR[1], **config}))
        return d

    env = gym.make(PLANAR[0], **PLANAR[1])
    history = make_training_env(PLANAR[0], 1, 0, PLANAR[1], history=3)
    kw = {"n_steps": 64, "batch_size": 64, "seed": 0, "device": "cpu"}
    return {
        "RUN": run("run", "ppo", PPO("MlpPolicy", env, **kw)),
        "RUN_HISTORY": run("run_history", "ppo", PPO("MlpPolicy", history, **kw), history=3),
        "RUN_LSTM": run("run_lstm", "recurrent-ppo", algo_class("recurrent-ppo")(
            "MlpLstmPolicy", env, policy_kwargs={"lstm_hidden_size": 16}, **kw)),
    }


def _cases():
    return [(spec, env) for spec, envs in SPECS.items() for env in envs]


def _venv(env_id, kwargs, seeds, uncertainty=None):
    import gymnasium as gym

    import lunar_env  # noqa: F401

    kw = dict(kwargs) if uncertainty is None else {**kwargs, "uncertainty": uncertainty}
    v = gym.make_vec(env_id, num_envs=len(seeds), vectorization_mode="vector_entry_point", **kw)
    obs, _ = v.reset(seed=list(seeds))
    return v, obs


def _law(spec, env_id, kwargs, run_dir, seeds):
    name, _, arg = spec.partition(":")
    if arg in RUNS:
        spec = f"{name}:{run_dir[arg]}"
    v, _ = _venv(env_id, kwargs, SEEDS)
    scenario = v.unwrapped.scenario
    states = v.unwrapped.navigation_state_nd
    v.close()

    def nominal_optimum():
        return optimum_family(scenario).per_case_optimum(scenario, states, progress=False)

    return build_law(spec, LawContext(env_id=env_id, env_kwargs=dict(kwargs),
                                      scenario=scenario, nominal_optimum=nominal_optimum))


def _fly(law, env_id, kwargs, case_ids, decisions=DECISIONS, restart_row=None,
         uncertainty=None, spy=None):
    """The actions (decisions, N, n_act) of ``law`` on cases ``case_ids`` (seeds of SEEDS);
    ``restart_row``: after the decisions, that row is put back at its start and flagged as
    starting an episode, and one more decision is taken (returned last)."""
    seeds = [SEEDS[c] for c in case_ids]
    v, obs = _venv(env_id, kwargs, seeds, uncertainty)
    core = v.unwrapped
    computer = FlightComputer.of(core, env_id)
    law.reset(computer, np.asarray(case_ids))
    n = len(seeds)
    start0, t0 = core.state_nd, core.t_s.copy()
    out = []
    start = np.ones(n, dtype=bool)
    for _ in range(decisions):
        nav, truth = navigation(core, computer, obs, np.ones(n, bool), start,
                                isinstance(law, PrivilegedLaw))
        if spy is not None:
            spy(nav, core)
        out.append(decide(law, nav, truth))
        obs, _, term, trunc, _ = v.step(out[-1])
        assert not (term.any() or trunc.any()), "a case ended within the conformance window"
        start = np.zeros(n, dtype=bool)
    if restart_row is not None:
        core.set_states([restart_row], start0[[restart_row]], t0[[restart_row]])
        obs = core.observations()
        start[restart_row] = True
        nav, truth = navigation(core, computer, obs, np.ones(n, bool), start,
                                isinstance(law, PrivilegedLaw))
        out.append(decide(law, nav, truth))
    v.close()
    return np.stack(out)


@pytest.mark.parametrize("spec, env", _cases(), ids=lambda x: x if isinstance(x, str)
                         else x[0])
def test_law_conformance(spec, env, run_dir):
    env_id, kwargs = env
    law = _law(spec, env_id, kwargs, run_dir, SEEDS)
    a = _fly(law, env_id, kwargs, [0, 1, 2], restart_row=0)
    # valid actions of the env's space
    import gymnasium as gym

    space = gym.make(env_id, **kwargs).action_space
    assert a.dtype == np.float32 and a.shape == (DECISIONS + 1, 3, *space.shape)
    assert np.all(np.isfinite(a)) and np.all((a >= space.low) & (a <= space.high))
    # a restarted row is commanded as at its first decision
    np.testing.assert_array_equal(a[-1, 0], a[0, 0])
    # batch size and case order do not change a row (a learned policy's to float32 rounding:
    # torch's matrix products round differently with the batch size)
    other = _fly(_law(spec, env_id, kwargs, run_dir, SEEDS), env_id, kwargs, [2, 0])
    atol = 1e-6 if spec.partition(":")[2] in RUNS else 0.0
    np.testing.assert_allclose(other[:, 0], a[:DECISIONS, 2], rtol=0, atol=atol)
    np.testing.assert_allclose(other[:, 1], a[:DECISIONS, 0], rtol=0, atol=atol)


@pytest.mark.parametrize("spec", ["apollo", "feedback", "random"])
def test_an_ordinary_law_is_handed_the_navigation_solution_never_the_truth(spec, run_dir):
    env_id, kwargs = PLANAR
    seen: list[tuple[Navigation, np.ndarray, np.ndarray]] = []

    def spy(nav, core):
        seen.append((nav, core.navigation_state_nd, core.state_nd))

    law = _law(spec, env_id, kwargs, run_dir, SEEDS)
    assert not isinstance(law, PrivilegedLaw)
    _fly(law, env_id, kwargs, [0, 1], uncertainty="standard", spy=spy)
    for nav, navigated, truth in seen:
        np.testing.assert_array_equal(nav.state_nd, navigated)
        assert not np.array_equal(nav.state_nd, truth)
        assert not hasattr(nav, "truth")
