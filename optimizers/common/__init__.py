"""Pieces shared by every optimiser: the Problem interface and the result object."""
