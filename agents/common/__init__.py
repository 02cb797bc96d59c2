"""Shared pieces of the agents rooms: run directories, the SB3 vec-env adapter, the actor half
of a policy."""
