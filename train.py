"""Train an SB3 policy on a lunar-descent env and compare it with the optimal trajectories.

``python train.py`` trains PPO on ``LunarSoftLanding-v0`` with the shipped configuration and
prints the comparison table; ``python train.py --help`` lists the options (see agents/train.py).
"""

from agents.train import main

if __name__ == "__main__":
    raise SystemExit(main())
