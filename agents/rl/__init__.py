"""Reinforcement learning: the SB3 training core, callbacks, wrappers (shaping, curriculum),
checkpoint selection, the seed race and the hyperparameter search.
"""
