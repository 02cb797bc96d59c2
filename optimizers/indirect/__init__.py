"""Indirect (Pontryagin) solvers: the certifiers every paper measures itself against.

- :mod:`.planar`: planar minimum fuel at constant thrust (landing and heliocentric transfer);
- :mod:`.pinpoint`: the 3D pinpoint landing of [001].
"""
