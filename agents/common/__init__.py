"""Shared pieces of the agents rooms: run directories, the rollout loop, the SB3 vec-env adapter,
observation features, the env-family registry and the guidance-law contract.
"""
