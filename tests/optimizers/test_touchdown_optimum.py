"""The touchdown optimum (LunarPinpointLanding-v3): two independent methods, phased
Legendre–Gauss collocation and Pontryagin multi-arc shooting, each replayed by DOP853, agreeing
on the propellant; the arc structure; the propellant margin of ``peng2012_touchdown``; the
optimum family's cache, plants and registry."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from lunar_env import get_scenario
from lunar_env.scenarios import PinpointState
from optimizers.indirect.touchdown import TouchdownShooting
from optimizers.optimum import optimum_family
from optimizers.optimum.touchdown import (
    AGREEMENT_REL,
    CERTIFIED,
    TouchdownOptimumFamily,
    solve_touchdown_case,
    touchdown_ocp,
    touchdown_optima,
)
from optimizers.problems.touchdown import MAX_MIN_MAX, TouchdownOCP
from optimizers.transcription.phased_gpm import PhasedGaussPseudospectral, solve_structure

SC = get_scenario("peng2012_touchdown")
G_SURFACE = SC.body.mu_m3_s2 / SC.body.radius_m ** 2


def _corner(bits) -> np.ndarray:
    """The normalised start at a corner of the dispersion (altitude, speed, mass, longitude,
    latitude: 0 the low end, 1 the high end)."""
    d, st = SC.dispersion, SC.initial
    dh, dv, dm, dl, dp = (rg[i] for rg, i in zip(
        (d.altitude_m, d.speed_m_s, d.mass_kg, d.longitude_rad, d.latitude_rad), bits,
        strict=True))
    return SC.state_nd(PinpointState(st.altitude_m + dh, st.longitude_rad + dl,
                                     st.latitude_rad + dp, st.u_m_s, st.v_m_s + dv, st.w_m_s,
                                     st.inclination_rad, st.mass_kg + dm))


def _hover_s(margin_kg: float) -> float:
    """Seconds of hover at the touchdown mass (dry mass + the margin) the margin buys."""
    m = SC.vehicle.dry_mass_kg + margin_kg
    return margin_kg / (m * G_SURFACE / SC.vehicle.exhaust_velocity_m_s)


def test_peng2012_touchdown_nominal_optimum_by_two_methods():
    """[001]'s start to touchdown: full thrust 7.4 s, minimum throttle 23.6 s, full thrust
    531.9 s; 277.5753 kg by both methods, agreeing far inside 1e-6; both DOP853 replays on
    the target. The 300 kg load leaves 22.4 kg: 126 s of hover at touchdown, as Apollo 17's
    117 s (Apollo 11: 45 s)."""
    opt = solve_touchdown_case(SC, touchdown_ocp(SC).x0_nd)
    assert opt.success, opt.message
    np.testing.assert_allclose(opt.levels, [1.0, 0.2, 1.0])
    np.testing.assert_allclose(opt.durations_s, [7.44, 23.56, 531.89], atol=0.01)
    assert opt.fuel_kg == pytest.approx(277.5753, abs=1e-3)
    assert opt.fuel_rel_diff <= AGREEMENT_REL
    assert opt.fuel_indirect_kg == pytest.approx(opt.fuel_kg, rel=AGREEMENT_REL)
    assert np.all(opt.replay_errors[[0, 2]] < 0.01) and np.all(opt.replay_errors[[1, 3]] < 1e-3)
    margin = SC.vehicle.mass_kg - SC.vehicle.dry_mass_kg - opt.fuel_kg
    assert margin == pytest.approx(22.42, abs=0.01)
    assert 117.0 < _hover_s(margin) < 130.0
    # the law: (α, β, throttle) inside the bounds, full thrust then the floor
    u = opt.controls_at(np.array([1.0, 20.0, 300.0, opt.tf_s]), SC)
    np.testing.assert_allclose(u[:, 2], [1.0, 0.2, 1.0, 1.0])
    assert np.all(u[:, 0] >= SC.alpha_bounds_rad[0]) and np.all(u[:, 0] <= SC.alpha_bounds_rad[1])


@pytest.mark.parametrize("bits, levels, first_arc_s", [
    ((0, 0, 1, 0, 0), (0.2, 1.0), None),      # heavy, low, slow: no first full-thrust arc
    ((1, 0, 1, 0, 1), (1.0, 0.2, 1.0), 0.82),  # a first arc shorter than the 1 s floor
], ids=["min-max", "short-first-arc"])
def test_dispersion_corners_find_their_arc_structure(bits, levels, first_arc_s):
    opt = solve_touchdown_case(SC, _corner(bits))
    assert opt.success, opt.message
    np.testing.assert_allclose(opt.levels, levels)
    assert opt.fuel_rel_diff <= AGREEMENT_REL
    if first_arc_s is not None:
        assert opt.durations_s[0] == pytest.approx(first_arc_s, abs=0.01)


def test_pontryagin_refuses_a_structure_without_the_first_arc():
    """The certification is not a formality: on [001]'s start the min–max structure has a
    collocation optimum and an extremal, but the switching function is negative on its first
    arc (full thrust is better there), so the extremal is refused."""
    ocp = TouchdownOCP(SC)
    gpm = PhasedGaussPseudospectral()
    direct = gpm.solve(ocp, (None, 1.0))
    assert direct.success
    ext = TouchdownShooting().solve(ocp, direct.levels, guess_durations_nd=direct.durations_nd,
                                    guess_final_mass_nd=direct.final_state[6],
                                    guess_costate_tf=direct.costate_tf)
    assert not ext.success and not ext.switching_ok
    assert "switching function" in ext.message
    full = solve_structure(gpm, ocp, MAX_MIN_MAX)
    assert full.fuel_kg < direct.fuel_kg - 4e-4  # 0.42 g: 1.5e-6 of the propellant


def _standard_case_optimum(seed: int):
    """The certified optimum of the `standard` v3 case reset with ``seed``, with its true
    engine from its true start (a campaign's omniscient reference)."""
    import gymnasium as gym

    env = gym.make("LunarPinpointLanding-v3", uncertainty="standard").unwrapped
    env.reset(seed=seed)
    errors = env.episode_errors
    return solve_touchdown_case(SC, np.array(env.state_nd, dtype=float),
                                thrust_scale=float(errors.thrust_scale[0]),
                                isp_scale=float(errors.isp_scale[0]))


def test_an_extremal_with_a_first_arc_the_collocation_removed_is_certified():
    """A `standard` case (seed 900000072: thrust +2.5 %) whose collocation removes the first
    full-thrust arc while the extremal holds it for 0.03 s. The min–max extremal breaks the
    minimum principle at its start; with that arc reinstated the full structure converges, and
    the two methods agree to 1e-10. Before, such cases (2 % of `standard`) had no reference."""
    opt = _standard_case_optimum(900000072)
    assert opt.success, opt.message
    np.testing.assert_allclose(opt.levels, [0.2, 1.0])  # the collocation's structure
    assert opt.message.startswith("certified: throttle 1 for 0.03 s, 0.2 for 26.")
    assert opt.fuel_rel_diff <= 1e-9
    assert opt.fuel_kg == pytest.approx(282.3765, abs=1e-3)
    assert np.all(opt.replay_errors[[0, 2]] < 0.01) and np.all(opt.replay_errors[[1, 3]] < 1e-3)


def test_a_collocation_stopped_at_the_iteration_limit_resumes_and_is_certified():
    """A `standard` case (seed 900000376: thrust −2.6 %) whose cold collocation stops at IPOPT's
    iteration limit with the terminal conditions met: resumed once from its last iterate it
    converges, and both methods certify it (10 laws land this case; it had no reference)."""
    opt = _standard_case_optimum(900000376)
    assert opt.success, opt.message
    assert opt.fuel_kg == pytest.approx(278.065, abs=1e-3)
    assert opt.fuel_rel_diff <= 1e-9


def test_removed_arcs_are_placed_in_the_full_structure_every_way():
    from optimizers.optimum.touchdown import _embeddings

    full = (1.0, 0.2, 1.0)
    assert _embeddings((0.2, 1.0), full) == [[1, 2]]
    assert _embeddings((1.0, 0.2), full) == [[0, 1]]
    assert _embeddings((1.0,), full) == [[0], [2]]
    assert _embeddings(full, full) == [[0, 1, 2]]
    assert _embeddings((0.2, 0.2), full) == []


def test_family_registry_cache_and_plants(tmp_path, monkeypatch):
    monkeypatch.setenv("LUNAR_CACHE_DIR", str(tmp_path))
    fam = optimum_family(SC)
    assert isinstance(fam, TouchdownOptimumFamily)
    assert isinstance(fam.replan_ocp(SC), TouchdownOCP)
    rng = np.random.default_rng(7)
    states = np.array([SC.state_nd(s) for s in SC.sample_initial(rng, 2)])
    first = fam.per_case_optimum(SC, states, progress=False)
    assert first.info["solver"] == CERTIFIED and first.info["converged"] == 2
    assert len(list((tmp_path / "touchdown_optimum").glob("*.npz"))) == 2
    again = fam.per_case_optimum(SC, states, progress=False)  # read from the cache
    np.testing.assert_array_equal(again.fuel_kg, first.fuel_kg)
    assert [s.solve_s for s in again.solutions] == [s.solve_s for s in first.solutions]
    # the omniscient reference: the nominal plant is the per-case optimum; a stronger engine
    # with the same Isp lands on less propellant (less gravity loss)
    ref = fam.plant_optimum_fuel(SC, states, np.array([1.0, 1.03]), np.array([1.0, 1.0]))
    assert ref.solver == (CERTIFIED, CERTIFIED)
    assert ref.fuel_kg[0] == pytest.approx(first.fuel_kg[0], rel=1e-9)
    direct = solve_touchdown_case(SC, states[1], thrust_scale=1.03)
    assert ref.fuel_kg[1] == pytest.approx(direct.fuel_kg, rel=1e-9)
    assert ref.fuel_kg[1] < first.fuel_kg[1]


def test_lagrange_interpolation_is_exact_for_the_collocation_polynomials():
    """The collocation's control representation (replays, env replays): a polynomial of degree
    N − 1 through N LG points is reproduced everywhere."""
    from optimizers.common.quadrature import lagrange_interpolate, legendre_gauss

    tau = legendre_gauss(10)[0]
    coef = np.random.default_rng(0).normal(size=(10, 3))
    f = np.stack([np.polynomial.polynomial.polyval(tau, coef[:, j]) for j in range(3)], 1)
    x = np.linspace(-1.0, 1.0, 41)
    want = np.stack([np.polynomial.polynomial.polyval(x, coef[:, j]) for j in range(3)], 1)
    np.testing.assert_allclose(lagrange_interpolate(tau, f, x), want, rtol=1e-10, atol=1e-10)
    np.testing.assert_array_equal(lagrange_interpolate(tau, f, tau[3:4]), f[3:4])


def test_bad_inputs_are_refused():
    with pytest.raises(ValueError, match="7 finite"):
        solve_touchdown_case(SC, np.full(7, np.nan))
    with pytest.raises(ValueError, match="thrust_scale"):
        solve_touchdown_case(SC, touchdown_ocp(SC).x0_nd, thrust_scale=0.0)
    with pytest.raises(TypeError, match="TouchdownScenario"):
        TouchdownOCP(get_scenario("peng2012"))
    with pytest.raises(ValueError, match="outside"):
        TouchdownOCP(SC).levels((1.0, 0.1))


@pytest.mark.slow
def test_fifty_drawn_states_agree_and_solve_in_under_two_seconds():
    """50 states of the dispersion (seed 2026): every one certified, the two methods' propellant
    within 1e-6 (measured: max 1.1e-13, median 3.3e-14), median solve time < 2 s (measured
    0.9 s on 2 cores)."""
    rng = np.random.default_rng(2026)
    states = np.array([SC.state_nd(s) for s in SC.sample_initial(rng, 50)])
    opts = touchdown_optima(SC, states, use_cache=False, progress=False)
    assert all(o.success for o in opts), [o.message for o in opts if not o.success]
    rel = np.array([o.fuel_rel_diff for o in opts])
    assert rel.max() <= AGREEMENT_REL
    assert float(np.median([o.solve_s for o in opts])) < 2.0


@pytest.mark.slow
def test_every_dispersion_corner_keeps_more_than_apollo_11s_hover_margin():
    """The 32 corners of the dispersion box are certified; the most demanding (the lightest
    start) keeps 16.7 kg, 96 s of hover at touchdown, more than Apollo 11's 45 s."""
    rows = np.array([_corner(b) for b in itertools.product((0, 1), repeat=5)])
    opts = touchdown_optima(SC, rows, use_cache=False, progress=False)
    assert all(o.success for o in opts), [o.message for o in opts if not o.success]
    assert max(o.fuel_rel_diff for o in opts) <= AGREEMENT_REL
    margin = rows[:, 6] * SC.scaling().mass_kg - SC.vehicle.dry_mass_kg \
        - np.array([o.fuel_kg for o in opts])
    assert margin.min() == pytest.approx(16.70, abs=0.05)
    assert _hover_s(float(margin.min())) > 45.0


@pytest.mark.slow
def test_batches_run_on_the_executor(tmp_path, monkeypatch):
    """Chunks of the chain as keyed tasks on a local executor: the same optima as in process."""
    from optimizers.common.executor import LocalExecutor

    rng = np.random.default_rng(3)
    states = np.array([SC.state_nd(s) for s in SC.sample_initial(rng, 4)])
    here = touchdown_optima(SC, states, use_cache=False, progress=False)
    with LocalExecutor(2) as ex:
        there = touchdown_optima(SC, states, progress=False, executor=ex,
                                 cache_dir=tmp_path)
    for a, b in zip(here, there, strict=True):
        assert a.success and b.success
        assert b.fuel_kg == pytest.approx(a.fuel_kg, rel=AGREEMENT_REL)
    assert len(list(tmp_path.glob("*.npz"))) == 4
    assert math.isfinite(there[0].solve_s)
