"""Evaluation: every guidance law over the same cases against the per-case optimum; reports and the
reward ranking.
"""
