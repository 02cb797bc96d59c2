"""agents: SB3 training, imitation from optimiser trajectories, evaluation and comparison."""
