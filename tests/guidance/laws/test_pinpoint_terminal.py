"""The pinpoint terminal window (:mod:`guidance.laws.terminal_window`)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from guidance.laws.terminal_window import TerminalWindow

G_GATE = 4902802600000.0 / (1738000.0 + 2000.0) ** 2  # m/s², the Moon at the v2 gate
GRAVITY = np.array([0.0, 0.0, -G_GATE])
MASS_KG = 321.0  # at the gate, nominal flights of the reserve law


@pytest.fixture(scope="module")
def window():
    import gymnasium as gym

    import lunar_env  # noqa: F401

    sc = gym.make("LunarPinpointLanding-v2").unwrapped.scenario
    v = sc.vehicle
    return TerminalWindow(v.thrust_n, v.exhaust_velocity_m_s, sc.alpha_bounds_rad,
                          sc.beta_bounds_rad, dt_s=2.0)


def _fly(window: TerminalWindow, controls: np.ndarray, v0, h0: float, substeps: int = 200):
    """An independent flight of the plan: fine explicit steps with the mass burning down
    (the planner integrates whole steps at constant acceleration). Returns the speed sampled
    over each step (steps, substeps + 1), the heights and velocities at the nodes."""
    v, h, m = np.array(v0, dtype=float), float(h0), MASS_KG
    dt = window.dt_s / substeps
    speeds, heights, vels = [], [h], [v.copy()]
    for alpha, beta, throttle in controls:
        d = np.array([math.cos(alpha) * math.cos(beta), math.cos(alpha) * math.sin(beta),
                      math.sin(alpha)])
        trace = [np.linalg.norm(v)]
        for _ in range(substeps):
            a = throttle * window.thrust_n / m * d + GRAVITY
            h += v[2] * dt + 0.5 * a[2] * dt * dt
            v = v + a * dt
            m -= throttle * window.thrust_n / window.exhaust_velocity_m_s * dt
            trace.append(np.linalg.norm(v))
        speeds.append(trace)
        heights.append(h)
        vels.append(v.copy())
    return np.array(speeds), np.array(heights), np.array(vels)


@pytest.mark.parametrize("v0, h0", [((10.0, 0.0, -1.0), 15.0), ((12.0, 2.0, -1.0), 8.0),
                                    ((6.0, 0.0, -1.0), 6.0)])
def test_the_window_keeps_the_gate_inside_a_band_crossed_below_the_limit(window, v0, h0):
    plan = window.plan(np.array(v0), h0, MASS_KG, GRAVITY)
    assert plan is not None
    speeds, heights, vels = _fly(window, plan.controls, v0, h0)
    n, first = plan.n_steps, plan.approach + 1
    assert np.all(plan.controls[n:, 2] == 0.0)  # then the fall
    for k in range(first, n + 1):  # the window's nodes
        assert np.linalg.norm(vels[k]) <= window.speed_limit + 0.02
        assert vels[k][2] <= 1e-6  # descending: each height crossed once
    for k in range(n):  # no speed minimum inside a step: the engine stays on
        inner = speeds[k][1:-1]
        assert not np.any((inner < speeds[k][:-2]) & (inner < speeds[k][2:]))
    top = heights[first]
    v_n = np.linalg.norm(vels[n])
    # then the fall, to the limit (energy)
    bottom = heights[n] - (window.speed_limit ** 2 - v_n ** 2) / (2.0 * G_GATE)
    margin = min(top, -bottom)
    # the planner's margin, met by the fine flight (it burns the mass down within a step)
    assert margin == pytest.approx(plan.margin_m, abs=0.3)
    # wider than a stop and fall can be centred: half of 25 / (2 g) = 3.9 m
    assert plan.margin_m > 0.5 * window.success_speed ** 2 / (2.0 * G_GATE)


def test_the_window_is_nearly_twice_the_fall_from_a_stop(window):
    # measured: 7.5 m either side from 12 m/s at 12 m up with the default margins
    # (8.3 m without them), against 7.7 m in all for a fall from rest
    plan = window.plan(np.array([12.0, 0.0, -1.0]), 12.0, MASS_KG, GRAVITY)
    assert 2.0 * plan.margin_m > 1.8 * 25.0 / (2.0 * G_GATE)


def test_a_plan_from_inside_the_window_keeps_its_top(window):
    plan = window.plan(np.array([2.0, 0.0, -3.0]), 1.0, MASS_KG, GRAVITY, top_m=6.0)
    assert plan is not None and plan.margin_m <= 6.0 + 1e-6


@pytest.mark.parametrize("kwargs, match", [
    ({"steps": 0}, "steps"), ({"dt_s": float("nan")}, "dt_s"),
    ({"speed_margin_m_s": 5.0}, "speed_margin_m_s"),
    ({"velocity_error_m_s": -1.0}, "velocity_error"),
    ({"accel_error_m_s2": float("inf")}, "accel_error"),
])
def test_bad_settings_are_refused_by_name(kwargs, match):
    args = {"thrust_n": 1500.0, "exhaust_velocity_m_s": 2940.0,
            "alpha_bounds_rad": (-0.87, 0.70), "beta_bounds_rad": (2.27, 3.84), "dt_s": 2.0}
    with pytest.raises(ValueError, match=match):
        TerminalWindow(**{**args, **kwargs})


def test_a_non_finite_state_is_refused(window):
    with pytest.raises(ValueError, match="finite"):
        window.plan(np.array([np.nan, 0.0, -1.0]), 10.0, MASS_KG, GRAVITY)
