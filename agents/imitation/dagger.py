"""DAgger ([Ross, Gordon & Bagnell 2011]) with the closed-loop expert: :func:`train_dagger` and the
choice of the final iteration (:func:`select_iteration`).
"""

from __future__ import annotations

import re
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from agents.common.runs import save_model_atomic, write_text_atomic
from agents.imitation.bc import _logger, _save_final, train_bc
from agents.imitation.families import IMITATION_FAMILIES, DaggerRequest
from agents.imitation.policy import (
    build_model,
    fit_policy,
    imitation_history,
    load_learner,
    load_policy_model,
    policy_inputs,
)
from lunar_env import get_scenario
from optimizers.common.checkpoint import save_npz_atomic

_DG_CKPT = re.compile(r"^dagger_iter_(\d+)\.zip$")


def train_dagger(hp: dict[str, Any], run: dict[str, Any], run_dir: Path, resume: bool = False):
    """DAgger with the closed-loop expert; returns the final PPO model (also ``model.zip``).

    The policy flies the dataset's env with ``hp["env_kwargs"]`` merged over it
    (:func:`agents.imitation.sources.run_env_kwargs`, e.g. an ``uncertainty`` model): the
    roll-outs, the initial BC and the final selection alike. Its env family labels the
    visited states with the teacher ``hp["dagger"]["teacher"]`` (one contract for every
    family: :mod:`agents.imitation.teachers`; checked before anything is loaded or flown).

    With ``hp["history"] = k`` (:func:`agents.imitation.policy.imitation_history`) the student
    is given its last k inputs and actions (:mod:`agents.features.history`), as a PPO run with
    ``history: k`` is. Its labels' inputs are the stacked inputs it built in the roll-outs, from
    the actions flown (the teacher's where it flew). Without an ``--init`` policy, the teacher
    flies every episode of the first iteration (Ross et al.'s β₁ = 1). The student is fitted
    on those flights, its inputs standardised with their statistics, instead of cloning the
    dataset, whose samples have no histories. The dataset still names the env's configuration.

    Raises
    ------
    ValueError
        The teacher setting names no teacher, or one the dataset's env family does not offer;
        a ``history`` the run cannot take (:func:`~agents.imitation.policy.
        imitation_history`).
    """
    import torch as th
    from stable_baselines3 import PPO

    from agents.imitation.sources import load_run_dataset
    from agents.imitation.teachers import parse_teacher

    dg = hp["dagger"]
    teacher = parse_teacher(dg.get("teacher"))
    history_k = imitation_history(hp, "dagger")
    ds, env_kwargs = load_run_dataset(run, hp.get("env_kwargs"))
    # the family's own refusal (a teacher it cannot label with), before any training
    IMITATION_FAMILIES.of(get_scenario(ds.meta["scenario"])).check_teacher(teacher)
    seed = int(run["seed"])
    th.manual_seed(seed)
    ckdir = run_dir / "checkpoints"
    ckdir.mkdir(parents=True, exist_ok=True)
    lbdir = run_dir / "labels"
    lbdir.mkdir(parents=True, exist_ok=True)
    done = sorted((int(m.group(1)), f) for f in ckdir.iterdir() if (m := _DG_CKPT.match(f.name)))
    if resume and done:
        from agents.common.runs import newest_loadable

        path, model = newest_loadable([f for _, f in reversed(done)],
                                      lambda f: PPO.load(f, device=run["device"]),
                                      what="DAgger checkpoint")
        it0 = int(_DG_CKPT.match(path.name).group(1))
        start = it0 + 1
        print(f"Resuming DAgger {run_dir} after iteration {it0} of {dg['n_iterations']}")
    else:
        if resume:
            print(f"No DAgger iteration finished in {run_dir}: starting from the initial policy")
        start = 0
        if run.get("init"):
            init = load_policy_model(run["init"], device=run["device"])
            model = build_model(run["env"], env_kwargs, hp["policy_kwargs"], seed, run["device"],
                                hp.get("obs_features"),
                                True if hp.get("standardize_inputs") else None, history_k)
            try:
                model.policy.load_state_dict(init.policy.state_dict())
            except RuntimeError as exc:
                raise ValueError(f"--init {run['init']}: its policy does not match "
                                 f"policy_kwargs {hp['policy_kwargs']} and history={history_k} "
                                 f"({exc})") from None
        elif history_k is not None:
            print(f"A student with a history of {history_k}: the teacher flies the first "
                  "iteration; the student is fitted on its flights (the dataset holds no "
                  "histories)")
            # inputs standardised with the first labels' statistics once they exist
            model = build_model(run["env"], env_kwargs, hp["policy_kwargs"], seed, run["device"],
                                hp.get("obs_features"), None, history_k)
        else:
            print("No --init policy: behaviour cloning first (bc section of the config)")
            bc_dir = run_dir / "bc_init"
            bc_dir.mkdir(exist_ok=True)
            # a run directory of its own (evaluate / --init-from read its inputs from config.yml)
            write_text_atomic(bc_dir / "config.yml", yaml.safe_dump(hp, sort_keys=True))
            write_text_atomic(bc_dir / "args.yml", yaml.safe_dump(
                dict(run, mode="bc", run_dir=str(bc_dir)), sort_keys=True))
            model = train_bc(hp, dict(run, no_tensorboard=True), bc_dir)
    policy = model.policy
    rng = np.random.default_rng(seed + 7919)
    teacher_first = history_k is not None and not run.get("init")
    if history_k is None:
        inputs = policy_inputs(run["env"], env_kwargs, hp.get("obs_features"))
        ds_inputs, ds_actions = inputs(ds.observations), ds.actions
    else:  # the labels hold the student's stacked inputs, features included
        def inputs(x):
            return np.asarray(x, dtype=np.float32)

        ds_inputs = ds_actions = None
    logger = _logger(run_dir, not run.get("no_tensorboard"))
    scenario = get_scenario(ds.meta["scenario"])
    family = IMITATION_FAMILIES.of(scenario)
    history_file = run_dir / "dagger_history.yml"
    history = yaml.safe_load(history_file.read_text()) if history_file.exists() else []
    history = [h for h in history if h["iteration"] < start]
    for it in range(start, int(dg["n_iterations"])):
        t_it = time.perf_counter()
        lb_file = lbdir / f"iter_{it:03d}.npz"
        if lb_file.exists():  # labels of an interrupted iteration: reuse, do not re-solve
            with np.load(lb_file) as z:
                lab = {k: z[k] for k in z.files}
            roll = {k: float(lab.pop(k)) for k in list(lab) if k.startswith("rollout_")}
            print(f"DAgger iteration {it}: reusing {len(lab['obs'])} labels from {lb_file}")
        else:
            ep_seed = seed + int(dg.get("seed_offset", 100000)) + it * int(dg["n_episodes"])
            # the family flies this iteration's policy (saved: worker processes load it) and
            # its expert labels the visited states
            pol_file = lbdir / f"iter_{it:03d}_policy.zip"
            if not pol_file.exists():
                save_model_atomic(model, pol_file)
            request = DaggerRequest(
                env_id=run["env"], env_kwargs=env_kwargs, policy_file=str(pol_file),
                load_learner=load_learner, obs_features=hp.get("obs_features"),
                n_episodes=int(dg["n_episodes"]), seed=ep_seed, settings=dict(dg),
                n_workers=int(dg.get("n_label_workers", 1)),
                store_dir=lbdir / f"iter_{it:03d}_parts", progress=not run.get("no_progress"),
                history=history_k, teacher_throughout=teacher_first and it == 0)
            lab, roll = family.dagger_iteration(scenario, request)
            save_npz_atomic(lb_file, {**lab, **{k: np.array(v) for k, v in roll.items()}},
                            compressed=True)
        who = "teacher" if teacher_first and it == 0 else "policy"
        print(f"DAgger iteration {it}: {who} roll-outs success "
              f"{100 * roll['rollout_success_rate']:.1f} %, mean fuel "
              f"{roll['rollout_fuel_mean_kg']:.2f} kg; {len(lab['obs'])} expert labels",
              flush=True)
        if teacher_first and it == 0 and hp.get("standardize_inputs"):
            # the student's input statistics: those of the teacher's flights, as a clone
            # takes its dataset's (same seed: the same initial weights)
            th.manual_seed(seed)
            model = build_model(run["env"], env_kwargs, hp["policy_kwargs"], seed,
                                run["device"], hp.get("obs_features"), inputs(lab["obs"]),
                                history_k)
            policy = model.policy
        agg_obs, agg_act = [], []
        for j in range(it + 1):
            with np.load(lbdir / f"iter_{j:03d}.npz") as z:
                keep = np.ones(len(z["obs"]), dtype=bool)
                if dg.get("drop_fallback_labels", True):
                    # decision: a "fallback" label is the expert's braking guess where it found
                    # no landing at all, not an optimal action; measured, it contradicts the
                    # optimal labels next to it (35-43° RMS apart) and only adds noise
                    keep = z["status"] != "fallback"
                agg_obs.append(z["obs"][keep])
                agg_act.append(z["actions"][keep])
        eo, ea = inputs(np.concatenate(agg_obs)), np.concatenate(agg_act)
        fraction = dg.get("dagger_fraction")
        if fraction is None:
            # pooled (Ross et al. 2011's aggregate): one epoch is one pass over the dataset and
            # every label so far, drawn alike
            main_obs, main_act = ((eo, ea) if ds_inputs is None else
                                  (np.concatenate([ds_inputs, eo]),
                                   np.concatenate([ds_actions, ea])))
            eo = ea = None
            fraction = 0.0
        else:
            main_obs, main_act = ds_inputs, ds_actions
        stats = fit_policy(policy, main_obs, main_act, n_epochs=int(dg["n_epochs"]),
                           batch_size=int(dg["batch_size"]),
                           learning_rate=float(dg["learning_rate"]),
                           learning_rate_final=float(dg.get("learning_rate_final",
                                                            dg["learning_rate"])),
                           rng=rng, extra_obs=eo, extra_act=ea,
                           extra_fraction=float(fraction),
                           val_obs=inputs(agg_obs[-1]), val_act=agg_act[-1],
                           logger=logger, progress=not run.get("no_progress"),
                           log_prefix=f"dagger_iter{it}",
                           step_offset=it * int(dg["n_epochs"]))
        for k, v in roll.items():
            logger.record(f"dagger/{k}", v)
        n_total = sum(len(o) for o in agg_obs)
        logger.record("dagger/n_labels_total", n_total)
        logger.dump(it)
        status, counts = np.unique(lab["status"], return_counts=True)
        history.append({"iteration": it, **roll, "n_labels": int(len(lab["obs"])),
                        "n_labels_total": int(n_total),
                        "expert_status": {str(s): int(c) for s, c in zip(status, counts,
                                                                          strict=True)},
                        "train_loss": float(stats["train_loss"]),
                        "wall_s": time.perf_counter() - t_it})
        save_model_atomic(model, ckdir / f"dagger_iter_{it}.zip")
        write_text_atomic(history_file, yaml.safe_dump(history))
    logger.close()
    n_select = int(dg.get("select_states") or 0)
    if n_select > 0:
        model = select_iteration(run_dir, run["env"], env_kwargs, hp.get("obs_features"),
                                 n_select, int(dg.get("select_seed", 50000)), run["device"],
                                 history_k)
    path = _save_final(model, run_dir)
    print(f"DAgger done ({dg['n_iterations']} iterations). Model: {path}")
    return model


def select_iteration(run_dir: Path, env_id: str, env_kwargs: dict[str, Any] | None,
                     obs_features: list[str] | None, n_states: int, seed: int,
                     device: str = "cpu", history: int | None = None):
    """The DAgger iteration whose policy lands most often on held-out validation states.

    Ross et al. (2011) guarantee the *best* of the iterates, not the last: the policy of one
    iteration to the next may trade a few cases (measured on the pinpoint env: 99.5 % after
    iteration 6, 99.0 % after 7, on the evaluation's 200 states). Each checkpoint flies cases
    ``seed .. seed + n_states - 1`` (default seed 50000: disjoint from the dataset's, the
    roll-outs' and the evaluation's cases; :mod:`agents.rl.selection`); ties go to the later
    iteration. ``history``: the run's (the policies' inputs). The scores are written to
    ``selection.yml``; returns the chosen model.
    """
    from stable_baselines3 import PPO

    from agents.rl.selection import best_of, score_candidates, write_selection

    ckdir = run_dir / "checkpoints"
    done = sorted((int(m.group(1)), f) for f in ckdir.iterdir() if (m := _DG_CKPT.match(f.name)))
    if not done:
        raise FileNotFoundError(f"no DAgger checkpoint in {ckdir}")
    scores = score_candidates(done, env_id, env_kwargs,
                              obs_features, n_states, seed, device, label="DAgger iteration",
                              history=history)
    best = best_of(scores)
    write_selection(run_dir, seed, n_states, "iteration", scores, best)
    print(f"DAgger selection: iteration {best['key']} ({100 * best['success_rate']:.1f} %)")
    return PPO.load(dict(done)[best["key"]], device=device)
