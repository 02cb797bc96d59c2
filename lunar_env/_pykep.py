"""pykep's Lambert solver as a reference, run in a child process (tests and benchmarks only;
the toolkit itself never imports pykep).

Two defects of the pykep 3.0.1 wheel are worked around here:

- it ships without the TOPS benchmark data files that ``pykep.trajopt.gym.__init__`` reads at
  import time, so ``import pykep`` raises FileNotFoundError although its compiled core
  (``lambert_problem`` among it) is intact: an empty ``pykep.trajopt.gym`` module (the only
  part that reads them) is registered before the import;
- once imported, the interpreter aborts at exit ("corrupted double-linked list", status 134),
  which would fail the test run that imported it. So pykep only ever runs in a child process
  (``python -m lunar_env._pykep IN.npz OUT.npz``) that leaves with ``os._exit(0)`` after
  writing its results atomically.

:func:`pykep_lambert` is the entry point: the same problems in, pykep's solutions (in the
layout of :class:`lunar_env.lambert.LambertSolutions`) and its wall time out.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import tempfile
import time
import types

import numpy as np

__all__ = ["pykep_available", "pykep_lambert"]


def pykep_available() -> tuple[bool, str]:
    """(True, version) if pykep can be used as a reference, else (False, the reason)."""
    spec = importlib.util.find_spec("pykep")
    if spec is None:
        return False, "pykep is not installed (`pip install pykep`, in the test extra)"
    return True, "installed"


def _import_pykep():
    spec = importlib.util.find_spec("pykep")
    root = list(spec.submodule_search_locations)[0]
    tops = os.path.join(root, "trajopt", "gym", "tops", "_tops_cr3bp.json")
    if not os.path.exists(tops) and "pykep.trajopt.gym" not in sys.modules:
        sys.modules["pykep.trajopt.gym"] = types.ModuleType(
            "pykep.trajopt.gym", "placeholder: this pykep wheel lacks the TOPS data files")
    import pykep

    return pykep


def pykep_lambert(r1, r2, tof, mu, clockwise, max_revs: int, *, repeat: int = 1,
                  timeout_s: float = 600.0) -> dict:
    """Solve every problem with ``pykep.lambert_problem`` in a child process.

    Parameters
    ----------
    r1, r2 : ndarray, shape (batch, 3)
    tof, mu : ndarray, shape (batch,)
    clockwise : ndarray of bool, shape (batch,)
    max_revs : int
    repeat : int
        Time the loop over all problems this many times; the best wall time is reported.

    Returns
    -------
    dict
        ``v1``, ``v2`` (batch, 2·max_revs + 1, 3) with NaN rows where pykep has no solution,
        ``n_max`` (batch,), ``iterations`` (batch, 2·max_revs + 1), ``wall_s`` (best loop
        time), ``version``.

    Raises
    ------
    ImportError
        pykep is not installed or does not import.
    RuntimeError
        The child failed (its stderr is in the message).
    """
    ok, why = pykep_available()
    if not ok:
        raise ImportError(why)
    with tempfile.TemporaryDirectory() as tmp:
        src, dst = os.path.join(tmp, "in.npz"), os.path.join(tmp, "out.npz")
        np.savez(src, r1=np.asarray(r1, float), r2=np.asarray(r2, float),
                 tof=np.asarray(tof, float), mu=np.asarray(mu, float),
                 cw=np.asarray(clockwise, bool), max_revs=int(max_revs), repeat=int(repeat))
        proc = subprocess.run([sys.executable, "-m", "lunar_env._pykep", src, dst],
                              capture_output=True, text=True, timeout=timeout_s)
        if proc.returncode != 0 or not os.path.exists(dst):
            raise RuntimeError(f"pykep child failed (status {proc.returncode}): "
                               f"{proc.stderr.strip()[-2000:]}")
        with np.load(dst) as d:
            out = {k: d[k] for k in d.files}
    out["wall_s"] = float(out["wall_s"])
    out["version"] = str(out["version"])
    return out


def _child(src: str, dst: str) -> None:
    pk = _import_pykep()
    with np.load(src) as d:
        r1, r2, tof, mu, cw = d["r1"], d["r2"], d["tof"], d["mu"], d["cw"]
        max_revs, repeat = int(d["max_revs"]), int(d["repeat"])
    n = len(tof)
    n_sol = 2 * max_revs + 1
    v1 = np.full((n, n_sol, 3), np.nan)
    v2 = np.full((n, n_sol, 3), np.nan)
    iters = np.zeros((n, n_sol), dtype=np.int64)
    n_max = np.zeros(n, dtype=np.int64)
    r1l, r2l = r1.tolist(), r2.tolist()
    tofl, mul, cwl = tof.tolist(), mu.tolist(), [bool(c) for c in cw]
    lp_cls = pk.lambert_problem
    best = np.inf
    for _ in range(max(1, repeat)):
        # the timed loop reads every solution but keeps none: holding 50 000 result lists
        # would add Python garbage-collection passes to pykep's time
        t0 = time.perf_counter()
        for i in range(n):  # what a Python user writes: one object per problem
            lp = lp_cls(r1l[i], r2l[i], tofl[i], mul[i], cwl[i], max_revs)
            _v0, _v1 = lp.v0, lp.v1
        best = min(best, time.perf_counter() - t0)
    for i in range(n):
        lp = lp_cls(r1l[i], r2l[i], tofl[i], mul[i], cwl[i], max_revs)
        a, b = np.asarray(lp.v0), np.asarray(lp.v1)
        v1[i, :len(a)] = a
        v2[i, :len(b)] = b
        it = lp.iters
        iters[i, :len(it)] = it
        n_max[i] = lp.Nmax
    tmp = dst + ".tmp.npz"
    np.savez(tmp, v1=v1, v2=v2, iterations=iters, n_max=n_max, wall_s=best,
             version=getattr(pk, "__version__", "unknown"))
    os.replace(tmp, dst)


if __name__ == "__main__":
    try:
        _child(sys.argv[1], sys.argv[2])
    except BaseException:  # noqa: BLE001 - report, then leave without pykep's atexit
        import traceback

        traceback.print_exc()
        sys.stderr.flush()
        os._exit(1)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)
