"""Shared settings. Tests run from a fresh clone; numba kernels compile on first use (cached).

The default run uses two pytest-xdist workers (``addopts`` in pyproject.toml, ``--dist worksteal``).
On 2 cores each worker keeps one BLAS/OpenMP thread (torch, numpy), unless the caller set them:
two workers of two threads each on two cores only contend. A kernel that both workers compile
first writes its index and data files through a unique temporary name and ``os.replace``
(numba.core.caching), so a race costs one extra compile, never a damaged cache file; but from a
fresh clone that extra compile is most of the RK4 kernels, so a whole-suite run fills the cache
once before the workers start (:func:`pytest_sessionstart`, ``numba_warmup.py``).

This directory is on ``sys.path`` (pytest's default rootdir-conftest import): helpers shared by
several test files live in ``proc_helpers.py``.
"""

import os

if os.environ.get("PYTEST_XDIST_WORKER"):
    for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ.setdefault(_var, "1")

import matplotlib  # noqa: E402
import pytest  # noqa: E402

matplotlib.use("Agg")
os.environ.setdefault("MPLBACKEND", "Agg")

_WARMUP_WALL = pytest.StashKey[float]()


@pytest.hookimpl(tryfirst=True)  # before xdist starts the workers and the header is written
def pytest_sessionstart(session):
    """Whole-suite run with xdist workers: fill numba's on-disk cache once, before the workers
    start, in two processes compiling disjoint halves of the kernels (``numba_warmup.py``), so
    the workers load the kernels instead of both compiling most of them. Runs in the
    controller only (a worker has ``workerinput``) and only when the paths come from
    ``testpaths`` (a run of a few files compiles only what its tests need);
    ``LUNAR_TESTS_NUMBA_WARMUP=0`` turns it off, ``=1`` forces it for any paths."""
    config = session.config
    forced = os.environ.get("LUNAR_TESTS_NUMBA_WARMUP")
    if forced == "0" or hasattr(config, "workerinput"):
        return
    if not (getattr(config.option, "numprocesses", None) or 0) >= 2:
        return
    if forced != "1" and config.args_source != config.ArgsSource.TESTPATHS:
        return
    from numba_warmup import warm_in_parallel

    config.stash[_WARMUP_WALL] = warm_in_parallel(config.rootpath)


def pytest_report_header(config):
    wall = config.stash.get(_WARMUP_WALL, None)
    return None if wall is None else f"numba cache warm-up: {wall:.1f} s"
