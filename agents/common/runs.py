"""Run directories, checkpoints and trained models: one module for train, evaluate, imitation.

A run directory ``<log-folder>/<algo>/<env id>_<k>/`` (RL Zoo layout) holds ``config.yml``,
``args.yml``, ``command.txt``, ``checkpoints/rl_model_<steps>_steps.zip`` with
``rl_model_vecnormalize_<steps>_steps.pkl`` (and the replay buffer of off-policy algorithms),
``model.zip`` + ``vecnormalize.pkl`` (the final model) and ``timing.yml``.

Guarantees:

- :func:`next_run_dir` *creates* the directory atomically (``mkdir`` without ``exist_ok`` in a
  retry loop), so concurrent runs in one folder never share a directory;
- :func:`write_text_atomic` / :func:`save_model_atomic` write to a temporary file in the same
  folder and ``os.replace`` it into place: a kill leaves the previous file or the new one,
  never half of one. A checkpoint's statistics are written *before* its model, so a model file
  implies its statistics;
- :func:`resumable_checkpoint` picks the newest *complete* checkpoint (readable zip, and its
  normalisation statistics when the run normalises observations), says which newer ones it
  skipped and why, and refuses to resume a normalised run without statistics.
"""

from __future__ import annotations

import json
import os
import pickle
import re
import zipfile
from pathlib import Path
from typing import Any

import yaml

from optimizers.common.checkpoint import atomic_write_bytes
from optimizers.common.processes import exit_with_parent

__all__ = ["CKPT_RE", "next_run_dir", "claim_run_dir", "run_dir_of", "read_run", "checkpoints",
           "latest_checkpoint", "resumable_checkpoint", "trained_files", "load_trained",
           "write_text_atomic", "save_model_atomic", "save_vecnormalize_atomic", "algo_class",
           "newest_loadable", "exit_with_parent", "MAX_SB3_SEED", "ALGO_NAMES"]

CKPT_RE = re.compile(r"^rl_model_(\d+)_steps\.zip$")
#: largest seed of a training run: SB3 seeds numpy's global generator (``np.random.seed``
#: takes seeds below 2**32), and a seed race or DAgger's roll-outs add offsets to it
MAX_SB3_SEED = 2**31 - 1


#: the algorithms of a run (``--algo``) in the order the command line lists them
ALGO_NAMES = ("ppo", "sac", "td3", "recurrent-ppo")


def algo_class(algo: str):
    """The SB3 class of ``algo`` (one of :data:`ALGO_NAMES`).

    ``"recurrent-ppo"`` is :class:`agents.common.recurrent.RecurrentPPO` (sb3-contrib's LSTM
    PPO), imported only here: without sb3-contrib installed it raises Gymnasium's
    ``DependencyNotInstalled`` naming the ``memory`` extra, and the other algorithms work.

    Raises
    ------
    ValueError
        An algorithm not in :data:`ALGO_NAMES`.
    """
    if algo not in ALGO_NAMES:
        raise ValueError(f"algo = {algo!r}; allowed: {list(ALGO_NAMES)}")
    if algo == "recurrent-ppo":
        from agents.common.recurrent import RecurrentPPO

        return RecurrentPPO
    from stable_baselines3 import PPO, SAC, TD3

    return {"ppo": PPO, "sac": SAC, "td3": TD3}[algo]


# ----------------------------------------------------------------------------- writing


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (temporary file in the same folder, then
    ``os.replace``)."""
    return atomic_write_bytes(path, text.encode())


def _fsync(path: Path) -> None:
    with open(path, "rb") as fh:
        os.fsync(fh.fileno())


def _save_atomic(save, path: Path, tmp: Path) -> Path:
    """``save(tmp)`` (a library's own writer), fsync, then ``os.replace(tmp, path)``; the
    temporary file is removed if anything fails."""
    try:
        save(tmp)
        _fsync(tmp)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def save_model_atomic(model, path: str | Path) -> Path:
    """``model.save`` to a temporary ``.zip`` beside ``path`` (unique per process), then
    ``os.replace``."""
    path = Path(path)
    return _save_atomic(model.save, path, path.with_name(f".{path.stem}.{os.getpid()}.tmp.zip"))


def save_vecnormalize_atomic(vecnormalize, path: str | Path) -> Path:
    """``VecNormalize.save`` to a temporary file beside ``path``, then ``os.replace``."""
    path = Path(path)
    return _save_atomic(lambda tmp: vecnormalize.save(str(tmp)), path,
                        path.with_name(f".{path.name}.{os.getpid()}.tmp"))


def newest_loadable(candidates, load, what: str = "checkpoint", log=print):
    """``(path, load(path))`` of the first of ``candidates`` (newest first) that loads.

    Damaged files are skipped with a message through ``log`` naming each and why; if none
    loads, ``FileNotFoundError`` lists every file and its error.
    """
    rejected = []
    for path in candidates:
        try:
            obj = load(path)
        except Exception as exc:  # a damaged file: any reader error
            rejected.append((path, f"{type(exc).__name__}: {exc}"))
            continue
        for p, why in rejected:
            log(f"resume: skipping damaged {what} {p} ({why}); using {path}")
        return path, obj
    details = "; ".join(f"{p}: {why}" for p, why in rejected) or "none found"
    raise FileNotFoundError(f"no loadable {what} ({details})")


# ----------------------------------------------------------------------------- run dirs


def next_run_dir(parent: str | Path, prefix: str) -> Path:
    """Create and return ``parent/<prefix>_<k>``, k one past the highest existing index.

    The directory is created here, atomically: two processes asking at the same instant get
    two different directories.
    """
    parent = Path(parent)
    parent.mkdir(parents=True, exist_ok=True)
    pattern = re.compile(rf"^{re.escape(prefix)}_(\d+)$")
    k = 1 + max((int(m.group(1)) for d in parent.iterdir()
                 if (m := pattern.match(d.name))), default=0)
    while True:
        path = parent / f"{prefix}_{k}"
        try:
            path.mkdir()
            return path
        except FileExistsError:
            k += 1


def claim_run_dir(path: str | Path) -> Path:
    """Create an explicit run directory (``--run-dir``) for this process alone.

    The directory may exist only if empty; the claim is an exclusive lock file
    (``O_CREAT | O_EXCL``), so two processes given the same directory never both get it.

    Raises
    ------
    FileExistsError
        It holds files already, or another process claimed it first.
    """
    path = Path(path)
    path.mkdir(parents=True, exist_ok=True)
    if any(p.name != ".claimed" for p in path.iterdir()):
        raise FileExistsError(f"run directory {path} exists and is not empty; use --resume")
    try:
        fd = os.open(path / ".claimed", os.O_CREAT | os.O_EXCL | os.O_WRONLY)
    except FileExistsError:
        raise FileExistsError(f"run directory {path} was claimed by another process (if none "
                              f"runs there, delete {path / '.claimed'})") from None
    os.write(fd, f"{os.getpid()}\n".encode())
    os.close(fd)
    return path


def run_dir_of(path: str | Path) -> Path:
    """The run directory of a run directory, a model ``.zip`` in it, or a checkpoint ``.zip``."""
    p = Path(path)
    if p.is_dir():
        return p
    return p.parent.parent if p.parent.name == "checkpoints" else p.parent


def read_run(path: str | Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """``(args, config)`` of a run (``args.yml``, ``config.yml``; empty dicts when absent)."""
    run_dir = run_dir_of(path)
    out = []
    for name in ("args.yml", "config.yml"):
        f = run_dir / name
        out.append((yaml.safe_load(f.read_text()) or {}) if f.exists() else {})
    return out[0], out[1]


# ----------------------------------------------------------------------------- checkpoints


def checkpoints(run_dir: str | Path) -> list[tuple[int, Path]]:
    """``(steps, path)`` of every ``rl_model_<steps>_steps.zip`` of a run, newest first."""
    ckdir = Path(run_dir) / "checkpoints"
    found = []
    if ckdir.is_dir():
        for f in ckdir.iterdir():
            m = CKPT_RE.match(f.name)
            if m:
                found.append((int(m.group(1)), f))
    return sorted(found, reverse=True)


def latest_checkpoint(run_dir: str | Path) -> tuple[Path, int]:
    """Newest checkpoint file of a run and its step count (no validation).

    Raises
    ------
    FileNotFoundError
        If the run has no checkpoint.
    """
    found = checkpoints(run_dir)
    if not found:
        ckdir = Path(run_dir) / "checkpoints"
        raise FileNotFoundError(f"no checkpoint rl_model_<steps>_steps.zip in {ckdir}; "
                                "the run cannot be resumed (start it again without --resume)")
    steps, path = found[0]
    return path, steps


def _vecnormalize_path(ckpt: Path, steps: int) -> Path:
    return ckpt.parent / f"rl_model_vecnormalize_{steps}_steps.pkl"


def _readable_zip(path: Path) -> str | None:
    """None for a readable SB3 model zip, else why not (damaged, or not a model)."""
    try:
        with zipfile.ZipFile(path) as zf:
            bad = zf.testzip()
            names = set(zf.namelist())
        if bad is not None:
            return f"member {bad} is corrupt"
        missing = {"data", "policy.pth"} - names
        return f"not an SB3 model (no {sorted(missing)})" if missing else None
    except (zipfile.BadZipFile, OSError, EOFError, ValueError) as exc:
        return f"not a readable zip ({exc})"


def _readable_pickle(path: Path) -> str | None:
    if not path.exists():
        return f"its statistics {path.name} are missing"
    try:
        with open(path, "rb") as fh:
            pickle.load(fh)
        return None
    except Exception as exc:  # any unpickling failure means a damaged file
        return f"its statistics {path.name} are unreadable ({type(exc).__name__})"


def resumable_checkpoint(run_dir: str | Path, *, needs_vecnormalize: bool,
                         log=print) -> tuple[Path, int, Path | None]:
    """The newest complete checkpoint: ``(model zip, steps, statistics path or None)``.

    A checkpoint is complete when its zip reads and, for a run that normalises observations
    (``needs_vecnormalize``), its ``VecNormalize`` statistics exist and unpickle. Newer
    incomplete checkpoints are skipped with a message through ``log``.

    Raises
    ------
    FileNotFoundError
        No checkpoint at all, or none complete (the message lists why each was rejected).
    """
    found = checkpoints(run_dir)
    if not found:
        latest_checkpoint(run_dir)  # raises the no-checkpoint error
    rejected = []
    for steps, path in found:
        why = _readable_zip(path)
        vn = _vecnormalize_path(path, steps)
        if why is None and needs_vecnormalize:
            why = _readable_pickle(vn)
        if why is None:
            for _, p, w in rejected:
                log(f"resume: skipping checkpoint {p.name} ({w}); using {path.name}")
            return path, steps, (vn if vn.exists() else None)
        rejected.append((steps, path, why))
    details = "; ".join(f"{p.name}: {w}" for _, p, w in rejected)
    raise FileNotFoundError(f"no complete checkpoint in {Path(run_dir) / 'checkpoints'} "
                            f"({details}); the run cannot be resumed")


def trained_files(run_dir_or_model: str | Path, log=print) -> tuple[Path, Path | None]:
    """The files :func:`load_trained` reads: ``(model zip, VecNormalize statistics or None)``.

    A run directory gives its ``model.zip`` (else its newest complete checkpoint); a ``.zip``
    path gives itself, with the statistics beside it (``vecnormalize.pkl``, or the matching
    checkpoint's). ``log`` receives the messages of skipped incomplete checkpoints.

    Raises
    ------
    FileNotFoundError
        No model file (or, for a run directory without ``model.zip``, no complete checkpoint).
    """
    p = Path(run_dir_or_model)
    if p.is_dir():
        if (p / "model.zip").exists():
            model_path, vn_path = p / "model.zip", p / "vecnormalize.pkl"
        else:
            _, cfg = read_run(p)
            model_path, _, vn_path = resumable_checkpoint(
                p, needs_vecnormalize=bool(cfg.get("normalize")), log=log)
            vn_path = vn_path or model_path.parent / "missing.pkl"
    else:
        model_path = p
        m = CKPT_RE.match(p.name)
        vn_path = (_vecnormalize_path(p, int(m.group(1))) if m
                   else p.parent / "vecnormalize.pkl")
    if not model_path.exists():
        raise FileNotFoundError(f"model file {model_path} does not exist")
    return model_path, (vn_path if vn_path.exists() else None)


def load_trained(run_dir_or_model: str | Path, env=None, device: str = "cpu"):
    """Load a trained model and its ``VecNormalize`` statistics.

    Parameters
    ----------
    run_dir_or_model : str or Path
        A run directory (uses ``model.zip``, else the newest complete checkpoint) or a ``.zip``
        path (statistics from ``vecnormalize.pkl`` beside it or the matching checkpoint file).
    env : VecEnv, optional
        Attached to the model (needed only to continue training).

    Returns
    -------
    model : BaseAlgorithm
    vecnormalize_path : Path or None
    algo : str
    """
    p = Path(run_dir_or_model)
    model_path, vn_path = trained_files(p)
    algo = read_run(p)[0].get("algo")
    if algo is None:
        with zipfile.ZipFile(model_path) as zf:
            data = zf.read("data").decode()
        # a model without its run files: the algorithm from what its saved data holds (the
        # recurrent policies are sb3-contrib's and agents.common.recurrent's)
        policy = json.loads(data).get("policy_class")
        if isinstance(policy, dict) and "common.recurrent" in str(policy.get("__module__")):
            algo = "recurrent-ppo"
        else:
            algo = "sac" if '"log_ent_coef"' in data else ("td3" if "target_policy_noise" in data
                                                            else "ppo")
    model = algo_class(algo).load(model_path, env=env, device=device)
    return model, vn_path, algo
