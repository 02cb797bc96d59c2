"""The env families and their experts: one module per family (planar soft landing, 3D pinpoint),
and the laws every family flies (:mod:`.laws`; convex re-planning, :mod:`.convex`).
"""
