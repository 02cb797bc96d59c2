"""The explicit laws' descent phases on ``LunarPinpointLanding-v3`` (guidance.laws.apollo.
DescentPhases): the switch from a gate to terminal descent, the rate of descent held and the
horizontal velocity nulled there, the options' checks, and v2's flights unchanged."""

import math

import numpy as np
import pytest

from guidance.flight import decide, fly, make_vec, navigation
from guidance.law import FlightComputer
from guidance.laws.apollo import (
    PHASE_HIGH_GATE,
    PHASE_LOW_GATE,
    PHASE_TERMINAL,
    AugmentedApolloLaw,
    DescentPhases,
)
from guidance.registry import LawContext, build_law
from lunar_env import dynamics as dyn
from lunar_env import get_scenario

V3 = "LunarPinpointLanding-v3"
SC = get_scenario("peng2012_touchdown")


def _start_si(height_m, uprange_m, v_along_m_s, v_up_m_s, mass_kg):
    """A Moon-fixed start (x, y, z m, vx, vy, vz m/s, m kg) ``uprange_m`` before the site
    along the orbit plane, ``height_m`` above its surface, moving at (v_along, 0, v_up) in the
    local frame."""
    tgt = np.asarray(SC.target_position_m(), dtype=float)
    r_site = float(np.linalg.norm(tgt))
    n = np.asarray(SC.plane_normal(), dtype=float)
    f = dyn.orbital_frame(*tgt / r_site, *n)
    up, along = np.array(f[0:3]), np.array(f[3:6])
    psi = uprange_m / r_site
    pos = (r_site + height_m) * (math.cos(psi) * up - math.sin(psi) * along)
    u = pos / np.linalg.norm(pos)
    g = dyn.orbital_frame(*u, *n)
    vel = v_along_m_s * np.array(g[3:6]) + v_up_m_s * np.array(g[0:3])
    return np.concatenate([pos, vel, [mass_kg]])


def _fly_traced(law, start_si, max_steps=400):
    """Per decision: the law's phase, the navigated height and velocity (guidance frame); and
    the env's info at the end."""
    v = make_vec(V3, 1, {})
    obs, _ = v.reset(options={"state_si": start_si[None]})
    core = v.unwrapped
    comp = FlightComputer.of(core, V3)
    law.reset(comp, np.arange(1))
    start = np.ones(1, dtype=bool)
    rows = []
    info = None
    for _ in range(max_steps):
        nav, _ = navigation(core, comp, obs, np.ones(1, dtype=bool), start)
        start[:] = False
        action = decide(law, nav)
        f = nav.frame
        rows.append((int(law.phase[0]), float(f.height_m[0]), f.v[0].copy()))
        obs, _, term, trunc, info = v.step(action)
        if term[0] or trunc[0]:
            break
    v.close()
    return rows, info


@pytest.mark.parametrize("kr", [6.0, 12.0])
def test_gate_reached_then_terminal_descent_holds_the_rate_and_nulls_the_horizontal(kr):
    """From 300 m up and 800 m uprange at 25 m/s: the law flies to the low gate, switches to
    terminal descent there, holds the rate of descent and brings the horizontal velocity to
    zero, and touches down at the rate."""
    phases = DescentPhases(high_gate_m=0.0, low_gate_m=40.0, rate_m_s=1.5)
    law = AugmentedApolloLaw(k_r=kr, phases=phases)
    rows, info = _fly_traced(law, _start_si(300.0, 800.0, 25.0, -6.0, 340.0))
    phase = np.array([r[0] for r in rows])
    assert phase[0] == PHASE_LOW_GATE and phase[-1] == PHASE_TERMINAL
    assert np.all(np.diff(phase) >= 0)  # no phase is flown twice
    k = int(np.argmax(phase == PHASE_TERMINAL))
    # the gate is reached: the switch comes within a few seconds of the low gate's height
    assert 40.0 - 5.0 < rows[k][1] < 40.0 + 20.0, rows[k]
    # after three time constants of each loop: the rate held, the horizontal velocity nulled
    settled = [r for r in rows[k:] if r is not rows[-1]][int(3 * phases.horizontal_tau_s) + 1:]
    assert len(settled) > 5
    v = np.array([r[2] for r in settled])
    np.testing.assert_allclose(v[:, 2], -1.5, atol=0.05)
    assert np.max(np.linalg.norm(v[:, :2], axis=1)) < 0.1
    assert info["is_success"][0]
    assert info["touchdown_vertical_speed_m_s"][0] == pytest.approx(1.5, abs=0.1)
    assert info["touchdown_horizontal_speed_m_s"][0] < 0.1


def test_high_gate_comes_before_the_low_gate():
    """With a high gate the law brakes to it first (phase 0), then approaches the low gate."""
    phases = DescentPhases(high_gate_m=600.0, high_gate_speed_m_s=40.0, low_gate_m=30.0)
    law = AugmentedApolloLaw(k_r=6.0, phases=phases)
    rows, info = _fly_traced(law, _start_si(1500.0, 9000.0, 120.0, -20.0, 360.0))
    phase = np.array([r[0] for r in rows])
    assert phase[0] == PHASE_HIGH_GATE
    assert set(phase.tolist()) == {PHASE_HIGH_GATE, PHASE_LOW_GATE, PHASE_TERMINAL}
    assert np.all(np.diff(phase) >= 0)
    k = int(np.argmax(phase == PHASE_LOW_GATE))
    assert abs(rows[k][1] - 600.0) < 150.0, rows[k]  # switched near the high gate's height
    assert info["is_success"][0]


@pytest.mark.parametrize("spec, message", [
    ("apollo:low_gate=1", r"low_gate_m = 1\.0 is not allowed; it must be in \[5, 500\]"),
    ("zem-zev:low_gate=900", r"low_gate_m = 900\.0 is not allowed; it must be in \[5, 500\]"),
    ("zem-zev:low_gate=nan", r"low_gate_m = nan is not allowed; it must be in \[5, 500\]"),
    ("apollo:high_gate=10", r"high_gate_m = 10\.0 is not allowed; it must be 0 \(no high "
                            r"gate\) or in \(15, 10000\]"),
    ("zem-zev:rate=3.5", r"rate_m_s = 3\.5 is not allowed; it must be in \[0\.2, 2\.9\]"),
    ("zem-zev:tilt=80", r"max_tilt_deg = 80\.0 is not allowed; it must be in \[0, 60\]"),
    ("zem-zev:phased=0,rate=2", r"rate are options of the phases; phased=0 flies none"),
    ("apollo:low_gate=abc", r"option low_gate='abc' is not valid"),
])
def test_bad_phase_options_are_refused_naming_the_value_and_range(spec, message):
    ctx = LawContext(env_id=V3, env_kwargs={}, scenario=SC)
    with pytest.raises(ValueError, match=message) as err:
        build_law(spec, ctx)
    assert str(err.value).startswith("law ")


def test_phases_need_an_env_that_lands_on_its_site():
    """v2 ends at the 2 km gate: phases asked for there are refused at reset, and the default
    flies without them."""
    v = make_vec("LunarPinpointLanding-v2", 1, {"throttle_channel": True})
    v.reset(seed=0)
    comp = FlightComputer.of(v.unwrapped, "LunarPinpointLanding-v2")
    v.close()
    with pytest.raises(ValueError, match="does not end at touchdown on its target"):
        AugmentedApolloLaw(phases=DescentPhases()).reset(comp, np.arange(1))
    law = AugmentedApolloLaw()
    law.reset(comp, np.arange(1))
    assert law.descent is None
    with pytest.raises(ValueError, match="options of the law without phases"):
        AugmentedApolloLaw(aim_above_m=5.0).reset(
            FlightComputer.of(make_vec(V3, 1, {}).unwrapped, V3), np.arange(1))


def test_spec_options_reach_the_phases():
    ctx = LawContext(env_id=V3, env_kwargs={}, scenario=SC)
    law = build_law("zem-zev:low_gate=50,rate=1.5,high_gate=0", ctx)
    assert law.phases == DescentPhases(low_gate_m=50.0, rate_m_s=1.5, high_gate_m=0.0)
    assert build_law("apollo:phased=0", ctx).phases is False
    assert build_law("apollo", ctx).phases is None  # the env family's default


#: final states (normalised) of v2 flights recorded from the code before the phases existed
#: (seed 5, 2 cases): (law, env arguments) -> rows
V2_FINAL_STATES = {
    ("apollo", ()): [
        [0.9042034887666534, 0.40363299273982484, 0.14764578648716953, -0.026136764617955957,
         -0.06678503324421767, -0.03527964812338061, 0.5],
        [0.9050632443350355, 0.40207806185249934, 0.14661710720099294, -0.03224950021325015,
         -0.06485675108854715, -0.034720358266581916, 0.5]],
    ("apollo", ("throttle_channel", "uncertainty")): [
        [0.8961796729979651, 0.4178976797545914, 0.15660888593658714, -0.0008036316140088966,
         0.0012649552134121785, 0.0007716515904796244, 0.5283894390957078],
        [0.8961915230609548, 0.4178695365161088, 0.15661616978718437, -0.0031637230877673713,
         0.0036443706961387067, 0.0023046393220703975, 0.5220934777291774]],
    ("zem-zev", ()): [
        [0.8962384968582078, 0.4177929576935181, 0.15655165743086935, -0.0324669825151742,
         0.055339928693648614, 0.03662774610202957, 0.5171370708259492],
        [0.8970589696619231, 0.4163714076906825, 0.1556370007423625, -0.017104607415619186,
         0.0281876090408223, 0.01907136010175733, 0.5]],
    ("zem-zev", ("throttle_channel", "uncertainty")): [
        [0.8961798751585024, 0.41789732218267794, 0.1566086832418556, -0.0012746089347535209,
         0.001611447909772334, 0.0010763831762285576, 0.5292701583407635],
        [0.8961963339601752, 0.41786186424252514, 0.156609110850593, -0.004256878940490107,
         0.005998693347282223, 0.004783167852167321, 0.5232593469170055]],
}


@pytest.mark.parametrize("key", list(V2_FINAL_STATES), ids=lambda k: f"{k[0]}-{len(k[1])}")
def test_v2_flights_are_unchanged(key):
    """v2 (the 2 km gate, no touchdown) flies exactly as before the phases: same final
    states, bit for bit."""
    spec, kw_keys = key
    kw = {"throttle_channel": True, "uncertainty": "standard"} if kw_keys else {}
    env_id = "LunarPinpointLanding-v2"
    law = build_law(spec, LawContext(env_id=env_id, env_kwargs={},
                                     scenario=get_scenario("peng2012")))
    ro = fly(env_id, law, 2, seed=5, env_kwargs=kw)
    np.testing.assert_array_equal(ro.final_state_nd, np.array(V2_FINAL_STATES[key]))


def test_convex_refuses_the_touchdown_problem_by_name():
    """SCvx has no transcription of the touchdown problem: the law says so when it is built,
    not at its first re-plan."""
    pytest.importorskip("cvxpy")
    ctx = LawContext(env_id=V3, env_kwargs={}, scenario=SC)
    with pytest.raises(ValueError, match="no convex transcription of TouchdownOCP"):
        build_law("convex", ctx)
