"""The env families and their experts: one module per family (planar soft landing, 3D pinpoint).
"""
