"""Model-generic source of the compiled RK4 integrator (see :mod:`lunar_env.integrators`).

These functions are never called directly. :mod:`lunar_env.integrators` instantiates them once
per dynamics model, binding the model's names below to that model's compiled functions, and
compiles them with numba (``cache=True``). The integrator logic therefore exists once, and the
per-model kernels run on scalar tuples (no per-step heap arrays), which is what makes them fast.

Names bound per model: ``LOAD(row) -> state tuple``, ``DERIV(y, u, p) -> dy tuple``,
``PREP(u) -> c`` and ``DERIV_C(y, c, p) -> dy`` (the same right-hand side split into its
control part and its state part, DERIV = DERIV_C ∘ PREP), ``RADIUS(y)``, ``RADIAL_RATE(y)``
(with the sign of dr/dt), ``SPEED_RATE(y, dy)`` (= V_rel · dV_rel/dt, whose upward zero crossing
is a minimum of the speed relative to the surface), ``MASS(y)``, ``UZERO`` (zero control tuple;
the last control channel is the throttle).
"""

# ruff: noqa: F821  (LOAD, DERIV, PREP, DERIV_C, RADIAL_RATE, RADIUS, SPEED_RATE, MASS, UZERO are bound per model)
import numpy as np
from numba import prange
from numba.cpython.unsafe.tuple import tuple_setitem

EVENT_NONE = 0
EVENT_RADIUS = 1
EVENT_SPEED_MIN = 2
EVENT_FUEL = 3
EVENT_RADIUS_MIN = 4  # internal: radial rate crossing zero upward (a minimum of the radius)
_ROOT_ITERATIONS = 80


def control_in(breaks, coefs, i, k, t, burn):
    """Control tuple of trajectory i at time t evaluated on segment k (no segment search).

    An RK4 step evaluates all its stages, including the one at its end point, on the segment
    that contains the step's start: a control held over [t, t + h] (a zero-order hold, an env
    step) is then integrated exactly as held, also when the next segment starts at t + h.
    """
    order = coefs.shape[3]
    tau = t - breaks[i, k]
    u = UZERO
    for j in range(len(u)):
        acc = coefs[i, k, j, order - 1]
        for q in range(order - 2, -1, -1):
            acc = acc * tau + coefs[i, k, j, q]
        u = tuple_setitem(u, j, acc)
    last = len(u) - 1
    u = tuple_setitem(u, last, u[last] * burn)
    return u


def segment_at(breaks, coefs, i, k, t):
    """Segment containing t, searched forward from k; a break within 1e-12 (relative) after t
    counts as reached, so grid points that round just below a break start the new segment."""
    n_seg = coefs.shape[1]
    while k < n_seg - 1 and t >= breaks[i, k + 1] - 1e-12 * (1.0 + abs(t)):
        k += 1
    return k


def rk4_core(y, h, c0, c1, c2, p):
    """One classical RK4 step of length h from y, given the prepared controls (``PREP``) at the
    step's start, middle and end."""
    k1 = DERIV_C(y, c0, p)
    yt = y
    for j in range(len(y)):
        yt = tuple_setitem(yt, j, y[j] + 0.5 * h * k1[j])
    k2 = DERIV_C(yt, c1, p)
    for j in range(len(y)):
        yt = tuple_setitem(yt, j, y[j] + 0.5 * h * k2[j])
    k3 = DERIV_C(yt, c1, p)
    for j in range(len(y)):
        yt = tuple_setitem(yt, j, y[j] + h * k3[j])
    k4 = DERIV_C(yt, c2, p)
    out = y
    h6 = h / 6.0
    for j in range(len(y)):
        out = tuple_setitem(out, j, y[j] + h6 * (k1[j] + 2.0 * (k2[j] + k3[j]) + k4[j]))
    return out


def rk4_step(y, t, h, breaks, coefs, i, k, burn, p):
    """One classical RK4 step of length h from (t, y)."""
    u0 = control_in(breaks, coefs, i, k, t, burn)
    u1 = control_in(breaks, coefs, i, k, t + 0.5 * h, burn)
    u2 = control_in(breaks, coefs, i, k, t + h, burn)
    # the control's trigonometry once per distinct value: a held control costs one sin/cos
    c0 = PREP(u0)
    c1 = c0 if u1 == u0 else PREP(u1)
    c2 = c1 if u2 == u1 else PREP(u2)
    return rk4_core(y, h, c0, c1, c2, p)


def event_value(kind, y, t, breaks, coefs, i, k, burn, p, r_stop, m_dry):
    """Signed event function: crosses zero (upward for SPEED_MIN) at the event."""
    if kind == EVENT_RADIUS:
        return RADIUS(y) - r_stop
    if kind == EVENT_FUEL:
        return MASS(y) - m_dry
    if kind == EVENT_RADIUS_MIN:
        return RADIAL_RATE(y)
    u = control_in(breaks, coefs, i, k, t, burn)  # under the step's control (segment k)
    return SPEED_RATE(y, DERIV(y, u, p))


def is_after(kind, g):
    """Whether the event function value g lies on the post-event side."""
    if kind == EVENT_SPEED_MIN or kind == EVENT_RADIUS_MIN:
        return g >= 0.0
    return g <= 0.0


def locate(kind, y, t, h, g_lo, g_hi, breaks, coefs, i, k, burn, p, r_stop, m_dry):
    """Partial step in (0, h] at which the event fires, by Illinois regula falsi.

    The event is located on the RK4 solution itself (each trial is an RK4 step of the trial
    length from the step's start), so the stopped state is exactly what the integrator would
    reach there. Returns the shortest trial length found on the post-event side.
    """
    lo = 0.0
    hi = h
    side = 0
    for _ in range(_ROOT_ITERATIONS):
        if hi - lo <= 1e-15 * (1.0 + abs(t)):
            break
        denom = g_hi - g_lo
        mid = lo - g_lo * (hi - lo) / denom if denom != 0.0 else 0.5 * (lo + hi)
        if not (lo < mid < hi):
            mid = 0.5 * (lo + hi)
        ym = rk4_step(y, t, mid, breaks, coefs, i, k, burn, p)
        gm = event_value(kind, ym, t + mid, breaks, coefs, i, k, burn, p, r_stop, m_dry)
        if is_after(kind, gm):
            hi = mid
            g_hi = gm
            if side == 1:
                g_lo *= 0.5
            side = 1
        else:
            lo = mid
            g_lo = gm
            if side == -1:
                g_hi *= 0.5
            side = -1
    return hi


def propagate_lane(i, y0, t0, dt, n_steps, breaks, coefs, p, m_dry, r_stop, stop_at_speed_min,
                   record, y_end, t_end, status, t_burnout, n_rec, traj):
    """Trajectory ``i`` of :func:`propagate`, its results written into row ``i`` of the output
    arrays. One compiled function serves the serial and the parallel kernel (the parallel one
    only spreads the rows over threads), so the step loop is compiled once per model."""
    nx = y0.shape[1]
    pi = p[i]  # this trajectory's parameters (a plant error makes them per-lander)
    y = LOAD(y0[i])
    t = t0[i]
    h = dt[i]
    rs = r_stop[i]
    use_radius = rs == rs
    burn = 1.0 if MASS(y) > m_dry else 0.0
    k = 0
    if record:
        for j in range(nx):
            traj[i, 0, j] = y[j]
    st = EVENT_NONE
    g_speed = 0.0
    if stop_at_speed_min:
        g_speed = event_value(EVENT_SPEED_MIN, y, t, breaks, coefs, i, k, burn, pi, rs, m_dry)
    s_done = 0
    carry = False
    u0 = UZERO
    c0 = PREP(u0)
    for s in range(n_steps):
        t_next = t0[i] + (s + 1) * h
        k_new = segment_at(breaks, coefs, i, k, t)
        if k_new != k:
            k = k_new
            carry = False
            # a speed minimum is judged under a held control: restart the speed-rate
            # sign at the new segment (a kink at the break itself is not an event)
            if stop_at_speed_min:
                g_speed = event_value(EVENT_SPEED_MIN, y, t, breaks, coefs, i, k, burn, pi,
                                      rs, m_dry)
        while True:
            hh = t_next - t
            # The control at the step's start is the one the previous full step ended with
            # (same segment, same burn): carried over, its trigonometry is not redone.
            if not carry:
                u0 = control_in(breaks, coefs, i, k, t, burn)
                c0 = PREP(u0)
            u1 = control_in(breaks, coefs, i, k, t + 0.5 * hh, burn)
            u2 = control_in(breaks, coefs, i, k, t + hh, burn)
            c1 = c0 if u1 == u0 else PREP(u1)
            c2 = c1 if u2 == u1 else PREP(u2)
            y1 = rk4_core(y, hh, c0, c1, c2, pi)
            kind = EVENT_NONE
            best = hh
            if burn > 0.0 and MASS(y1) <= m_dry:
                tau = locate(EVENT_FUEL, y, t, hh, MASS(y) - m_dry, MASS(y1) - m_dry,
                             breaks, coefs, i, k, burn, pi, rs, m_dry)
                if tau <= best:
                    best = tau
                    kind = EVENT_FUEL
            if use_radius:
                g0 = RADIUS(y) - rs
                g1 = RADIUS(y1) - rs
                h_cross = -1.0
                if g0 > 0.0 and g1 <= 0.0:
                    h_cross = hh
                elif g0 > 0.0 and RADIAL_RATE(y) < 0.0 and RADIAL_RATE(y1) > 0.0:
                    # The radius has a minimum inside the step: a dip below r_stop and back
                    # (a lander braking to a stop just under the surface) crosses twice and
                    # shows no sign change at the step's ends. Look at the minimum.
                    tau_m = locate(EVENT_RADIUS_MIN, y, t, hh, RADIAL_RATE(y),
                                   RADIAL_RATE(y1), breaks, coefs, i, k, burn, pi, rs, m_dry)
                    g_m = RADIUS(rk4_step(y, t, tau_m, breaks, coefs, i, k, burn, pi)) - rs
                    if g_m <= 0.0:
                        h_cross = tau_m
                        g1 = g_m
                if h_cross > 0.0:
                    tau = locate(EVENT_RADIUS, y, t, h_cross, g0, g1, breaks, coefs, i, k,
                                 burn, pi, rs, m_dry)
                    if tau < best or kind == EVENT_NONE:
                        best = tau
                        kind = EVENT_RADIUS
            g1s = 0.0
            if stop_at_speed_min:
                g1s = event_value(EVENT_SPEED_MIN, y1, t + hh, breaks, coefs, i, k, burn, pi,
                                  rs, m_dry)
                if g_speed < 0.0 and g1s >= 0.0:
                    tau = locate(EVENT_SPEED_MIN, y, t, hh, g_speed, g1s, breaks, coefs, i,
                                 k, burn, pi, rs, m_dry)
                    if tau < best or kind == EVENT_NONE:
                        best = tau
                        kind = EVENT_SPEED_MIN
            if kind == EVENT_NONE:
                y = y1
                t = t_next
                g_speed = g1s
                u0 = u2
                c0 = c2
                carry = True
                break
            carry = False
            y = rk4_step(y, t, best, breaks, coefs, i, k, burn, pi)
            t = t + best
            if kind == EVENT_FUEL:
                burn = 0.0
                t_burnout[i] = t
                if stop_at_speed_min:
                    g_speed = event_value(EVENT_SPEED_MIN, y, t, breaks, coefs, i, k, burn,
                                          pi, rs, m_dry)
                if t_next - t <= 1e-15 * (1.0 + abs(t)):
                    t = t_next
                    break
                continue
            st = kind
            break
        s_done = s + 1
        if record:
            for j in range(nx):
                traj[i, s_done, j] = y[j]
        if st != EVENT_NONE:
            break
    status[i] = st
    t_end[i] = t
    n_rec[i] = s_done + 1
    for j in range(nx):
        y_end[i, j] = y[j]
    if record:
        for s2 in range(s_done + 1, n_steps + 1):
            for j in range(nx):
                traj[i, s2, j] = y[j]


def propagate(y0, t0, dt, n_steps, breaks, coefs, p, m_dry, r_stop, stop_at_speed_min,
              record):
    """Integrate a batch with fixed-step RK4 and in-step event location.

    y0 (B, nx); t0, dt, r_stop (B,); breaks (B, n_seg+1); coefs (B, n_seg, nu, order);
    p (B, n_params): each trajectory's model parameters (``params.as_array()`` per row).
    Returns y_end (B, nx), t_end (B,), status (B,), t_burnout (B,), n_rec (B,), traj.
    """
    n_traj = y0.shape[0]
    nx = y0.shape[1]
    y_end = np.empty((n_traj, nx))
    t_end = np.empty(n_traj)
    status = np.zeros(n_traj, dtype=np.int64)
    t_burnout = np.full(n_traj, np.nan)
    n_rec = np.zeros(n_traj, dtype=np.int64)
    if record:
        traj = np.empty((n_traj, n_steps + 1, nx))
    else:
        traj = np.empty((1, 1, nx))
    # One signature of the lane for every caller: the row as int64 (a prange index is uint64)
    # and the flag as a plain bool (propagate_into passes the literal False); each other
    # signature would be a full compile of the step loop.
    rec = np.bool_(record)
    for i in prange(n_traj):
        propagate_lane(np.int64(i), y0, t0, dt, n_steps, breaks, coefs, p, m_dry, r_stop,
                       stop_at_speed_min, rec, y_end, t_end, status, t_burnout, n_rec, traj)
    return y_end, t_end, status, t_burnout, n_rec, traj


def propagate_into(y0, t0, dt, n_steps, breaks, coefs, p, m_dry, r_stop, stop_at_speed_min,
                   y_end, t_end, status, t_burnout):
    """:func:`propagate` without recording, its results copied into the caller's arrays
    ``y_end`` (B, nx), ``t_end``, ``status`` (int64), ``t_burnout`` (B,). For callers that
    step often with few trajectories (environments): handing new arrays back to Python costs
    several times what the integration of one lander does, copying into prepared ones does not.
    """
    ye, te, st, tb, _, _ = propagate(y0, t0, dt, n_steps, breaks, coefs, p, m_dry, r_stop,
                                     stop_at_speed_min, False)
    y_end[:] = ye
    t_end[:] = te
    status[:] = st
    t_burnout[:] = tb
