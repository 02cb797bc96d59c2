"""Shared settings. Tests run from a fresh clone; numba kernels compile on first use (cached).

The default run uses two pytest-xdist workers (``addopts`` in pyproject.toml, ``--dist worksteal``).
On 2 cores each worker keeps one BLAS/OpenMP thread (torch, numpy), unless the caller set them:
two workers of two threads each on two cores only contend. Numba's on-disk cache needs no
warm-up: a kernel that both workers compile first writes its index and data files through a
unique temporary name and ``os.replace`` (numba.core.caching), so a race costs one extra compile,
never a damaged cache file.

This directory is on ``sys.path`` (pytest's default rootdir-conftest import): helpers shared by
several test files live in ``proc_helpers.py``.
"""

import os

if os.environ.get("PYTEST_XDIST_WORKER"):
    for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ.setdefault(_var, "1")

import matplotlib  # noqa: E402

matplotlib.use("Agg")
os.environ.setdefault("MPLBACKEND", "Agg")
