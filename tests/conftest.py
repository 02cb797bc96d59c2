"""Shared fixtures. Tests run from a fresh clone; numba kernels compile on first use (cached)."""

import os

import matplotlib

matplotlib.use("Agg")
os.environ.setdefault("MPLBACKEND", "Agg")
