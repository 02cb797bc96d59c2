"""Scenario registry, SI/normalised conversion, and rejection of invalid values."""

import dataclasses
import math

import numpy as np
import pytest

from lunar_env import dynamics as dyn
from lunar_env import get_scenario, list_scenarios
from lunar_env.scenarios import (
    PinpointState,
    PlanarDispersion,
    PlanarScenario,
    PlanarState,
    Vehicle,
)


def test_all_papers_registered():
    names = set(list_scenarios())
    assert {"zhu2007", "peng2012", "wang2003", "peng_mars", "wang2001"} <= names
    with pytest.raises(KeyError, match="registered"):
        get_scenario("apollo11")


def test_zhu2007_nominal_values():
    sc = get_scenario("zhu2007")
    assert sc.initial.radius_m == 1753e3
    assert sc.initial.angular_rate_rad_s == pytest.approx(9.65e-4)
    assert sc.vehicle.exhaust_velocity_m_s == pytest.approx(2940.0)
    y = sc.state_nd()
    assert y[dyn.R] == 1.0 and y[dyn.M] == 1.0
    s = sc.scaling()
    # normalisation of [000] eq. (5): μ = 1
    assert s.velocity_m_s ** 2 * s.length_m == pytest.approx(sc.body.mu_m3_s2)
    # mass flow: fuel = F/c·tf, as the papers compute it (1500/(300·9.8)·556.0648 = 283.7065)
    assert get_scenario("peng2012").vehicle.mass_flow_kg_s * 556.0648 == pytest.approx(283.7065,
                                                                                       abs=1e-4)


def test_peng2012_initial_orbit_inclination_is_30_degrees():
    sc = get_scenario("peng2012")
    r0, v0 = sc.initial_position_velocity_m()
    n = np.cross(r0, v0)
    n /= np.linalg.norm(n)
    assert math.degrees(math.acos(n[2])) == pytest.approx(30.0, abs=1e-12)
    assert np.linalg.norm(v0) == pytest.approx(1713.8)
    d = dyn.moon3d_derived(sc.state_nd(), sc.params())
    assert math.degrees(d["longitude_rad"]) == pytest.approx(10.0)
    assert d["latitude_rad"] == pytest.approx(0.0, abs=1e-15)
    s = sc.scaling()
    assert d["v_nd"] * s.velocity_m_s == pytest.approx(1713.8)
    assert d["u_nd"] == pytest.approx(0.0, abs=1e-15)
    assert d["w_nd"] == pytest.approx(0.0, abs=1e-15)
    # the plane's ground track passes close to the target (25°E, 9°N)
    lat = math.radians(9.0)
    arc = math.asin(math.sin(lat) / math.sin(math.radians(30)))
    lon = 10 + math.degrees(math.atan(math.cos(math.radians(30)) * math.tan(arc)))
    assert abs(lon - 25.0) < 1.0


def test_dispersion_sampling_is_seeded_and_inside_ranges():
    sc = get_scenario("zhu2007")
    a = sc.sample_initial(np.random.default_rng(1), 100)
    b = sc.sample_initial(np.random.default_rng(1), 100)
    np.testing.assert_array_equal(a, b)
    d = sc.dispersion
    h = a[:, 0] - sc.initial.radius_m
    assert d.altitude_m[0] <= h.min() and h.max() <= d.altitude_m[1]
    nd = sc.si_to_nd(a)
    assert np.all(np.isfinite(nd)) and nd.shape == (100, 5)
    states = get_scenario("peng2012").sample_initial(np.random.default_rng(0), 3)
    assert len(states) == 3 and all(isinstance(s, PinpointState) for s in states)


@pytest.mark.parametrize("field,value,match", [
    ("mass_kg", 0.0, "mass_kg"),
    ("mass_kg", -5.0, "mass_kg"),
    ("isp_s", 0.0, "isp_s"),
    ("isp_s", float("nan"), "isp_s"),
    ("thrust_n", float("inf"), "thrust_n"),
    ("dry_mass_kg", 700.0, "dry_mass_kg"),
])
def test_invalid_vehicle_rejected(field, value, match):
    kw = dict(mass_kg=600.0, thrust_n=1350.0, isp_s=300.0, dry_mass_kg=300.0)
    kw[field] = value
    with pytest.raises(ValueError, match=match):
        Vehicle(**kw)


def test_invalid_scenarios_rejected():
    sc = get_scenario("zhu2007")
    with pytest.raises(ValueError, match="below the surface"):
        dataclasses.replace(sc, initial=PlanarState(1737e3, 0.0, 0.0, 1600.0, 600.0))
    with pytest.raises(ValueError, match="reversed"):
        PlanarDispersion(altitude_m=(100.0, -100.0))
    with pytest.raises(ValueError, match="not finite"):
        PlanarState(float("nan"), 0.0, 0.0, 1600.0, 600.0)
    with pytest.raises(ValueError, match="reaches below the surface"):
        dataclasses.replace(sc, dispersion=PlanarDispersion(altitude_m=(-20e3, 0.0)))
    with pytest.raises(ValueError, match="reversed"):
        dataclasses.replace(sc, tf_bounds_s=(700.0, 500.0))


def test_user_built_scenario():
    sc = PlanarScenario(
        name="my_lander", reference="user", body=get_scenario("zhu2007").body,
        vehicle=Vehicle(mass_kg=800.0, thrust_n=2000.0, isp_s=310.0, dry_mass_kg=400.0),
        initial=PlanarState(1750e3, 0.0, 0.0, 1680.0, 800.0),
        target=get_scenario("zhu2007").target)
    assert sc.params().thrust_nd > 0
    assert sc.surface_radius_m == 1738e3
