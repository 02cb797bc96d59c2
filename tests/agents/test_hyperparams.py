"""YAML hyperparameters in the RL-Zoo layout: parsing, profiles, overrides, refusal of code."""

import pytest
import torch
import yaml

from agents.hyperparams import (
    ALGOS,
    apply_overrides,
    default_hyperparams_path,
    load_hyperparams,
    parse_override,
    resolve_algo_kwargs,
)

ENV_IDS = ("LunarSoftLanding-v0", "LunarPinpointLanding-v0")


@pytest.mark.parametrize("algo", ALGOS)
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_shipped_files_have_a_tuned_and_a_quick_entry(algo, env_id):
    hp = load_hyperparams(default_hyperparams_path(algo), env_id)
    quick = load_hyperparams(default_hyperparams_path(algo), env_id, "quick")
    assert hp["n_timesteps"] >= 1e5
    assert quick["n_timesteps"] <= 10_000  # CI runs it end to end
    assert quick["policy"] == hp["policy"]  # the profile merges over the base entry
    kwargs = resolve_algo_kwargs(quick, algo, n_actions=1)
    for key in ("n_envs", "n_timesteps", "policy", "normalize", "noise_type", "noise_std"):
        assert key not in kwargs


def test_profile_merges_nested_mappings(tmp_path):
    f = tmp_path / "ppo.yml"
    f.write_text(yaml.safe_dump({
        "Env-v0": {"n_envs": 4, "n_timesteps": 1000,
                   "policy_kwargs": {"net_arch": [64, 64], "activation_fn": "tanh"}},
        "Env-v0@small": {"policy_kwargs": {"net_arch": [8]}},
    }))
    hp = load_hyperparams(f, "Env-v0", "small")
    assert hp["policy_kwargs"] == {"net_arch": [8], "activation_fn": "tanh"}
    assert hp["n_envs"] == 4
    assert load_hyperparams(f, "Env-v0", "default")["policy_kwargs"]["net_arch"] == [64, 64]


def test_missing_entries_name_what_exists(tmp_path):
    f = tmp_path / "ppo.yml"
    f.write_text("Env-v0: {n_envs: 1, n_timesteps: 10}\n")
    with pytest.raises(ValueError, match="Env-v0"):
        load_hyperparams(f, "Other-v0")
    with pytest.raises(ValueError, match="no profile 'fast'"):
        load_hyperparams(f, "Env-v0", "fast")


def test_policy_kwargs_strings_are_not_evaluated(tmp_path):
    f = tmp_path / "ppo.yml"
    f.write_text('Env-v0: {n_envs: 1, n_timesteps: 10, '
                 'policy_kwargs: "dict(net_arch=[__import__(\'os\').getpid()])"}\n')
    with pytest.raises(ValueError, match="not evaluated"):
        load_hyperparams(f, "Env-v0")
    with pytest.raises(ValueError, match="strings are not evaluated"):
        resolve_algo_kwargs({"policy_kwargs": {"log_std_init": "-1 + 0"}}, "ppo")
    with pytest.raises(ValueError, match="activation_fn"):
        resolve_algo_kwargs({"policy_kwargs": {"activation_fn": "nn.Tanh"}}, "ppo")


def test_structural_resolution():
    kw = resolve_algo_kwargs({
        "learning_rate": "lin_3e-4", "clip_range": 0.1, "n_envs": 8,
        "policy_kwargs": {"net_arch": {"pi": [32], "vf": [16, 16]}, "activation_fn": "relu",
                          "optimizer_class": "adamw"},
    }, "ppo")
    assert kw["learning_rate"](1.0) == pytest.approx(3e-4)
    assert kw["learning_rate"](0.5) == pytest.approx(1.5e-4)
    assert kw["clip_range"] == 0.1
    assert kw["policy_kwargs"]["activation_fn"] is torch.nn.ReLU
    assert kw["policy_kwargs"]["optimizer_class"] is torch.optim.AdamW
    assert kw["policy_kwargs"]["net_arch"] == {"pi": [32], "vf": [16, 16]}
    with pytest.raises(ValueError, match="lin_"):
        resolve_algo_kwargs({"learning_rate": "fast"}, "ppo")
    td3 = resolve_algo_kwargs({"noise_type": "normal", "noise_std": 0.2}, "td3", n_actions=2)
    assert td3["action_noise"]._sigma.tolist() == [0.2, 0.2]
    with pytest.raises(ValueError, match="off-policy"):
        resolve_algo_kwargs({"noise_type": "normal"}, "ppo")


def test_unknown_keys_are_refused_before_the_algorithm_is_built():
    """A key that is neither a run key nor an argument of the algorithm's constructor (a typo,
    or an option no longer offered such as ``noise_anneal``) is refused by name, per
    algorithm: ``gae_lambda`` is a PPO argument, not a TD3 one."""
    anneal = {"start_fraction": 0.7, "final_log_std": -5.0}
    with pytest.raises(ValueError, match=r"ppo hyperparameters: unknown key\(s\) "
                                         r"\['noise_anneal'\]"):
        resolve_algo_kwargs({"n_steps": 64, "noise_anneal": anneal}, "ppo")
    assert resolve_algo_kwargs({"n_steps": 64, "n_envs": 2}, "ppo") == {"n_steps": 64}
    with pytest.raises(ValueError, match=r"unknown key\(s\) \['gae_lambda'\]"):
        resolve_algo_kwargs({"gae_lambda": 0.95}, "td3")
    for algo in ALGOS:
        for env_id in ENV_IDS:
            resolve_algo_kwargs(load_hyperparams(default_hyperparams_path(algo), env_id), algo,
                                n_actions=1)


def test_cli_overrides_parse_yaml_values_and_dotted_keys():
    assert parse_override("n_steps=512") == ("n_steps", 512)
    assert parse_override("learning_rate=lin_1e-3") == ("learning_rate", "lin_1e-3")
    key, val = parse_override("policy_kwargs={net_arch: [32, 32]}")
    assert key == "policy_kwargs" and val == {"net_arch": [32, 32]}
    with pytest.raises(ValueError, match="key=value"):
        parse_override("n_steps")
    hp = apply_overrides({"policy_kwargs": {"net_arch": [64], "activation_fn": "tanh"}},
                         {"policy_kwargs.activation_fn": "relu", "gamma": 0.99})
    assert hp == {"policy_kwargs": {"net_arch": [64], "activation_fn": "relu"}, "gamma": 0.99}


def test_the_pinpoint_throttle_entry_is_the_measured_fine_tune_with_a_throttle():
    """@robust_throttle is @robust_finetune (the same schedule, statistics and capped
    updates) with the throttle channel, the widening of the nominal policy's action head by
    one throttle channel at full thrust with the angles' exploration σ, one run (no race) and
    the length it was measured at: the measured recipe, not a variant of it."""
    import gymnasium as gym

    import lunar_env  # noqa: F401  (registers the ids)

    env_id = "LunarPinpointLanding-v2"
    path = default_hyperparams_path("ppo")
    finetune = load_hyperparams(path, env_id, "robust_finetune")
    throttle = load_hyperparams(path, env_id, "robust_throttle")
    changed = {k for k in finetune.keys() | throttle.keys() if finetune.get(k) != throttle.get(k)}
    assert changed == {"env_kwargs", "added_action_init", "seed_race", "n_timesteps"}
    assert throttle["env_kwargs"] == {**finetune["env_kwargs"], "throttle_channel": True}
    assert throttle["seed_race"] is None and finetune["seed_race"]
    assert throttle["n_timesteps"] > finetune["n_timesteps"]
    with gym.make(env_id) as nominal, gym.make(env_id, throttle_channel=True) as throttled:
        n_nominal = nominal.action_space.shape[0]
        n_throttled = throttled.action_space.shape[0]
    added = throttle["added_action_init"]
    assert len(added["action"]) == len(added["log_std"]) == n_throttled - n_nominal == 1
    assert added["action"] == [1.0]  # full thrust: the widened policy flies as the nominal one
    assert added["log_std"] == [finetune["policy_kwargs"]["log_std_init"]]
