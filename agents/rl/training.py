"""The training core of :mod:`agents.train`: build the training env and run or continue one
SB3 run in a run directory (its callbacks are the classes of :mod:`agents.rl.callbacks`).

Split from the command line (:mod:`agents.train`) so that tools that train many runs (the
hyperparameter search, :mod:`agents.rl.search`) depend on the core without an import cycle with
the CLI that dispatches to them.
"""

from __future__ import annotations

import signal
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from agents.common.runs import (
    algo_class,
    load_trained,
    read_run,
    resumable_checkpoint,
    save_model_atomic,
    save_vecnormalize_atomic,
    write_text_atomic,
)
from agents.hyperparams import resolve_algo_kwargs
from agents.rl.warm_start import (
    input_map,
    load_widened_vecnormalize,
    widen_action_head,
    widen_input_layer,
)
from lunar_env.validation import require_bool

__all__ = ["train", "interrupt_on_sigterm", "make_training_env", "set_initial_action",
           "DEFAULT_ENV_ID"]

DEFAULT_ENV_ID = "LunarSoftLanding-v0"
#: the policy of a YAML entry without a ``policy`` key
DEFAULT_POLICY = {"ppo": "MlpPolicy", "sac": "MlpPolicy", "td3": "MlpPolicy",
                  "recurrent-ppo": "MlpLstmPolicy"}


def _is_native_env(env_id: str) -> bool:
    import gymnasium as gym

    import lunar_env  # noqa: F401  (registers our ids)

    try:
        spec = gym.spec(env_id)
    except gym.error.Error:
        return False
    return spec.vector_entry_point is not None and str(spec.entry_point).startswith("lunar_env")


def make_training_env(env_id: str, n_envs: int, seed: int | None,
                      env_kwargs: dict[str, Any] | None = None,
                      curriculum: dict[str, Any] | None = None, total_timesteps: int = 0,
                      progress: bool = True, obs_features: list[str] | None = None,
                      reward_shaping: dict[str, Any] | None = None, gamma: float = 0.99,
                      error_curriculum: dict[str, Any] | None = None,
                      history: int | None = None):
    """Build the SB3 ``VecEnv`` to train on (no normalisation wrapper).

    Our env ids go through the natively batched vector env (:func:`agents.common.vec_env.
    make_sb3_vec_env`); other Gymnasium ids through SB3's ``make_vec_env`` (``DummyVecEnv``).
    ``curriculum`` (the YAML mapping) wraps the batch in :class:`agents.rl.curriculum.
    OptimalStartCurriculum` annealed over ``total_timesteps``; ``obs_features`` (names of
    :mod:`agents.features`) appends derived features to the observations
    (:class:`agents.features.ObsFeatureWrapper`, outside the curriculum); ``reward_shaping``
    (YAML mapping) adds the potential-based shaping of :class:`agents.rl.shaping.PotentialShaping`
    with discount ``gamma`` (training only: evaluation measures landings, not rewards);
    ``error_curriculum`` (YAML mapping) anneals the env's uncertainty model in
    (:class:`agents.rl.curriculum.ErrorScaleCurriculum`, inside the start curriculum);
    ``history`` (k decisions) gives the policy its last k inputs (observation and features) and
    actions (:class:`agents.features.history.HistoryWrapper`, outermost, on any env id). Episode
    statistics are recorded by ``VecMonitor`` when the adapter does not already (they show the
    shaped return when shaping is on).
    """
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecMonitor

    from agents.features.history import HistoryWrapper, validate_history

    env_kwargs = dict(env_kwargs or {})
    if n_envs < 1:
        raise ValueError(f"n_envs={n_envs} must be >= 1")
    history = validate_history(history)
    if _is_native_env(env_id):
        from agents.common.vec_env import make_sb3_vec_env

        venv = make_sb3_vec_env(env_id, n_envs, seed=seed, **env_kwargs)
        if error_curriculum:
            from agents.rl.curriculum import ErrorScaleCurriculum
            from lunar_env.validation import require_option_keys

            require_option_keys("error_curriculum", error_curriculum,
                                ("start_scale", "final_scale", "anneal_fraction",
                                 "success_threshold", "scale_step", "window_episodes"))
            venv = ErrorScaleCurriculum(venv, total_timesteps=total_timesteps,
                                        **error_curriculum)
        if curriculum:
            from agents.rl.curriculum import OptimalStartCurriculum

            venv = OptimalStartCurriculum(venv, total_timesteps=total_timesteps,
                                          seed=0 if seed is None else int(seed),
                                          progress=progress, **curriculum)
        if reward_shaping:
            from agents.rl.shaping import PotentialShaping

            venv = PotentialShaping(venv, gamma=gamma, **reward_shaping)
        if obs_features:
            from agents.features import ObsFeatureWrapper

            venv = ObsFeatureWrapper(venv, obs_features)
        if history is not None:
            venv = HistoryWrapper(venv, history)
    else:
        if curriculum or obs_features or reward_shaping or error_curriculum:
            raise ValueError("curriculum, error_curriculum, obs_features and reward_shaping are "
                             "only available for "
                             "lunar_env ids, "
                             f"not {env_id!r}")
        venv = make_vec_env(env_id, n_envs=n_envs, seed=seed, env_kwargs=env_kwargs)
        # make_vec_env already wraps each env in Monitor
        return venv if history is None else HistoryWrapper(venv, history)
    from agents.rl.callbacks import find_wrapper

    if find_wrapper(venv, VecMonitor) is None:
        venv = VecMonitor(venv)
    return venv


def _normalize_kwargs(normalize: Any, gamma: float | None) -> dict[str, Any] | None:
    """``VecNormalize`` arguments of a ``normalize`` entry (None: no normalisation); the entry's
    own key ``update`` (:func:`_normalize_updates`) is not one of them."""
    if normalize in (None, False):
        return None
    if normalize is True:
        kw: dict[str, Any] = {}
    elif isinstance(normalize, dict):
        kw = dict(normalize)
        kw.pop("update", None)
    else:
        raise ValueError(f"normalize={normalize!r}: expected true/false or a mapping of "
                         "VecNormalize arguments")
    if gamma is not None:
        kw.setdefault("gamma", gamma)
    return kw


def _normalize_updates(normalize: Any) -> bool:
    """``normalize: {update: false}`` keeps the observation and reward statistics where they
    start (loaded from ``--init-from`` or a checkpoint) instead of updating them with every
    step (SB3's ``VecNormalize.training``).

    Why: a policy's weights are fit to its input statistics. Fine-tuning the nominal pinpoint
    policy (``--init-from``), its statistics kept updating on the new run's observations
    (dispersed starts only, where the nominal run had also started from optimal trajectories)
    and the training success of the *unchanged* policy (learning rate 0) fell from 93 to
    53 % in 0.66e6 steps.
    """
    if isinstance(normalize, dict):
        return require_bool("normalize.update", normalize.get("update", True))
    return True


def _select_final(model, run_dir: Path, run: dict[str, Any], hp: dict[str, Any],
                  sel: dict[str, Any], algo: str):
    """``select_checkpoint: {states, last, seed, warn_below}``: the final ``model.zip`` (and its
    statistics) become the newest-``last`` checkpoint that lands most of ``states`` validation
    cases (:mod:`agents.rl.selection`); the last iterate stays the newest checkpoint, so
    ``--resume`` still extends the run. Returns the chosen model."""
    from agents.rl.selection import VALIDATION_SEED, select_checkpoint
    from lunar_env.validation import require_option_keys
    from optimizers.common.checkpoint import atomic_write_bytes

    require_option_keys("select_checkpoint", sel, ("states", "last", "seed", "warn_below"))
    steps, path, vn_path = select_checkpoint(
        run_dir, run["env"], hp.get("env_kwargs"), hp.get("obs_features"),
        int(sel.get("states", 100)), int(sel.get("last", 4)),
        int(sel.get("seed", VALIDATION_SEED)), run.get("device", "cpu"),
        warn_below=sel.get("warn_below", 0.5), history=hp.get("history"))
    for src, name in ((vn_path, "vecnormalize.pkl"), (path, "model.zip")):
        if src is not None:  # model.zip last: a model file implies its statistics are in place
            atomic_write_bytes(run_dir / name, Path(src).read_bytes())
    return algo_class(algo).load(run_dir / "model.zip", device=run.get("device", "cpu"))


def set_initial_action(model, values: Any) -> None:
    """Start a new PPO policy at the mean action ``values`` (the ``initial_action``
    hyperparameter: one number in [-1, 1] per action channel): the action head's bias. SB3
    initialises the head's weights orthogonally with gain 0.01, so the mean action is the bias
    to ~0.1 over the whole input range, and the exploration noise is drawn around it.

    Why: the mean action of an untrained policy is 0 in every channel; on an env whose throttle
    channel maps [-1, 1] onto [throttle_min, 1], that is a 60 % throttle, too weak to brake
    [001]'s 1.7 km/s descent, and PPO must first learn full thrust from landings it never sees
    (``LunarPinpointLanding-v3``; measured in ``agents/hyperparams/ppo.yml``).

    Raises ValueError for a policy without an action head (SAC, TD3) or values that are not one
    finite number in [-1, 1] per channel."""
    import torch

    net = getattr(model.policy, "action_net", None)
    if net is None or not hasattr(net, "bias"):
        raise ValueError(f"initial_action={values!r}: only for PPO policies (an 'action_net' "
                         "head)")
    v = np.asarray(values, dtype=np.float64).reshape(-1)
    n = int(net.bias.shape[0])
    if len(v) != n or not np.all(np.isfinite(v)) or np.any(np.abs(v) > 1.0):
        raise ValueError(f"initial_action={values!r}: needs {n} finite values in [-1, 1], one "
                         "per action channel")
    with torch.no_grad():
        net.bias.copy_(torch.as_tensor(v, dtype=net.bias.dtype))


def interrupt_on_sigterm(signum, frame) -> None:
    """SIGTERM handler that takes the Ctrl-C path (a checkpoint, then exit): raises
    KeyboardInterrupt."""
    raise KeyboardInterrupt


def train(hp: dict[str, Any], run: dict[str, Any], run_dir: Path, resume: bool = False,
          callbacks: list | None = None, on_resumed=None):
    """Train (or continue) one run; returns ``(model, run_dir)``.

    ``hp`` are the resolved YAML hyperparameters, ``run`` the run arguments (as in ``args.yml``),
    ``callbacks`` extra SB3 callbacks. A ``KeyboardInterrupt`` (Ctrl-C, or SIGTERM) raised during
    training writes a checkpoint and propagates. ``on_resumed()`` is called once a resumed
    checkpoint has loaded (the CLI records a changed config only then: a failed resume changes
    nothing in the run directory). With ``select_checkpoint`` in ``hp`` the final ``model.zip``
    is the selected checkpoint (:mod:`agents.rl.selection`).
    """
    import torch
    from stable_baselines3.common.utils import set_random_seed
    from stable_baselines3.common.vec_env import VecNormalize

    algo = run["algo"]
    seed = int(run["seed"])
    torch.set_num_threads(max(int(run.get("torch_threads") or 1), 1))
    set_random_seed(seed)
    n_envs, n_timesteps = hp["n_envs"], hp["n_timesteps"]
    # whether VecNormalize keeps updating its statistics (every branch below that builds one)
    update_stats = _normalize_updates(hp.get("normalize"))
    venv = make_training_env(run["env"], n_envs, seed, hp.get("env_kwargs"),
                             curriculum=hp.get("curriculum"), total_timesteps=n_timesteps,
                             progress=not run.get("no_progress"),
                             obs_features=hp.get("obs_features"),
                             reward_shaping=hp.get("reward_shaping"),
                             gamma=float(hp.get("gamma", 0.99)),
                             error_curriculum=hp.get("error_curriculum"),
                             history=hp.get("history"))
    tb_dir = None if run.get("no_tensorboard") else str(run_dir / "tb")

    if resume:
        # the newest *complete* checkpoint; a normalised run never resumes without statistics
        ckpt, steps, vn_path = resumable_checkpoint(
            run_dir, needs_vecnormalize=bool(hp.get("normalize")))
        if vn_path is not None:
            venv = VecNormalize.load(str(vn_path), venv)
            venv.training = update_stats
        model = algo_class(algo).load(ckpt, env=venv, device=run.get("device", "cpu"),
                                       tensorboard_log=tb_dir)
        model.verbose = int(run.get("verbose", 0))  # the console of this process
        rb = ckpt.parent / f"rl_model_replay_buffer_{steps}_steps.pkl"
        if rb.exists() and hasattr(model, "load_replay_buffer"):
            model.load_replay_buffer(rb)
        if model.num_timesteps != steps:
            raise RuntimeError(f"checkpoint {ckpt} holds num_timesteps={model.num_timesteps}, "
                               f"expected {steps}")
        print(f"Resuming {run_dir} from step {steps} of {n_timesteps}")
        if on_resumed is not None:
            on_resumed()
    else:
        norm_kw = _normalize_kwargs(hp.get("normalize"), hp.get("gamma"))
        init = None
        if run.get("init_from"):
            # "PPO fine-tuned from BC": the new model starts from another model's policy weights.
            # Decision: an init model saved without VecNormalize statistics acts on raw
            # observations, so observation normalisation is switched off for this run (reward
            # normalisation stays as configured); with statistics, they are loaded.
            init, init_vn, _ = load_trained(run["init_from"], device=run.get("device", "cpu"))
            if norm_kw is not None and init_vn is None and norm_kw.get("norm_obs", True):
                norm_kw["norm_obs"] = False
                print(f"--init-from {run['init_from']}: no VecNormalize statistics, so "
                      "norm_obs is off (the initial policy expects raw observations)")
            added_inputs = input_map(read_run(run["init_from"])[1], hp, venv,
                                     int(init.observation_space.shape[0]), run["init_from"])
            if added_inputs is not None:
                from agents.features import StandardizedInputs

                if isinstance(getattr(init.policy, "features_extractor", None),
                              StandardizedInputs):
                    raise ValueError(f"--init-from {run['init_from']}: a policy that "
                                     "standardises its own inputs (a behaviour clone) cannot "
                                     "take added inputs; train with its env_kwargs, "
                                     "obs_features and history")
                print(f"--init-from {run['init_from']}: {added_inputs.added} added with zero "
                      "weights")
            if norm_kw is not None and init_vn is not None:
                venv = (VecNormalize.load(str(init_vn), venv) if added_inputs is None
                        else load_widened_vecnormalize(init_vn, venv, added_inputs))
                # VecNormalize.load keeps the pickled action space; this env's is the one to
                # learn (it differs when the init policy lacked a channel: added_action_init)
                venv.action_space = venv.venv.action_space
                venv.training = update_stats
                norm_kw = None
        if norm_kw is not None:
            venv = VecNormalize(venv, **norm_kw)
            venv.training = update_stats
        kwargs = resolve_algo_kwargs(hp, algo, n_actions=int(np.prod(venv.action_space.shape)))
        if init is not None:
            from agents.features import StandardizedInputs

            fx = getattr(init.policy, "features_extractor", None)
            if isinstance(fx, StandardizedInputs):
                # a clone standardises its inputs itself: keep its input map
                kwargs.setdefault("policy_kwargs", {})
                kwargs["policy_kwargs"]["features_extractor_class"] = StandardizedInputs
                kwargs["policy_kwargs"]["features_extractor_kwargs"] = {
                    "mean": fx.mean.cpu().numpy().tolist(), "std": fx.std.cpu().numpy().tolist()}
        model = algo_class(algo)(hp.get("policy", DEFAULT_POLICY[algo]), venv, seed=seed,
                                  device=run.get("device", "cpu"), tensorboard_log=tb_dir,
                                  verbose=int(run.get("verbose", 0)), **kwargs)
        if hp.get("initial_action") is not None:
            if init is not None:
                raise ValueError(f"initial_action={hp['initial_action']!r}: a run started by "
                                 f"--init-from {run['init_from']} flies its policy's actions; "
                                 "drop the key (hyperparameter initial_action=null)")
            set_initial_action(model, hp["initial_action"])
        if init is not None:
            # the exploration noise (log_std) stays this run's log_std_init: a cloned policy
            # carries whatever its trainer left there
            weights = {k: v for k, v in init.policy.state_dict().items() if k != "log_std"}
            weights = widen_action_head(weights, model.policy.state_dict(),
                                        hp.get("added_action_init"), run["init_from"])
            if added_inputs is not None:
                weights = widen_input_layer(weights, model.policy.state_dict(), added_inputs)
            try:
                model.policy.load_state_dict(weights, strict=False)
                missing = set(model.policy.state_dict()) - set(weights) - {"log_std"}
                if missing:
                    raise RuntimeError(f"missing weights {sorted(missing)}")
            except RuntimeError as exc:
                raise ValueError(
                    f"--init-from {run['init_from']}: its policy does not match this run's "
                    f"policy_kwargs {hp.get('policy_kwargs')} ({exc}); pass the same net_arch "
                    "with --hyperparams") from None

    from agents.rl.callbacks import (
        CriticWarmupCallback,
        EpisodeInfoCallback,
        RolloutCheckpointCallback,
        error_curriculum_of,
        error_scale_state_path,
        find_wrapper,
    )
    from agents.rl.curriculum import OptimalStartCurriculum

    curriculum = find_wrapper(venv, OptimalStartCurriculum)
    if curriculum is not None:  # continue the annealing schedule where the run stopped
        curriculum.num_timesteps = model.num_timesteps
    errors = error_curriculum_of(venv)
    if errors is not None:
        errors.num_timesteps = model.num_timesteps
        errors.apply()
        if resume and errors.success_threshold is not None:
            state = error_scale_state_path(ckpt)
            if not state.exists():
                raise FileNotFoundError(f"{state}: the success-driven error scale of checkpoint "
                                        f"{ckpt} is missing; cannot resume its schedule")
            errors.load_state_dict(yaml.safe_load(state.read_text()))
    remaining = n_timesteps - model.num_timesteps
    t0 = time.perf_counter()
    steps0 = model.num_timesteps
    tfile = run_dir / "timing.yml"
    previous = (yaml.safe_load(tfile.read_text()) or []) if tfile.exists() else []

    def record_timing() -> list:
        """This process's timing record (a resumed run appends one), rewritten atomically at
        every checkpoint and at the end, so a run killed part-way still accounts for the steps
        it saved."""
        wall_s = time.perf_counter() - t0
        done_steps = model.num_timesteps - steps0
        record = {"train_wall_s_this_session": wall_s, "steps_this_session": int(done_steps),
                   "steps_per_s": done_steps / wall_s if wall_s > 0 else float("nan"),
                   "num_timesteps": int(model.num_timesteps)}
        write_text_atomic(tfile, yaml.safe_dump(previous + [record]))
        return previous + [record]

    ckpt_cb = RolloutCheckpointCallback(run_dir, run.get("save_freq") or max(n_timesteps // 20, 1),
                                        hp, on_save=record_timing)
    every = run.get("summary_every")
    info_cb = EpisodeInfoCallback(
        n_timesteps, max(n_timesteps // 20, 1) if every is None else max(int(every), 0))
    warmup_steps = int(hp.get("critic_warmup_steps") or 0)
    extra = [CriticWarmupCallback(warmup_steps)] if warmup_steps else []

    old_handler = signal.signal(signal.SIGTERM, interrupt_on_sigterm)
    try:
        if remaining > 0:
            model.learn(total_timesteps=remaining,
                        callback=[ckpt_cb, info_cb, *extra, *(callbacks or [])],
                        reset_num_timesteps=not resume, tb_log_name="run",
                        progress_bar=not run.get("no_progress"))
    except KeyboardInterrupt:
        path = ckpt_cb.save_now(interrupted=True)
        print(f"\nInterrupted at step {model.num_timesteps}; checkpoint {path}.\n"
              f"Continue with: python train.py --resume {run_dir}", file=sys.stderr)
        venv.close()
        raise
    finally:
        signal.signal(signal.SIGTERM, old_handler)
    wall = time.perf_counter() - t0
    # (no learn() call when a run killed after its final checkpoint is resumed: the callback
    # was never attached, and the final checkpoint is already the final state)
    if ckpt_cb.last_saved_steps not in (None, model.num_timesteps):
        ckpt_cb.save_now()  # the newest checkpoint is the final state: --resume can extend it
    vn = model.get_vec_normalize_env()
    if vn is not None:
        save_vecnormalize_atomic(vn, run_dir / "vecnormalize.pkl")
    save_model_atomic(model, run_dir / "model.zip")
    records = record_timing()
    total_wall = sum(s["train_wall_s_this_session"] for s in records)
    print(f"Trained {model.num_timesteps} steps; this process {records[-1]['steps_this_session']}"
          f" steps in {wall:.1f} s ({records[-1]['steps_per_s']:.0f} steps/s); total training "
          f"wall time {total_wall:.1f} s. "
          f"Model: {run_dir / 'model.zip'}")
    venv.close()
    sel = hp.get("select_checkpoint")
    # after the summary line: it reports the run, the selection the chosen checkpoint
    if sel and model.num_timesteps >= n_timesteps:
        model = _select_final(model, run_dir, run, hp, dict(sel), algo)
    return model, run_dir
