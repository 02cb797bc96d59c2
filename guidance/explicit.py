"""Explicit (closed-form) powered-descent guidance: pure batched functions.

Every function here is a pure function of NumPy arrays, batched along axis 0 (like
:mod:`lunar_env.dynamics`): positions, velocities and accelerations have shape (N, d) with d
the number of axes of the guidance frame (2 planar, 3 in 3D), times-to-go shape (N,). Units are
any consistent set (the laws of :mod:`guidance.laws.apollo` use SI: m, m/s, m/s², s).
Nothing here knows an env; the frames live in :mod:`guidance.frames`.

The laws, derived from the sources
----------------------------------

*Apollo lunar-descent guidance* ([K74] Klumpp, "Apollo lunar descent guidance", Automatica 10,
1974). The commanded acceleration is the first value of the quadratic-in-time acceleration
profile a(t) = a₀ + a₁t + a₂t² (t from now, 0 ≤ t ≤ t_go) that reaches the target position
r_T, velocity v_T and acceleration a_T at t = t_go. Integrating twice,

    r_T = r + v t_go + a₀ t_go²/2 + a₁ t_go³/6 + a₂ t_go⁴/12
    v_T = v + a₀ t_go + a₁ t_go²/2 + a₂ t_go³/3
    a_T = a₀ + a₁ t_go + a₂ t_go²

and solving the three linear equations for a₀ (done symbolically in the tests) gives

    a_cmd = a₀ = a_T − 6 (v_T + v)/t_go + 12 (r_T − r)/t_go²                           (K)

which is [K74]'s published form ``12(R_T − R)/T² + 6(V_T + V)/T + A_T`` with its
target-referenced time T = −t_go < 0. This is the *total* acceleration; the thrust
acceleration is a_cmd − g (g: the known, non-thrust acceleration, constant over t_go).

*ZEM/ZEV feedback guidance* ([GHW] Guo, Hawkins & Wie, "Optimal feedback guidance algorithms
for planetary landing and asteroid intercept", AAS 11-588, 2011; JGCD 36(4), 2013). The
energy-optimal thrust acceleration in uniform gravity with fixed t_go is

    a_thrust = 6 ZEM/t_go² − 2 ZEV/t_go,                                                 (Z)
    ZEM = r_T − (r + v t_go + ½ g t_go²),   ZEV = v_T − (v + g t_go).

*Augmented Apollo guidance* ([L18] Lu, "Augmented Apollo powered descent guidance", JGCD 42(3),
2019): one gain k_r spans both. Writing (K) with r_T − r = ZEM + v t_go + ½ g t_go² and
v_T = ZEV + v + g t_go gives a_thrust = 12 ZEM/t_go² − 6 ZEV/t_go + a_T − g; the family

    a_thrust = k_r ZEM/t_go² − (2k_r/3 − 2) ZEV/t_go + (k_r/6 − 1)(a_T − g)              (A)
             = (k_r/t_go²)(r_T − r − v t_go) + (2/t_go)(1 − k_r/3)(v_T − v)
               + (k_r/6 − 1) a_T − g

is (K) at k_r = 12 and (Z) at k_r = 6 (tested). (Derived here as the one-gain family through
(K) and (Z); the two end points are what the tests pin, the form in between was not checked
against [L18]'s text.) In closed loop with g uniform and t_go
counting down exactly, the position error goes as c₁ t_go³ + c₂ t_go^(k_r/3)
(Euler–Cauchy equation of (A)), so the command stays bounded to touchdown only for k_r ≥ 6:
:data:`K_R_MIN`. Larger gains hold the trajectory to a steeper final approach; [L18] uses
6 < k_r ≤ 12 and we allow up to :data:`K_R_MAX`.

*Gravity turn*: thrust opposite the surface-relative velocity.

Time to go
----------
For a constant-thrust engine that can only be steered, :func:`thrust_matched_tgo` chooses a
t_go at which the magnitude of (A)'s thrust acceleration equals the available T/m (a bracketed
root find, batched), so that the command is flyable exactly at full thrust. There are usually
two such roots, a hurried one and a braking one (see its docstring). :func:`rocket_tgo`
instead takes the burn time in which the rocket equation gains |ZEV|, which accounts for T/m
growing as propellant burns.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

__all__ = ["K_R_APOLLO", "K_R_ZEM_ZEV", "K_R_MIN", "K_R_MAX", "zem_zev",
           "augmented_apollo_thrust", "apollo_published_accel", "zem_zev_thrust",
           "free_position_thrust", "gravity_turn_direction", "first_crossing",
           "thrust_matched_tgo", "rocket_tgo",
           "check_gain", "check_state"]

#: [K74]'s gain (Apollo lunar-descent guidance)
K_R_APOLLO = 12.0
#: the gain at which (A) is [GHW]'s ZEM/ZEV law
K_R_ZEM_ZEV = 6.0
#: below this gain the closed-loop command grows without bound as t_go → 0 (module docstring)
K_R_MIN = 6.0
#: the largest gain accepted (twice Apollo's: the start of the trajectory then asks for
#: ever larger corrections that saturate a constant-thrust engine)
K_R_MAX = 24.0


def check_gain(k_r) -> float:
    """``k_r`` as a float; ``ValueError`` naming it unless finite and in [K_R_MIN, K_R_MAX]."""
    if isinstance(k_r, (bool, np.bool_)) or not isinstance(k_r, (numbers.Real, np.floating,
                                                                 np.integer)):
        raise ValueError(f"k_r = {k_r!r} is not a number; it must be in "
                         f"[{K_R_MIN:g}, {K_R_MAX:g}]")
    k = float(k_r)
    if not (math.isfinite(k) and K_R_MIN <= k <= K_R_MAX):
        raise ValueError(f"k_r = {k_r!r} is not allowed; it must be in [{K_R_MIN:g}, "
                         f"{K_R_MAX:g}] (12: Apollo, 6: ZEM/ZEV; below 6 the command "
                         "diverges as t_go -> 0)")
    return k


def check_state(name: str, x: np.ndarray) -> np.ndarray:
    """``x`` as a float64 array; ``ValueError`` naming ``name`` and the bad rows if any entry
    is not finite (a NaN state never becomes a NaN command)."""
    a = np.asarray(x, dtype=np.float64)
    bad = ~np.isfinite(a)
    if bad.any():
        rows = np.unique(np.nonzero(bad.reshape(len(a), -1) if a.ndim else bad)[0])[:5]
        raise ValueError(f"{name} has non-finite entries (rows {rows.tolist()}); the guidance "
                         "law needs a finite navigated state")
    return a


def _check_tgo(t_go: np.ndarray) -> np.ndarray:
    t = np.asarray(t_go, dtype=np.float64)
    if not np.all(np.isfinite(t)) or np.any(t <= 0.0):
        bad = t[~(np.isfinite(t) & (t > 0.0))]
        raise ValueError(f"t_go = {bad[:5].tolist()} (s) is not allowed; the time to go must "
                         "be finite and > 0")
    return t


def zem_zev(r, v, r_t, v_t, g, t_go) -> tuple[np.ndarray, np.ndarray]:
    """Zero-effort miss and velocity ([GHW]): where the lander would be, and how fast, at t_go
    with no thrust in uniform known acceleration ``g``.

    Parameters
    ----------
    r, v, r_t, v_t, g : ndarray, shape (N, d)
        Position, velocity, target position, target velocity, known acceleration.
    t_go : ndarray, shape (N,) or scalar
        Time to go (> 0).

    Returns
    -------
    zem, zev : ndarray, shape (N, d)
    """
    t = _check_tgo(t_go)[..., None]
    zem = r_t - (r + v * t + 0.5 * g * t * t)
    zev = v_t - (v + g * t)
    return zem, zev


def augmented_apollo_thrust(r, v, r_t, v_t, a_t, g, t_go, k_r, check: bool = True
                            ) -> np.ndarray:
    """Thrust acceleration of the augmented Apollo law (A) ([L18]; module docstring).

    Parameters
    ----------
    r, v : ndarray, shape (N, d)
        Navigated position and velocity in the guidance frame.
    r_t, v_t, a_t : ndarray, shape (N, d) or (d,)
        Target position, velocity and *total* acceleration at t_go (a_t enters only for
        k_r ≠ 6).
    g : ndarray, shape (N, d) or (d,)
        Known non-thrust acceleration, taken as constant over t_go.
    t_go : ndarray, shape (N,) or scalar
        Time to go (s), > 0.
    k_r : float
        Gain in [K_R_MIN, K_R_MAX]: 12 is Apollo ([K74]), 6 ZEM/ZEV ([GHW]).
    check : bool
        Validate k_r and t_go (default). A caller that validated them once (the t_go root
        find evaluates the law ~100 times a decision) passes False.

    Returns
    -------
    ndarray, shape (N, d)
        Commanded thrust acceleration (no limit applied).

    Raises
    ------
    ValueError
        t_go ≤ 0 or not finite, k_r out of range.
    """
    if check:
        k = check_gain(k_r)
        t = _check_tgo(t_go)
    else:
        k, t = k_r, t_go
    tc = t[..., None]
    zem = r_t - (r + v * tc + 0.5 * g * tc * tc)
    zev = v_t - (v + g * tc)
    return k * zem / (tc * tc) - (2.0 * k / 3.0 - 2.0) * zev / tc + (k / 6.0 - 1.0) * (a_t - g)


def apollo_published_accel(r, v, r_t, v_t, a_t, t_go) -> np.ndarray:
    """[K74]'s published total acceleration (K), a_T − 6(v_T + v)/t_go + 12(r_T − r)/t_go²
    (shapes as :func:`augmented_apollo_thrust`); subtract g for the thrust acceleration."""
    tc = _check_tgo(t_go)[..., None]
    return a_t - 6.0 * (v_t + v) / tc + 12.0 * (r_t - r) / (tc * tc)


def zem_zev_thrust(r, v, r_t, v_t, g, t_go) -> np.ndarray:
    """[GHW]'s thrust acceleration (Z), 6 ZEM/t_go² − 2 ZEV/t_go."""
    zem, zev = zem_zev(r, v, r_t, v_t, g, t_go)
    tc = np.asarray(t_go, dtype=np.float64)[..., None]
    return 6.0 * zem / (tc * tc) - 2.0 * zev / tc


def free_position_thrust(v, v_t, g, t_go, check: bool = True) -> np.ndarray:
    """Energy-optimal thrust acceleration on axes whose final *position* is free: the position
    costate vanishes (transversality), the optimal control is constant, ZEV/t_go.

    Used for the planar env's downrange axis (its task has no landing site). Shapes: ``v``,
    ``v_t``, ``g`` (N, d) or broadcastable, ``t_go`` (N,).
    """
    tc = (_check_tgo(t_go) if check else t_go)[..., None]
    return (v_t - v - g * tc) / tc


def gravity_turn_direction(v) -> np.ndarray:
    """Unit thrust directions opposite the surface-relative velocity ``v`` (N, d); straight up
    (the last axis) where the lander is at rest."""
    v = np.asarray(v, dtype=np.float64)
    speed = np.linalg.norm(v, axis=-1, keepdims=True)
    up = np.zeros_like(v)
    up[..., -1] = 1.0
    return np.where(speed > 1e-9, -v / np.maximum(speed, 1e-300), up)


def first_crossing(residual, tgo_min, tgo_max, n: int, n_grid: int = 48,
                   n_bisect: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """Smallest t ∈ [tgo_min, tgo_max] with ``residual(t) <= 0``, per row (bracketed, batched).

    ``residual(t (k,), rows) -> (k,)`` is positive while t is too short (for the rows
    ``rows``: an index array, or ``slice(None)`` for all ``n``). A geometric grid of
    ``n_grid`` points brackets the first sign change, ``n_bisect`` batched bisections refine it.

    Returns
    -------
    t : ndarray, shape (n,)
        The crossing; ``tgo_min`` where the residual is already ≤ 0 there, and the grid point
        of the smallest residual where it never crosses.
    found : ndarray, shape (n,), bool
        A bracketed crossing was found.
    """
    if not (0.0 < tgo_min < tgo_max and math.isfinite(tgo_max)):
        raise ValueError(f"t_go search interval [{tgo_min!r}, {tgo_max!r}] s is not allowed; "
                         "it needs 0 < tgo_min < tgo_max < inf")
    grid = np.geomspace(tgo_min, tgo_max, n_grid)
    res = residual(np.repeat(grid, n), np.tile(np.arange(n), n_grid)).reshape(n_grid, n)
    ok = res <= 0.0
    has = ok.any(axis=0)
    first = np.where(has, np.argmax(ok, axis=0), np.argmin(res, axis=0))
    t = grid[first].copy()
    found = has & (first > 0)
    idx = np.nonzero(found)[0]
    if idx.size:
        lo = grid[first[idx] - 1]
        hi = grid[first[idx]]
        for _ in range(n_bisect):
            mid = 0.5 * (lo + hi)
            over = residual(mid, idx) > 0.0
            lo = np.where(over, mid, lo)
            hi = np.where(over, hi, mid)
        t[idx] = hi
    return t, found


def thrust_matched_tgo(command, accel_avail, tgo_min, tgo_max, branch: str = "long",
                       n_grid: int = 48, n_bisect: int = 26) -> tuple[np.ndarray, np.ndarray]:
    """t_go ∈ [tgo_min, tgo_max] at which |command(t_go)| = accel_avail, per row.

    ``command(t_go (k,), rows) -> (k, d)`` is the law's thrust acceleration as a function of
    t_go (all other arguments fixed) for the rows ``rows`` (index array or ``slice(None)``).
    Seen as a function of t_go, |command| is large for short t_go (the target must be reached
    in a hurry), has a minimum at the law's "natural" time (the least effort), and grows again
    for longer t_go (the lander must brake harder to arrive later) before it tends to |g|. So
    the thrust level is usually met twice:

    - ``branch="short"``: the first root, below the least-effort time: a hurried profile that
      keeps or adds speed first (for a fast lander far from its site: thrust *forward*);
    - ``branch="long"``: the first root above the least-effort time: the braking profile
      (the one a steer-only lander braking from orbit can fly).

    Both are bracketed on a geometric grid of ``n_grid`` points and refined by ``n_bisect``
    batched bisections.

    Parameters
    ----------
    command : callable
    accel_avail : ndarray, shape (N,)
        Available thrust acceleration T/m (same units as the command).
    tgo_min, tgo_max : float
        Search interval (s), 0 < tgo_min < tgo_max.
    branch : {"long", "short"}

    Returns
    -------
    t_go : ndarray, shape (N,)
        The root; on the long branch where |command| never climbs back to T/m, the short
        root; where the least effort already exceeds T/m, the least-effort t_go (best effort
        at full thrust).
    found : ndarray, shape (N,), bool
        A bracketed root was found.
    """
    if branch not in ("long", "short"):
        raise ValueError(f"branch = {branch!r} is not allowed; use 'long' or 'short'")
    if not (0.0 < tgo_min < tgo_max and math.isfinite(tgo_max)):
        raise ValueError(f"t_go search interval [{tgo_min!r}, {tgo_max!r}] s is not allowed; "
                         "it needs 0 < tgo_min < tgo_max < inf")
    acc = np.asarray(accel_avail, dtype=np.float64)
    n = len(acc)
    grid = np.geomspace(tgo_min, tgo_max, n_grid)
    # the whole grid in one call of the law (rows repeated): ~50 small NumPy calls cost more
    # than the arithmetic
    mags = np.linalg.norm(command(np.repeat(grid, n), np.tile(np.arange(n), n_grid)),
                          axis=1).reshape(n_grid, n)
    jmin = np.argmin(mags, axis=0)
    cols = np.arange(n)
    reach = mags[jmin, cols] <= acc
    j = np.arange(n_grid)[:, None]
    short = mags <= acc[None, :]
    long_ = (mags >= acc[None, :]) & (j > jmin[None, :])
    has_long = long_.any(axis=0) & reach if branch == "long" else np.zeros(n, dtype=bool)
    # the long branch where it exists; else the short root (on the long branch a lander
    # that cannot spend its thrust braking any later has too much thrust: it must hurry)
    use_long = has_long
    has = np.where(use_long, has_long, short.any(axis=0) & reach)
    first = np.where(use_long, np.argmax(long_, axis=0), np.argmax(short, axis=0))
    first = np.where(has, first, jmin)
    # residual > 0 while t_go is below the root: |a| - A on the short branch, A - |a| on the
    # long one
    sign = np.where(use_long, -1.0, 1.0)
    t_go = grid[first].copy()
    found = has & (first > 0)
    idx = np.nonzero(found)[0]
    if idx.size:
        lo, hi = grid[first[idx] - 1], grid[first[idx]]
        sub_acc, sub_sign = acc[idx], sign[idx]
        for _ in range(n_bisect):
            mid = 0.5 * (lo + hi)
            res = sub_sign * (np.linalg.norm(command(mid, idx), axis=1) - sub_acc)
            lo = np.where(res > 0.0, mid, lo)
            hi = np.where(res > 0.0, hi, mid)
        t_go[idx] = hi
    return t_go, found


def rocket_tgo(zev_of, accel_avail, exhaust_velocity, burnout_s, tgo_min, tgo_max
               ) -> tuple[np.ndarray, np.ndarray]:
    """t_go of a constant-thrust burn that gains the velocity to be gained: the smallest t with
    c·ln(m/(m − ṁt)) ≥ |ZEV(t)| (the rocket equation, as E-guidance and PEG estimate the burn
    time; it accounts for T/m growing as propellant burns, which a fixed-magnitude match does
    not).

    Parameters
    ----------
    zev_of : callable
        ``zev_of(t (k,), rows) -> (k, d)``: the zero-effort velocity error at time to go t.
    accel_avail : ndarray, shape (N,)
        T/m now (m/s²).
    exhaust_velocity : float
        c = Isp·g0 (m/s).
    burnout_s : ndarray, shape (N,)
        Time to propellant exhaustion at full thrust (s); no velocity is gained after it.
    tgo_min, tgo_max : float

    Returns
    -------
    t_go, found : ndarray, shape (N,)
    """
    acc = np.asarray(accel_avail, dtype=np.float64)
    c = float(exhaust_velocity)
    burn = np.asarray(burnout_s, dtype=np.float64)

    def residual(t, rows):
        # ṁ t / m = (T/m) t / c, capped at burnout
        frac = np.minimum(acc[rows] * np.minimum(t, burn[rows]) / c, 1.0 - 1e-12)
        return np.linalg.norm(zev_of(t, rows), axis=1) + c * np.log1p(-frac)

    return first_crossing(residual, tgo_min, tgo_max, len(acc))
