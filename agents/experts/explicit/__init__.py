"""Explicit (closed-form) guidance: Apollo, ZEM/ZEV (one augmented-Apollo law with a gain) and
gravity turn, for both env families (issue 30).

- :mod:`.guidance`: the laws as pure batched functions (and the t_go root find);
- :mod:`.frames`: the local-vertical guidance frames of the two envs;
- :mod:`.laws`: the guidance-law classes (:class:`agents.common.law.GuidanceLaw`);
- :mod:`.specs`: the ``--laws`` factories (``apollo``, ``zem-zev``, ``gravity-turn``);
- :mod:`.tune`: the Optuna search of the gain and the t_go margin.
"""
