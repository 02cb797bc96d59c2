"""Imitation of the optimiser: behaviour cloning (BC) and DAgger into an SB3 PPO policy.

::

    lunar dataset --n 1000                                   # optimal landings
    python -m agents.imitation bc --dataset data/imitation/LunarSoftLanding-v0_n1000_seed0.npz
    python -m agents.imitation dagger --dataset <same> \\
        --init runs/imitation/bc_LunarSoftLanding-v0_1
    python -m agents.imitation bc --quick --dataset small.npz           # CI-sized
    python -m agents.imitation bc --resume runs/imitation/bc_LunarSoftLanding-v0_1
    python train.py --init-from runs/imitation/bc_LunarSoftLanding-v0_1  # PPO fine-tuned from BC
    python -m agents.imitation evaluate --model BC=runs/imitation/bc_... \\
        --model DAgger=runs/imitation/dagger_... --model PPO=runs/ppo/... --n-states 1000

The ``imitation`` library pins gymnasium 0.29 / SB3 2.2, so both algorithms are written here on
SB3's ``ActorCriticPolicy`` and torch:

- **BC** ([Pomerleau 1991]; as in ``imitation.algorithms.bc``): the policy's Gaussian *mean*
  action is regressed on the dataset's optimal actions (mean-squared error; decision: the
  evaluation flies the deterministic mean, and MSE on it is what matters; ``log_std`` keeps its
  initial value so PPO starts exploring from ``log_std_init``). Only the actor (``mlp_extractor``
  policy branch + ``action_net``) is trained; the value branch is left for PPO.
- **DAgger** ([Ross, Gordon & Bagnell 2011]): iteration i rolls out the current policy
  (β = 0: the first "expert" iteration is the BC dataset itself) in the native vector env,
  labels visited states with the closed-loop expert :class:`agents.experts.planar.
  PontryaginExpert` (re-solves the optimal problem from the state), aggregates, and retrains
  the policy (warm-started) on the union, each minibatch mixing ``dagger_fraction`` DAgger
  labels with optimal-trajectory samples (``dagger_fraction: null``: all data pooled and drawn
  alike, as the pinpoint entry does). Labels: the thrust angle of the expert's new plan at
  the middle of the env step (the dataset's label rule); where the expert holds, falls back or
  plans with the ground constraint, the angle it returns.

Output: a run directory ``runs/imitation/<bc|dagger>_<env id>_<k>/`` in the layout of
:mod:`agents.train` — ``config.yml``, ``args.yml`` (``algo: ppo``), ``command.txt``, ``tb/``
(TensorBoard), ``checkpoints/``, and ``model.zip``, a Stable-Baselines3 **PPO** model whose
policy holds the cloned weights (``PPO.load`` works; ``agents.evaluate --model`` and
``train.py --init-from`` accept the directory). Hyperparameters: ``agents/hyperparams/
imitation.yml`` keyed by env id. ``--resume RUN_DIR`` continues from the newest checkpoint
(BC: epoch; DAgger: iteration, whose labels are kept on disk and not recomputed).
"""
