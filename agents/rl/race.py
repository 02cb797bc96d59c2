"""Seed race: train a few seeds side by side and keep the one that has learnt to land.

Why: whether a pinpoint PPO run meets the target is, to a large part, the seed's
draw. Of fourteen seeds of the 9e6 entry trained alone, eleven land 95-100 % of the evaluation
states; two never learn to land (0 %) and one lands 77.5 %. The default run therefore trains
seeds ``seed, seed + 1`` in two processes, one per core (each at ~85-95 % of the speed of one
run alone: a run uses one core), and keeps the one whose policy lands more of the held-out
validation cases (:data:`agents.rl.selection.VALIDATION_SEED`.., never the evaluation's). This is
successive halving over seeds (Jamieson & Talwalkar 2016; Li et al. 2018, Hyperband), decided
by the env's own verdict.

Every candidate trains to the end, with its own checkpoint selection, and the run adopts the
winner's selected policy: a run alone uses one core, so racing to the end costs little wall time
(training and selection 690-811 s), and the choice is made on the final policies. (Deciding at
70 % and continuing the winner alone was measured and removed: ``--seed 28``'s seed 29,
continued alone from 70 %, ended at 93.1 %, trained in one go at 99.0 %.)

The candidates are keyed tasks on the project's executor
(:class:`optimizers.common.executor.LocalExecutor`, one worker per candidate): a candidate whose
run directory already holds its final checkpoint and selection counts as done and is not
trained again.

Layout: the candidates are full run directories ``<run>/race/seed_<s>`` (each can be resumed
or evaluated alone); ``<run>/race.yml`` records the scores and the chosen seed; the winner's
checkpoints, ``model.zip``, ``vecnormalize.pkl`` and ``selection.yml`` are copied into the run
and the run's ``args.yml`` gets its seed, so the rest is an ordinary run. An interrupted race
resumes its candidates (``python train.py --resume <run>``).
"""

from __future__ import annotations

import multiprocessing
import os
import shutil
import signal
import sys
import time
from pathlib import Path
from typing import Any

import yaml

from agents.common.runs import checkpoints, write_text_atomic
from optimizers.common.checkpoint import atomic_write_bytes

__all__ = ["race_done", "race_pending", "race_settings", "race_trained_to_end", "seed_race"]


def race_settings(hp: dict[str, Any]) -> int | None:
    """The number of candidates of a ``seed_race: {candidates: N}`` entry, or None without one.

    ``candidates``: seeds trained side by side to the end (an integer >= 2, default 2).

    Raises
    ------
    ValueError
        ``candidates`` is not an integer >= 2, or the entry has another key.
    """
    spec = hp.get("seed_race")
    if not spec:
        return None
    from lunar_env.validation import require_number, require_option_keys

    require_option_keys("seed_race", spec, ("candidates",))
    k = require_number("seed_race candidates", spec.get("candidates", 2))
    if k != int(k) or k < 2:
        raise ValueError(f"seed_race candidates={k!r} must be an integer >= 2")
    return int(k)


def race_done(run_dir: Path) -> bool:
    """The race of ``run_dir`` is over: its winner's checkpoints are the run's (the last step of
    :func:`seed_race`; before it, ``--resume`` goes back into the race)."""
    return (Path(run_dir) / "checkpoints").is_dir()


def race_pending(hp: dict[str, Any], run_dir: Path) -> bool:
    """The run has a ``seed_race`` entry and its race is not over yet."""
    return bool(hp.get("seed_race")) and not race_done(run_dir)


def race_trained_to_end(hp: dict[str, Any], run_dir: Path) -> bool:
    """The run's race is over and its winner's final policy, trained to ``n_timesteps``, is the
    run's: nothing is left to train (``train.py -n`` extending the run trains again)."""
    if race_settings(hp) is None or not race_done(run_dir):
        return False
    return _reached(run_dir, int(hp["n_timesteps"])) and (Path(run_dir) / "model.zip").exists()


def _reached(run_dir: Path, steps: int) -> bool:
    """The newest checkpoint of ``run_dir`` is at ``steps`` or later."""
    ck = checkpoints(run_dir)
    return bool(ck) and ck[0][0] >= steps


def _candidate_done(cand: Path, hp: dict[str, Any]) -> bool:
    """A candidate finished before an interruption: trained to the end and, with
    ``select_checkpoint``, its checkpoint selection written."""
    return _reached(cand, int(hp["n_timesteps"])) and \
        (not hp.get("select_checkpoint") or (cand / "selection.yml").exists())


def train_candidate(hp: dict[str, Any], run: dict[str, Any], cand_dir: str) -> int:
    """Executor task: train one candidate to the end in ``cand_dir`` (resumed from its newest
    checkpoint when it has one), its console lines prefixed ``[seed <s>]``; returns its final
    ``num_timesteps``.

    In a worker process, SIGTERM raises KeyboardInterrupt for the whole task (``train`` turns
    it into a checkpoint while it learns), and once the task has returned the worker ignores
    SIGTERM and SIGINT: the race stops its workers by SIGTERM, and a candidate that finished
    before the others would otherwise die of it, idle, and break the pool under the candidates
    still checkpointing (seen as a lost checkpoint message and as a hung race).

    Raises
    ------
    KeyboardInterrupt
        Interrupted (Ctrl-C or SIGTERM): the candidate wrote its checkpoint first.
    RuntimeError
        Training failed; the message names the seed and the candidate's run directory.
    """
    from agents.common.runs import resumable_checkpoint
    from agents.rl.training import interrupt_on_sigterm, train

    cand = Path(cand_dir)
    in_worker = multiprocessing.parent_process() is not None
    if in_worker:
        signal.signal(signal.SIGTERM, interrupt_on_sigterm)
        signal.signal(signal.SIGINT, signal.default_int_handler)
    streams = sys.stdout, sys.stderr
    sys.stdout = _Prefixed(streams[0], f"[seed {run['seed']}] ")
    sys.stderr = _Prefixed(streams[1], f"[seed {run['seed']}] ")
    try:
        try:
            resumable_checkpoint(cand, needs_vecnormalize=bool(hp.get("normalize")),
                                 log=lambda msg: None)
            resume = True
        except FileNotFoundError:
            resume = False
        try:
            model, _ = train(hp, run, cand, resume=resume)
        except Exception as exc:
            raise RuntimeError(f"seed race: candidate seed {run['seed']} failed ({exc!r}); its "
                               f"run directory is {cand}") from exc
        return int(model.num_timesteps)
    finally:
        sys.stdout, sys.stderr = streams
        if in_worker:  # idle until the pool's shutdown ends it
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
            signal.signal(signal.SIGINT, signal.SIG_IGN)


class _Prefixed:
    """A text stream that starts every line with ``prefix`` (two candidates share a console)."""

    def __init__(self, stream, prefix: str) -> None:
        self.stream, self.prefix, self._bol = stream, prefix, True

    def write(self, text: str) -> int:
        out = []
        for piece in text.splitlines(keepends=True):
            if self._bol:
                out.append(self.prefix)
            out.append(piece)
            self._bol = piece.endswith("\n")
        self.stream.write("".join(out))
        self.stream.flush()
        return len(text)

    def flush(self) -> None:
        self.stream.flush()

    def __getattr__(self, name: str):
        return getattr(self.stream, name)


def seed_race(hp: dict[str, Any], run: dict[str, Any], run_dir: Path) -> dict[str, Any]:
    """Run (or finish) the seed race of ``run_dir``; returns the run arguments with the chosen
    seed, ``args.yml`` rewritten and the winner's checkpoints and final policy in ``run_dir``.
    Idempotent once decided.

    Raises
    ------
    RuntimeError
        A candidate failed, or has no checkpoint at ``n_timesteps`` after training.
    KeyboardInterrupt
        Interrupted: every candidate wrote its checkpoint; ``--resume`` continues the race.
    """
    from agents.rl.selection import VALIDATION_SEED, score_candidates

    run_dir = Path(run_dir)
    k = race_settings(hp)
    n_total = int(hp["n_timesteps"])
    race_file = run_dir / "race.yml"
    if race_file.exists():
        decision = yaml.safe_load(race_file.read_text())
    else:
        base_seed = int(run.get("race_seed", run["seed"]))
        seeds = [base_seed + i for i in range(k)]
        # select_checkpoint stays: each candidate selects its final policy in its own process
        cand_hp = {key: v for key, v in hp.items() if key != "seed_race"}
        dirs = [run_dir / "race" / f"seed_{s}" for s in seeds]
        print(f"Seed race: seeds {', '.join(map(str, seeds))} train side by side to the "
              f"end ({n_total:,} steps); the final policy that lands more validation cases "
              f"is the run's (agents/rl/race.py)", flush=True)
        t0 = time.perf_counter()
        _train_candidates(cand_hp, run, seeds, dirs)
        race_wall_s = time.perf_counter() - t0
        sel = hp.get("select_checkpoint") or {}
        n_states = int(sel.get("states", 100))
        val_seed = int(sel.get("seed", VALIDATION_SEED))  # the checkpoint selection's cases
        found = []
        for s, d in zip(seeds, dirs, strict=True):
            ck = checkpoints(d)
            if not ck or ck[0][0] < n_total:
                raise RuntimeError(f"seed race: candidate {d} has no checkpoint at step "
                                   f">= {n_total}")
            found.append((s, ck[0][1], ck[0][0]))
        scores = _selected_scores(dirs, n_states, val_seed)
        if scores is None:  # no checkpoint selection: the final policies are scored here
            scores = score_candidates([(s, path) for s, path, _ in found], run["env"],
                                      hp.get("env_kwargs"), hp.get("obs_features"), n_states,
                                      val_seed, run.get("device", "cpu"), label="seed",
                                      history=hp.get("history"))
        # the most landings; a tie goes to the earlier seed (the user's own first)
        best = max(range(k), key=lambda i: (scores[i]["success_rate"], -i))
        decision = {"seeds": seeds, "decide_at_steps": int(found[best][2]),
                    "validation_seed": val_seed, "n_states": n_states,
                    "chosen_seed": seeds[best], "race_wall_s": round(race_wall_s, 1),
                    "scores": [{"seed": s, "success_rate": r["success_rate"]}
                               for s, r in zip(seeds, scores, strict=True)]}
        write_text_atomic(race_file, yaml.safe_dump(decision, sort_keys=False))
        print(f"Seed race: seed {seeds[best]} wins "
              f"({100 * scores[best]['success_rate']:.1f} % of {n_states} validation cases; "
              + ", ".join(f"seed {s}: {100 * r['success_rate']:.1f} %"
                          for s, r in zip(seeds, scores, strict=True)) + ")", flush=True)
    chosen = int(decision["chosen_seed"])
    _adopt(run_dir / "race" / f"seed_{chosen}", run_dir)
    run = dict(run)
    run.setdefault("race_seed", int(decision["seeds"][0]))
    run["seed"] = chosen
    write_text_atomic(run_dir / "args.yml", yaml.safe_dump(run, sort_keys=True))
    return run


def _selected_scores(dirs: list[Path], n_states: int, val_seed: int
                     ) -> list[dict[str, Any]] | None:
    """Each candidate's validation success from its own checkpoint selection (the chosen
    checkpoint's, on the same cases), or None when one has no matching ``selection.yml``."""
    out = []
    for d in dirs:
        f = d / "selection.yml"
        sel = yaml.safe_load(f.read_text()) if f.exists() else None
        if not sel or int(sel["validation_seed"]) != val_seed or \
                int(sel["n_states"]) != n_states:
            return None
        chosen = [c for c in sel["scores"] if c["steps"] == sel["chosen_steps"]]
        out.append({"success_rate": float(chosen[0]["success_rate"])})
    return out


def _adopt(cand: Path, run_dir: Path) -> None:
    """Copy the winner's final policy (``model.zip``, ``vecnormalize.pkl``, ``selection.yml``),
    then its checkpoints (atomic rename of the folder: a run whose checkpoints are there has its
    final policy too), TensorBoard log and timing into the run; each skipped when already
    there."""
    target = run_dir / "checkpoints"
    if not target.exists():
        for name in ("model.zip", "vecnormalize.pkl", "selection.yml"):
            if (cand / name).exists():
                atomic_write_bytes(run_dir / name, (cand / name).read_bytes())
    if not target.exists():
        tmp = run_dir / "checkpoints.tmp"
        shutil.rmtree(tmp, ignore_errors=True)
        shutil.copytree(cand / "checkpoints", tmp)
        os.replace(tmp, target)
    timing = cand / "timing.yml"
    if timing.exists() and not (run_dir / "timing.yml").exists():
        write_text_atomic(run_dir / "timing.yml", timing.read_text())
    if (cand / "tb").is_dir() and not (run_dir / "tb").exists():
        shutil.copytree(cand / "tb", run_dir / "tb")


def _train_candidates(hp: dict[str, Any], run: dict[str, Any], seeds: list[int],
                      dirs: list[Path]) -> None:
    """Train every candidate not done yet to the end (checkpoint selection included) as a task
    :func:`train_candidate` keyed ``("seed_race", seeds[0], i)`` on a
    :class:`~optimizers.common.executor.LocalExecutor` with one worker per candidate. A Ctrl-C
    or SIGTERM lets each candidate write its checkpoint (SIGTERM is passed on to the workers),
    then propagates as KeyboardInterrupt; a failed candidate stops the others the same way
    before its error propagates."""
    from optimizers.common.executor import LocalExecutor, Task, TaskKey, run_tasks

    tasks = []
    for i, (s, d) in enumerate(zip(seeds, dirs, strict=True)):
        if _candidate_done(d, hp):
            continue
        d.mkdir(parents=True, exist_ok=True)
        cand_run = dict(run, seed=s, run_dir=str(d), no_progress=True, eval_states=0,
                        no_eval=True)
        cand_run.pop("race_seed", None)
        write_text_atomic(d / "config.yml", yaml.safe_dump(hp, sort_keys=True))
        write_text_atomic(d / "args.yml", yaml.safe_dump(cand_run, sort_keys=True))
        tasks.append(Task(TaskKey("seed_race", int(seeds[0]), i), train_candidate,
                          (hp, cand_run, str(d))))
    if not tasks:
        return

    def _stop_workers(signum=None, frame=None):
        for p in multiprocessing.active_children():  # each checkpoints on SIGTERM (train())
            os.kill(p.pid, signal.SIGTERM)
        if signum is not None:
            raise KeyboardInterrupt

    old = signal.signal(signal.SIGTERM, _stop_workers)
    try:
        with LocalExecutor(len(tasks)) as executor:
            run_tasks(tasks, executor)
    except KeyboardInterrupt:
        _join_workers()  # the workers got the Ctrl-C (or SIGTERM) too: let them checkpoint
        raise
    except BaseException:
        _stop_workers()
        _join_workers()
        raise
    finally:
        signal.signal(signal.SIGTERM, old)


def _join_workers() -> None:
    """Wait for this process's worker processes to end."""
    for p in multiprocessing.active_children():
        p.join()
