"""Fill numba's on-disk cache once before the xdist workers start.

From a fresh clone every ``@numba.njit(cache=True)`` kernel compiles on first use. With two
workers, each compiles the kernels its tests call, and both call most of them (the RK4 kernels
of both models, serial and parallel, cost ~1 min of CPU in all): the same work done twice.
``tests/conftest.py`` runs :func:`warm_in_parallel` in the xdist controller of a whole-suite
run before the workers start: two processes (one per core) compile disjoint halves of the
kernels into the cache, and the workers then load them (a second or two each).

Only a cost, never a check: whatever this misses compiles in the worker as before, and the
tests check the kernels' results themselves. ``python tests/numba_warmup.py a|b`` warms one half.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

# Each half in one process: a model's serial and parallel kernels share their compiled step
# loop (lunar_env.integrators._instantiate), so a model stays together (no compile done twice).
# Halves balanced by measured compile time from a cold cache: planar ~26 s, moon3d ~28 s (both
# kinds), the envs ~7 s each, lambert ~10 s (its serial and parallel kernels apart), the
# pinpoint expert ~13 s (its own kernels). An env steps in the half that compiles its model.
# Read-only inputs would be other signatures (~10 s each); lunar_env.integrators passes
# writable copies (_kernel_array).
PARTS = {
    "a": (("zhu2007", False), ("zhu2007", True)),
    "b": (("peng2012", False), ("peng2012", True)),
}


def _integrators(name: str, parallel: bool) -> None:
    import numpy as np

    from lunar_env import get_scenario
    from lunar_env import integrators as integ

    sc = get_scenario(name)
    s = sc.scaling()
    model = integ.PLANAR if sc.model == "planar" else integ.MOON3D
    n = 2
    y0 = np.repeat(sc.state_nd()[None], n, axis=0)
    u = np.ones((n, model.n_control))
    t0 = np.zeros(n)
    h = np.full(n, float(s.time_nd(1.0)))
    ctrl = integ.PiecewisePolynomial.constant(u, t0, t0 + 2 * h)
    rows = integ.params_rows(sc.params(s), n)
    dry = float(s.mass_nd(sc.vehicle.dry_mass_kg))
    r_stop = np.full(n, float(s.length_nd(sc.body.radius_m)))
    integ.integrate_prepared(model, y0, t0, h, 2, ctrl.breaks, ctrl.coefs, rows, dry, r_stop,
                             True, parallel)
    out = (np.empty_like(y0), np.empty(n), np.empty(n, dtype=np.int64), np.empty(n))
    integ.integrate_prepared(model, y0, t0, h, 2, ctrl.breaks, ctrl.coefs, rows, dry, r_stop,
                             True, parallel, out=out)


def _envs(env_ids: tuple[str, ...]) -> None:
    import gymnasium as gym
    import numpy as np

    import lunar_env  # noqa: F401

    for env_id in env_ids:
        for uncertainty in ("none", "standard"):
            env = gym.make(env_id, uncertainty=uncertainty)
            env.reset(seed=0)
            for _ in range(2):
                env.step(env.action_space.sample())
            env.close()
        vec = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point")
        vec.reset(seed=0)
        vec.step(np.stack([vec.single_action_space.sample() for _ in range(2)]))
        vec.close()


def _lambert(parallel: bool) -> None:
    import numpy as np

    from lunar_env.lambert import solve_lambert, solve_lambert_flat

    r1 = np.array([[1.0, 0.0, 0.0]] * 2)
    r2 = np.array([[0.0, 1.5, 0.1]] * 2)
    solve_lambert(r1, r2, np.array([20.0, 30.0]), 1.0, max_revs=2, parallel=parallel)
    solve_lambert_flat(r1, r2, np.array([20.0, 30.0]), 1.0, max_revs=2, parallel=parallel)


def _pinpoint_expert() -> None:
    import numpy as np

    from lunar_env import get_scenario
    from optimizers.indirect.pinpoint_feedback import PinpointFeedback

    sc = get_scenario("peng2012")
    PinpointFeedback(sc)(sc.state_nd()[None], np.zeros(1), 1.0)


def warm(part: str) -> None:
    """Compile (or load) one half of the kernels."""
    for name, parallel in PARTS[part]:
        _integrators(name, parallel)
    if part == "a":
        _envs(("LunarSoftLanding-v0",))
        _pinpoint_expert()  # its own kernels, no integrator's
        _lambert(parallel=False)
    else:
        _envs(("LunarPinpointLanding-v2", "LunarPinpointLanding-v3"))
        _lambert(parallel=True)


def warm_in_parallel(root: Path) -> float:
    """Run both halves at once in child processes; returns the wall time (s). A failure is
    reported and ignored: the workers then compile what they need themselves."""
    t = time.perf_counter()
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        p for p in (str(root), env.get("PYTHONPATH")) if p)
    procs = [subprocess.Popen([sys.executable, str(Path(__file__)), part], cwd=root, env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
             for part in PARTS]
    for p in procs:
        out, _ = p.communicate()
        if p.returncode != 0:
            print(f"numba warm-up {p.args[-1]} failed (ignored):\n{out[-2000:]}",
                  file=sys.stderr)
    return time.perf_counter() - t


if __name__ == "__main__":
    warm(sys.argv[1])
