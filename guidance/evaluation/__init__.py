"""Evaluations: laws over the same seeded initial states against the per-case optimum
(:mod:`.compare`), their reports and the normalised score."""
