"""A trained Stable-Baselines3 model as a guidance law (:mod:`guidance.law`), memory included.

A policy with memory flies the contract of :mod:`guidance.law`: its memory is per row (per
lander) and a row's memory restarts wherever ``nav.episode_start`` is true, so the law flies an
autoresetting vector env as SB3 trained it:

- a recurrent policy (``recurrent-ppo``, sb3-contrib's LSTM policy) keeps its LSTM state per row
  and hands ``episode_start`` to the policy, which zeroes those rows' state before the step;
- a policy trained with a stacked history (``history: k``, :mod:`agents.features.history`)
  rebuilds its input per row from ``nav.obs`` and the law's own previous actions, the history
  of a starting row filled with its first input.
"""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np

from agents.features import augment_observation, feature_constants, validate_features
from agents.features.history import HistoryStack, validate_history
from guidance.law import FlightComputer, GuidanceLaw, Navigation

__all__ = ["SB3Law", "law_from_spec", "run_env_kwargs", "run_identity"]


class SB3Law(GuidanceLaw):
    """A trained SB3 model with its ``VecNormalize`` observation statistics: deterministic
    actions, all landers in one batched forward pass of the observations.

    Parameters
    ----------
    model : BaseAlgorithm
        A feed-forward model (PPO, SAC, TD3, a clone) or a recurrent one (sb3-contrib's
        ``RecurrentPPO``: its LSTM state is kept per row, see the module docstring).
    vecnormalize : VecNormalize or str or Path or None
        Statistics (or the ``.pkl`` written by ``VecNormalize.save``); ``None`` if the model was
        trained without normalisation.
    name : str
    obs_features : list of str, optional
        Derived observation features the model was trained with (:mod:`agents.features`,
        the run's ``obs_features``); computed from the observation and the flight computer's
        nominal constants and appended before normalisation, as in training.
    history : int, optional
        The run's ``history``: the model's input is the last ``history`` inputs (observation
        and features) and actions (:mod:`agents.features.history`), stacked before
        normalisation, as in training.

    Raises
    ------
    ValueError
        ``history`` is not an integer from 1 to :data:`agents.features.history.MAX_HISTORY`;
        at the first decision, the model's input width is not what the observation, the
        features and the history give (a run loaded with other settings than it was trained
        with).
    """

    def __init__(self, model, vecnormalize=None, name: str = "PPO",
                 obs_features: list[str] | None = None, history: int | None = None) -> None:
        self.model = model
        self.name = name
        if isinstance(vecnormalize, str | Path):
            with open(vecnormalize, "rb") as fh:
                vecnormalize = pickle.load(fh)
        self.vecnormalize = vecnormalize
        self.obs_features = validate_features(obs_features)
        self.history = validate_history(history)
        # sb3-contrib's recurrent policies (duck-typed: sb3-contrib is optional)
        self.recurrent = hasattr(getattr(model, "policy", None), "lstm_hidden_state_shape")
        self._feature_consts = None
        self._stack: HistoryStack | None = None
        self._lstm_state: tuple[np.ndarray, np.ndarray] | None = None
        self._last_action: np.ndarray | None = None
        #: the model's inputs (N, n_in) at the last decision, before normalisation (the
        #: observation, the features and, with a history, the stacked row)
        self.last_inputs: np.ndarray | None = None

    @classmethod
    def from_path(cls, path: str | Path, name: str | None = None) -> SB3Law:
        """Load from a run directory or model ``.zip`` (:func:`agents.common.runs.load_trained`),
        with the run's ``obs_features`` and ``history`` (its ``config.yml``)."""
        from agents.common.runs import load_trained, read_run

        model, vn_path, algo = load_trained(path)
        hp = read_run(path)[1]
        return cls(model, vn_path, name=name or algo.upper(), obs_features=hp.get("obs_features"),
                   history=hp.get("history"))

    def reset(self, computer: FlightComputer, case_ids: np.ndarray) -> None:
        super().reset(computer, case_ids)
        self._feature_consts = feature_constants(computer) if self.obs_features else None
        # memory is built at the first decision, when the rows' input width is known
        self._stack = None
        self._lstm_state = None
        self._last_action = None

    def act(self, nav: Navigation) -> np.ndarray:
        obs = nav.obs
        if self.obs_features:
            obs = augment_observation(obs, self._feature_consts, self.obs_features)
        first = self._last_action is None
        start = np.ones(nav.n, dtype=bool) if first else np.asarray(nav.episode_start, bool)
        if self.history is not None:
            obs = self._stacked(np.asarray(obs, dtype=np.float32), start, first)
        if first:
            self._check_width(obs)
        self.last_inputs = np.asarray(obs, dtype=np.float32)
        if self.vecnormalize is not None:
            obs = self.vecnormalize.normalize_obs(obs)
        if self.recurrent:
            action, self._lstm_state = self.model.predict(
                obs, state=self._lstm_state, episode_start=start, deterministic=True)
        else:
            action, _ = self.model.predict(obs, deterministic=True)
        self._last_action = np.asarray(action, dtype=np.float32).reshape(nav.n, -1)
        return action

    def flown(self, nav: Navigation, actions: np.ndarray) -> None:
        """Another policy flew ``actions`` (N, n_act) at the decision of ``nav`` (this law is
        a DAgger student while its teacher flies): a history records those actions, the ones
        that led to the next input, as it records its own when it flies. (A recurrent policy's
        memory reads the observations only; it needs nothing.)"""
        if self._last_action is not None:
            self._last_action = np.asarray(actions, dtype=np.float32).reshape(
                self._last_action.shape)

    def _stacked(self, obs: np.ndarray, start: np.ndarray, first: bool) -> np.ndarray:
        """This decision's stacked inputs: the rows that start an episode begin a history at
        ``obs``, the others advance theirs by the law's previous action."""
        if first:
            n_act = int(np.prod(self.computer.action_space.shape))
            self._stack = HistoryStack(len(obs), self.history, obs.shape[1], n_act)
            self._stack.start(obs)
            return self._stack.stacked()
        if start.all():
            self._stack.start(obs)
        elif start.any():
            self._stack.push(obs, self._last_action, rows=~start)
            self._stack.start(obs, rows=start)
        else:
            self._stack.push(obs, self._last_action)
        return self._stack.stacked()

    def _check_width(self, inputs: np.ndarray) -> None:
        space = getattr(self.model, "observation_space", None)
        shape = getattr(space, "shape", None)
        if shape and int(np.prod(shape)) != inputs.shape[1]:
            raise ValueError(
                f"{self.name}: the model takes {int(np.prod(shape))} inputs, the observation "
                f"with obs_features={self.obs_features} and history={self.history} gives "
                f"{inputs.shape[1]}; load the run with the settings it was trained with (its "
                "config.yml)")


def law_from_spec(spec, context) -> GuidanceLaw:
    """Factory of the law specs ``NAME:RUN[:min_time_slack=M]``, NAME one of ``ppo``, ``sac``,
    ``td3``, ``recurrent-ppo``, ``bc``, ``dagger`` (the package's ``lunar_env.laws`` entry
    points; :mod:`guidance.registry`): the run directory or model ``.zip`` ``RUN`` (memory and
    inputs as the run was trained: :meth:`SB3Law.from_path`), labelled ``NAME:run-name``.

    ``min_time_slack=M`` (``LunarPinpointLanding-v3``, m ∈ (0, 50000]): landers whose natural
    stop lies less than ``M`` short of the site at the first measured decision fly the
    minimum-time law instead, as the explicit laws' option of that name does
    (:class:`~guidance.laws.min_time_touchdown.MinimumTimeHandover`)."""
    from guidance.laws.min_time_touchdown import spec_slack, with_handover

    spec.require_known_options(("min_time_slack",))
    if not spec.argument:
        raise ValueError(f"law {spec.text!r} needs a run: {spec.name}:RUN (a run directory or "
                         "a model .zip)")
    slack = spec_slack(spec)  # before the run is loaded
    path = Path(spec.argument)
    if not path.exists():
        raise ValueError(f"law {spec.text!r}: run {spec.argument!r} does not exist")
    return with_handover(SB3Law.from_path(path, name=spec.label()), slack, spec, context)


def run_env_kwargs(spec) -> dict | None:
    """The env arguments the run of a spec was trained with (its ``config.yml``; the
    uncertainty set left out: a campaign flies its own), or None for a spec without an
    existing run."""
    from agents.common.runs import read_run, run_dir_of

    if spec.argument is None or not Path(spec.argument).exists():
        return None
    hp = read_run(run_dir_of(spec.argument))[1]
    return {k: v for k, v in (hp.get("env_kwargs") or {}).items() if k != "uncertainty"}


def run_identity(spec) -> dict:
    """What the flights of a learned law depend on besides its spec: the SHA-256 of the model
    file and of its observation statistics (the files :func:`agents.common.runs.load_trained`
    reads; a run retrained in place, or its newest checkpoint replaced, is another law) and
    the observation features and history it was trained with. Empty for a spec without an
    existing run."""
    import hashlib

    from agents.common.runs import read_run, trained_files

    if spec.argument is None or not Path(spec.argument).exists():
        return {}

    def sha256(path):
        if path is None:
            return None
        h = hashlib.sha256()
        with open(path, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
        return h.hexdigest()

    model, stats = trained_files(spec.argument, log=lambda msg: None)
    hp = read_run(spec.argument)[1]
    ident = {"model_sha256": sha256(model), "vecnormalize_sha256": sha256(stats),
             "obs_features": list(hp.get("obs_features") or [])}
    if hp.get("history") is not None:  # absent for runs without one: their identity unchanged
        ident["history"] = int(hp["history"])
    return ident


law_from_spec.env_kwargs = run_env_kwargs
law_from_spec.identity = run_identity
