"""Recurrent PPO (sb3-contrib's ``RecurrentPPO``, an LSTM policy) for ``--algo recurrent-ppo``.

sb3-contrib is an optional dependency (the ``memory`` extra): this module imports it when it is
itself imported, and raises Gymnasium's ``DependencyNotInstalled`` naming the extra when it is
missing. Nothing else in the package imports it at module level, so every other algorithm works
without it.

:class:`SequenceLstmPolicy` is sb3-contrib's ``MlpLstmPolicy`` (same modules, parameters and
saved state) with a faster evaluation of training sequences: sb3-contrib steps the LSTM one
time step at a time, in Python, whenever a minibatch sequence holds an episode start. Its
recurrent rollout buffer cuts the sequences *at* every episode start, so a start can only be a
sequence's first step; resetting the initial state of those sequences and running the LSTM
over the whole padded sequence in one call computes the same outputs (to float32 rounding)
without the Python loop. Sequences with a start anywhere else (none come from the buffer) take
sb3-contrib's loop. :class:`RecurrentPPO` is sb3-contrib's ``RecurrentPPO`` with
``MlpLstmPolicy`` resolved to that class; models it saves load with sb3-contrib's own
``RecurrentPPO.load`` too (the policy class is stored by reference).
"""

from __future__ import annotations

from typing import Any, ClassVar

try:
    import sb3_contrib
    from sb3_contrib.common.recurrent.policies import RecurrentActorCriticPolicy
except ImportError as _exc:  # the optional 'memory' extra
    from gymnasium.error import DependencyNotInstalled

    raise DependencyNotInstalled(
        "--algo recurrent-ppo (an LSTM policy) needs sb3-contrib, the 'memory' extra: "
        "pip install -e '.[memory]'") from _exc

import torch as th
from torch import nn

__all__ = ["RecurrentPPO", "SequenceLstmPolicy"]


class SequenceLstmPolicy(RecurrentActorCriticPolicy):
    """sb3-contrib's ``MlpLstmPolicy`` whose sequences starting an episode at their first step
    run through the LSTM in one call (see the module docstring); every argument is
    ``RecurrentActorCriticPolicy``'s (``lstm_hidden_size``, ``n_lstm_layers``,
    ``shared_lstm``, ``enable_critic_lstm``, ``net_arch``, ...)."""

    @staticmethod
    def _process_sequence(features: th.Tensor, lstm_states: tuple[th.Tensor, th.Tensor],
                          episode_starts: th.Tensor, lstm: nn.LSTM
                          ) -> tuple[th.Tensor, tuple[th.Tensor, th.Tensor]]:
        """LSTM outputs (n_seq · length, hidden) and final states of ``n_seq`` sequences.

        ``features`` (n_seq · length, n_in) are the sequences one after the other,
        ``episode_starts`` (n_seq · length,) 1.0 where an episode starts (the state is zeroed
        before that step), ``lstm_states`` the states (n_layers, n_seq, hidden) before each
        sequence's first step.
        """
        n_seq = lstm_states[0].shape[1]
        starts = episode_starts.reshape((n_seq, -1))
        if not th.all(starts[:, 1:] == 0.0):
            # a start inside a sequence: sb3-contrib's step-by-step loop
            return RecurrentActorCriticPolicy._process_sequence(features, lstm_states,
                                                                episode_starts, lstm)
        keep = (1.0 - starts[:, 0]).view(1, n_seq, 1)
        sequence = features.reshape((n_seq, -1, lstm.input_size)).swapaxes(0, 1)
        out, states = lstm(sequence, (keep * lstm_states[0], keep * lstm_states[1]))
        return th.flatten(out.transpose(0, 1), start_dim=0, end_dim=1), states


class RecurrentPPO(sb3_contrib.RecurrentPPO):
    """sb3-contrib's ``RecurrentPPO`` (PPO with an LSTM policy, trained on sequences of the
    rollout) whose ``"MlpLstmPolicy"`` is :class:`SequenceLstmPolicy`; every argument is
    sb3-contrib's (``n_steps`` · ``n_envs`` is the rollout size, ``batch_size`` the steps of a
    minibatch of sequences)."""

    policy_aliases: ClassVar[dict[str, Any]] = {
        **sb3_contrib.RecurrentPPO.policy_aliases, "MlpLstmPolicy": SequenceLstmPolicy}

