"""Named, frozen scenarios: one per source-paper case, built the same way users build their own.

>>> from lunar_env import get_scenario
>>> sc = get_scenario("zhu2007")
>>> sc.vehicle.thrust_n
1350.0

Every value is SI; :meth:`PlanarScenario.scaling` and friends convert to the normalised units of
the kernels. Constructors validate their input: an invalid value raises ``ValueError`` naming
the field, the value and what is allowed.

Registry: ``zhu2007`` ([000]), ``peng2012`` ([001]), ``peng_mars`` ([002]), ``wang2003``
([003]), ``wang2001`` ([004], with the alias ``wang2001_transfer``), and ``peng2012_touchdown``
([001]'s start continued to touchdown with a throttleable engine, ``LunarPinpointLanding-v3``).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field, fields

import numpy as np

from .dynamics import Moon3DParams, PlanarParams
from .scaling import Scaling
from .states import check_planar_state_si, planar_nd_to_si, planar_si_to_nd
from .validation import require_finite, require_finite_positive, require_range

__all__ = [
    "Body", "Vehicle", "PlanarState", "PlanarTarget", "PlanarDispersion", "PlanarScenario",
    "PinpointState", "PinpointTarget", "PinpointDispersion", "PinpointScenario",
    "TouchdownScenario", "ImpulsiveTransferScenario", "get_scenario", "register_scenario",
    "list_scenarios",
    "G0_PAPER_M_S2", "MOON", "SUN", "EARTH",
]

G0_PAPER_M_S2 = 9.8  # [000], [001], [003]: 1500/(300·9.8)·556.0648 = 283.7065 kg
G0_STANDARD_M_S2 = 9.80665


def _check_positive(obj, *names: str) -> None:
    for n in names:
        require_finite_positive(f"{type(obj).__name__}.{n}", getattr(obj, n))


def _check_finite(obj, *names: str) -> None:
    for n in names:
        require_finite(f"{type(obj).__name__}.{n}", getattr(obj, n))


def _check_tf_bounds(name: str, tf_bounds_s) -> None:
    require_range(f"{name}.tf_bounds_s", tf_bounds_s)
    if not (tf_bounds_s[0] >= 0 and tf_bounds_s[1] > 0):
        raise ValueError(f"{name}.tf_bounds_s = {tuple(tf_bounds_s)!r} must be >= 0 with an upper "
                         "bound > 0 (final times are durations in s)")


@dataclass(frozen=True)
class Body:
    """Central body.

    Attributes
    ----------
    name : str
    mu_m3_s2 : float
        Gravitational parameter (m³/s²).
    radius_m : float
        Reference radius (m): the landing surface for the Moon.
    spin_rate_rad_s : float
        Rotation rate about the spin axis (rad/s); 0 for a non-rotating model.
    """

    name: str
    mu_m3_s2: float
    radius_m: float
    spin_rate_rad_s: float = 0.0

    def __post_init__(self) -> None:
        _check_positive(self, "mu_m3_s2", "radius_m")
        _check_finite(self, "spin_rate_rad_s")


MOON = Body("Moon", 4902.75e9, 1738.0e3)  # [000]
MOON_ROTATING = Body("Moon", 4902.8026e9, 1738.0e3, 2.6617e-6)  # [001] eq. (20)
SUN = Body("Sun", 1.32715e20, 6.957e8)  # [002]
# [004] gives no μ; the WGS-84/EGM-96 value is used (decision recorded in optimizers' Lambert docs)
EARTH = Body("Earth", 3.986004418e14, 6378.137e3)


@dataclass(frozen=True)
class Vehicle:
    """Lander or spacecraft.

    Attributes
    ----------
    mass_kg : float
        Initial (wet) mass.
    thrust_n : float
        Maximum thrust (N).
    isp_s : float
        Specific impulse (s); the exhaust velocity is ``isp_s * g0_m_s2``.
    dry_mass_kg : float
        Mass at which the propellant is exhausted (burn ends). 0 < dry_mass_kg < mass_kg.
    g0_m_s2 : float
        Standard gravity used with Isp; the papers use 9.8.
    """

    mass_kg: float
    thrust_n: float
    isp_s: float
    dry_mass_kg: float
    g0_m_s2: float = G0_PAPER_M_S2

    def __post_init__(self) -> None:
        _check_positive(self, "mass_kg", "thrust_n", "isp_s", "dry_mass_kg", "g0_m_s2")
        if not self.dry_mass_kg < self.mass_kg:
            raise ValueError(f"Vehicle.dry_mass_kg = {self.dry_mass_kg!r} is not allowed; it "
                             f"must be < mass_kg = {self.mass_kg!r}")

    @property
    def exhaust_velocity_m_s(self) -> float:
        return self.isp_s * self.g0_m_s2

    @property
    def mass_flow_kg_s(self) -> float:
        """Propellant flow at full thrust (kg/s)."""
        return self.thrust_n / self.exhaust_velocity_m_s


# ---------------------------------------------------------------------------------------------
# Planar two-body scenarios ([000], [002], [003])
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PlanarState:
    """Polar state in SI: radius (m), radial velocity (m/s), polar angle (rad), tangential
    velocity (m/s, = r·ω, positive in the direction of motion) and mass (kg)."""

    radius_m: float
    radial_velocity_m_s: float
    theta_rad: float
    tangential_velocity_m_s: float
    mass_kg: float

    def __post_init__(self) -> None:
        _check_positive(self, "radius_m", "mass_kg")
        _check_finite(self, "radial_velocity_m_s", "theta_rad", "tangential_velocity_m_s")

    @property
    def angular_rate_rad_s(self) -> float:
        return self.tangential_velocity_m_s / self.radius_m


@dataclass(frozen=True)
class PlanarTarget:
    """Terminal conditions: radius (m), radial and tangential velocity (m/s); θ is free."""

    radius_m: float
    radial_velocity_m_s: float = 0.0
    tangential_velocity_m_s: float = 0.0

    def __post_init__(self) -> None:
        _check_positive(self, "radius_m")
        _check_finite(self, "radial_velocity_m_s", "tangential_velocity_m_s")


@dataclass(frozen=True)
class PlanarDispersion:
    """Ranges (low, high) of offsets from the nominal initial state, drawn uniformly.

    Used by environment resets and dataset generation.
    """

    altitude_m: tuple[float, float] = (0.0, 0.0)
    tangential_velocity_m_s: tuple[float, float] = (0.0, 0.0)
    radial_velocity_m_s: tuple[float, float] = (0.0, 0.0)
    mass_kg: tuple[float, float] = (0.0, 0.0)
    theta_rad: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        for f in fields(self):
            require_range(f"PlanarDispersion.{f.name}", getattr(self, f.name))


@dataclass(frozen=True)
class PlanarScenario:
    """A planar two-body descent or transfer case.

    Attributes
    ----------
    name, reference : str
    body : Body
    vehicle : Vehicle
    initial : PlanarState
    target : PlanarTarget
    dispersion : PlanarDispersion
    tf_bounds_s : (float, float)
        Bounds of the free final time used by optimisers.
    surface_radius_m : float
        Radius below which the vehicle has crashed (the landing surface; for an interplanetary
        transfer the central body's radius).
    """

    name: str
    reference: str
    body: Body
    vehicle: Vehicle
    initial: PlanarState
    target: PlanarTarget
    dispersion: PlanarDispersion = field(default_factory=PlanarDispersion)
    tf_bounds_s: tuple[float, float] = (0.0, 1e4)
    surface_radius_m: float | None = None

    model = "planar"
    #: the env family of the scenario: the key of every per-family registry
    #: (:class:`lunar_env.families.FamilyRegistry`)
    family = "planar"

    def __post_init__(self) -> None:
        _check_tf_bounds(self.name, self.tf_bounds_s)
        if self.surface_radius_m is None:
            object.__setattr__(self, "surface_radius_m", self.body.radius_m)
        require_finite_positive(f"{self.name}.surface_radius_m", self.surface_radius_m)
        if self.initial.radius_m <= self.surface_radius_m:
            raise ValueError(
                f"{self.name}: initial.radius_m = {self.initial.radius_m!r} starts at or below "
                f"the surface; it must be > surface_radius_m = {self.surface_radius_m!r}")
        if abs(self.initial.mass_kg - self.vehicle.mass_kg) > 1e-9 * self.vehicle.mass_kg:
            raise ValueError(f"{self.name}: initial.mass_kg = {self.initial.mass_kg!r} must equal "
                             f"vehicle.mass_kg = {self.vehicle.mass_kg!r}")
        lo = self.initial.radius_m + self.dispersion.altitude_m[0]
        if lo <= self.surface_radius_m:
            raise ValueError(f"{self.name}: dispersion.altitude_m = {self.dispersion.altitude_m!r}"
                             " reaches below the surface; the lowest start must stay above it")
        mlo = self.vehicle.mass_kg + self.dispersion.mass_kg[0]
        if mlo <= self.vehicle.dry_mass_kg:
            raise ValueError(f"{self.name}: dispersion.mass_kg = {self.dispersion.mass_kg!r} "
                             "allows a start at or below the dry mass")

    def scaling(self) -> Scaling:
        """Normalisation of [000] eq. (5): L = r0, m_ref = m0."""
        return Scaling(self.initial.radius_m, self.body.mu_m3_s2, self.vehicle.mass_kg)

    def params(self, scaling: Scaling | None = None) -> PlanarParams:
        s = scaling or self.scaling()
        return PlanarParams(float(s.force_nd(self.vehicle.thrust_n)),
                            float(s.velocity_nd(self.vehicle.exhaust_velocity_m_s)))

    def state_nd(self, state: PlanarState | None = None, scaling: Scaling | None = None
                 ) -> np.ndarray:
        """Normalised state vector (r, vr, θ, ω, m), shape (5,)."""
        s = scaling or self.scaling()
        st = state or self.initial
        return np.array([
            s.length_nd(st.radius_m), s.velocity_nd(st.radial_velocity_m_s), st.theta_rad,
            s.rate_nd(st.angular_rate_rad_s), s.mass_nd(st.mass_kg)], dtype=np.float64)

    def sample_initial(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """Draw ``n`` initial states from the dispersion; SI columns (r, vr, θ, v_t, m).

        Returns ndarray, shape (n, 5).
        """
        d = self.dispersion
        st = self.initial

        def u(rg):
            return rng.uniform(rg[0], rg[1], size=n) if rg[1] > rg[0] else np.full(n, rg[0])

        return np.stack([
            st.radius_m + u(d.altitude_m),
            st.radial_velocity_m_s + u(d.radial_velocity_m_s),
            st.theta_rad + u(d.theta_rad),
            st.tangential_velocity_m_s + u(d.tangential_velocity_m_s),
            st.mass_kg + u(d.mass_kg),
        ], axis=1)

    def si_to_nd(self, si: np.ndarray, scaling: Scaling | None = None) -> np.ndarray:
        """SI rows (r m, vr m/s, θ rad, v_t m/s, m kg) -> normalised (r, vr, θ, ω, m)
        (:func:`lunar_env.states.planar_si_to_nd`)."""
        return planar_si_to_nd(si, scaling or self.scaling())

    def nd_to_si(self, nd: np.ndarray, scaling: Scaling | None = None) -> np.ndarray:
        """Normalised rows (r, vr, θ, ω, m) -> SI (r m, vr m/s, θ rad, v_t m/s, m kg)
        (:func:`lunar_env.states.planar_nd_to_si`)."""
        return planar_nd_to_si(nd, scaling or self.scaling())

    def check_state_si(self, row, name: str = "initial_state_si") -> np.ndarray:
        """Validate an SI row against this scenario (finite, r > 0, mass above the dry mass)."""
        return check_planar_state_si(row, dry_mass_kg=self.vehicle.dry_mass_kg, name=name)


# ---------------------------------------------------------------------------------------------
# 3D pinpoint landing on a rotating Moon ([001])
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PinpointState:
    """Initial state in the paper's variables.

    Attributes
    ----------
    altitude_m : float
    longitude_rad, latitude_rad : float
    u_m_s, v_m_s, w_m_s : float
        Velocity relative to the rotating Moon in the orbital frame: radial, along-track,
        cross-track.
    inclination_rad : float
        Inclination to the equator of the Moon-fixed plane containing r0 and V0; with the
        latitude this fixes the heading of the along-track axis (motion toward the north-east
        for a positive inclination below 90°).
    mass_kg : float
    """

    altitude_m: float
    longitude_rad: float
    latitude_rad: float
    u_m_s: float
    v_m_s: float
    w_m_s: float
    inclination_rad: float
    mass_kg: float

    def __post_init__(self) -> None:
        _check_finite(self, "longitude_rad", "latitude_rad", "u_m_s", "v_m_s", "w_m_s",
                      "inclination_rad")
        _check_positive(self, "altitude_m", "mass_kg")
        if abs(math.cos(self.inclination_rad)) > abs(math.cos(self.latitude_rad)) + 1e-15:
            raise ValueError(
                f"PinpointState.inclination_rad = {self.inclination_rad!r} cannot pass through "
                f"latitude {self.latitude_rad!r}; need |cos i| <= |cos φ|")


@dataclass(frozen=True)
class PinpointTarget:
    """Target point and terminal relative velocity (orbital-frame components)."""

    altitude_m: float
    longitude_rad: float
    latitude_rad: float
    u_m_s: float = 0.0
    v_m_s: float = 0.0
    w_m_s: float = 0.0

    def __post_init__(self) -> None:
        _check_finite(self, "altitude_m", "longitude_rad", "latitude_rad", "u_m_s", "v_m_s",
                      "w_m_s")
        if self.altitude_m < 0:
            raise ValueError(f"PinpointTarget.altitude_m = {self.altitude_m!r} is below the "
                             "surface; it must be >= 0")


@dataclass(frozen=True)
class PinpointDispersion:
    """Ranges (low, high) of offsets from the nominal initial state, drawn uniformly."""

    altitude_m: tuple[float, float] = (0.0, 0.0)
    speed_m_s: tuple[float, float] = (0.0, 0.0)
    mass_kg: tuple[float, float] = (0.0, 0.0)
    longitude_rad: tuple[float, float] = (0.0, 0.0)
    latitude_rad: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        for f in fields(self):
            require_range(f"PinpointDispersion.{f.name}", getattr(self, f.name))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


@dataclass(frozen=True)
class PinpointScenario:
    """3D pinpoint landing on a rotating Moon ([001]).

    Attributes
    ----------
    name, reference : str
    body, vehicle : Body, Vehicle
    initial : PinpointState
    target : PinpointTarget
    dispersion : PinpointDispersion
    tf_bounds_s : (float, float)
    alpha_bounds_rad, beta_bounds_rad : (float, float)
        Path constraints on the thrust elevation and azimuth.
    uw_bound_m_s : float
        Path constraint |u|, |w| <= bound.
    fuel_max_kg : float
        Propellant budget (path constraint on the fuel used).
    """

    name: str
    reference: str
    body: Body
    vehicle: Vehicle
    initial: PinpointState
    target: PinpointTarget
    dispersion: PinpointDispersion = field(default_factory=PinpointDispersion)
    tf_bounds_s: tuple[float, float] = (0.0, 1e4)
    alpha_bounds_rad: tuple[float, float] = (-math.pi / 2, math.pi / 2)
    beta_bounds_rad: tuple[float, float] = (0.0, 2 * math.pi)
    uw_bound_m_s: float = math.inf
    fuel_max_kg: float = math.inf

    model = "moon3d"
    #: the env family of the scenario (:class:`lunar_env.families.FamilyRegistry`)
    family = "pinpoint"

    def __post_init__(self) -> None:
        # The same checks as PlanarScenario, in the pinpoint geometry: every state the
        # dispersion can draw starts above the terminal gate (the target's altitude) with
        # propellant, so env resets and optimisers never meet an impossible start.
        _check_tf_bounds(self.name, self.tf_bounds_s)
        for n in ("alpha_bounds_rad", "beta_bounds_rad"):
            require_range(f"{self.name}.{n}", getattr(self, n))
        if abs(self.initial.mass_kg - self.vehicle.mass_kg) > 1e-9 * self.vehicle.mass_kg:
            raise ValueError(f"{self.name}: initial.mass_kg = {self.initial.mass_kg!r} must equal "
                             f"vehicle.mass_kg = {self.vehicle.mass_kg!r}")
        if not self.target.altitude_m < self.initial.altitude_m:
            raise ValueError(f"{self.name}: target.altitude_m = {self.target.altitude_m!r} is not "
                             f"below initial.altitude_m = {self.initial.altitude_m!r}; the lander "
                             "descends to the target")
        if self.initial.altitude_m + self.dispersion.altitude_m[0] <= self.target.altitude_m:
            raise ValueError(f"{self.name}: dispersion.altitude_m = {self.dispersion.altitude_m!r}"
                             " allows a start at or below the target's altitude "
                             f"{self.target.altitude_m!r} m (the terminal gate); the lowest start "
                             "must stay above it")
        if self.vehicle.mass_kg + self.dispersion.mass_kg[0] <= self.vehicle.dry_mass_kg:
            raise ValueError(f"{self.name}: dispersion.mass_kg = {self.dispersion.mass_kg!r} "
                             "allows a start at or below the dry mass "
                             f"{self.vehicle.dry_mass_kg!r} kg")
        for n in ("uw_bound_m_s", "fuel_max_kg"):  # inf = no constraint; NaN and <= 0 refused
            v = getattr(self, n)
            if not (isinstance(v, numbers.Real) and not isinstance(v, bool) and v > 0):
                raise ValueError(f"{self.name}.{n} = {v!r} must be > 0 (math.inf: no bound)")

    def scaling(self) -> Scaling:
        """Normalisation of [001] eq. (11): L = R_L, m_ref = m0."""
        return Scaling(self.body.radius_m, self.body.mu_m3_s2, self.vehicle.mass_kg)

    # -- geometry ---------------------------------------------------------------------------
    def initial_position_velocity_m(self, state: PinpointState | None = None
                                    ) -> tuple[np.ndarray, np.ndarray]:
        """Moon-fixed Cartesian r0 (m) and V0 (m/s) of the initial state.

        The along-track axis at r0 is the horizontal unit vector whose great circle has the
        stated inclination, heading north-east (azimuth from north ψ with sin ψ = cos i / cos φ,
        [001] "initial orbit inclination 30°"). The paper's y axis is that direction, so
        V0 = u x̂ + v ŷ + w ẑ with ẑ = x̂ × ŷ.
        """
        st = state or self.initial
        r = self.body.radius_m + st.altitude_m
        lam, phi = st.longitude_rad, st.latitude_rad
        up = np.array([math.cos(phi) * math.cos(lam), math.cos(phi) * math.sin(lam),
                       math.sin(phi)])
        east = np.array([-math.sin(lam), math.cos(lam), 0.0])
        north = np.cross(up, east)
        sin_psi = np.clip(math.cos(st.inclination_rad) / math.cos(phi), -1.0, 1.0)
        psi = math.asin(sin_psi)
        along = math.cos(psi) * north + math.sin(psi) * east
        cross = np.cross(up, along)
        v = st.u_m_s * up + st.v_m_s * along + st.w_m_s * cross
        return r * up, v

    def plane_normal(self) -> tuple[float, float, float]:
        """n̂ of the nominal initial orbit plane (Moon-fixed); defines the orbital frame."""
        r0, _ = self.initial_position_velocity_m()
        st = self.initial
        # the along-track direction (not V0, which may have u or w components)
        probe = PinpointState(st.altitude_m, st.longitude_rad, st.latitude_rad, 0.0, 1.0, 0.0,
                              st.inclination_rad, st.mass_kg)
        _, along = self.initial_position_velocity_m(probe)
        n = _unit(np.cross(r0, along))
        return (float(n[0]), float(n[1]), float(n[2]))

    def params(self, scaling: Scaling | None = None) -> Moon3DParams:
        s = scaling or self.scaling()
        return Moon3DParams(float(s.force_nd(self.vehicle.thrust_n)),
                            float(s.velocity_nd(self.vehicle.exhaust_velocity_m_s)),
                            float(s.rate_nd(self.body.spin_rate_rad_s)), self.plane_normal())

    def state_nd(self, state: PinpointState | None = None, scaling: Scaling | None = None
                 ) -> np.ndarray:
        """Normalised Moon-fixed state (x, y, z, vx, vy, vz, m), shape (7,)."""
        s = scaling or self.scaling()
        st = state or self.initial
        r, v = self.initial_position_velocity_m(st)
        return np.concatenate([s.length_nd(r), s.velocity_nd(v), [s.mass_nd(st.mass_kg)]])

    def target_position_m(self) -> np.ndarray:
        """Moon-fixed position of the target point (m), shape (3,)."""
        t = self.target
        r = self.body.radius_m + t.altitude_m
        return r * np.array([math.cos(t.latitude_rad) * math.cos(t.longitude_rad),
                             math.cos(t.latitude_rad) * math.sin(t.longitude_rad),
                             math.sin(t.latitude_rad)])

    def sample_initial(self, rng: np.random.Generator, n: int) -> list[PinpointState]:
        """Draw ``n`` initial states from the dispersion."""
        d = self.dispersion
        st = self.initial

        def u(rg):
            return rng.uniform(rg[0], rg[1], size=n) if rg[1] > rg[0] else np.full(n, rg[0])

        dh, dv, dm, dl, dp = (u(d.altitude_m), u(d.speed_m_s), u(d.mass_kg),
                              u(d.longitude_rad), u(d.latitude_rad))
        return [PinpointState(st.altitude_m + dh[k], st.longitude_rad + dl[k],
                              st.latitude_rad + dp[k], st.u_m_s, st.v_m_s + dv[k], st.w_m_s,
                              st.inclination_rad, st.mass_kg + dm[k]) for k in range(n)]


@dataclass(frozen=True)
class TouchdownScenario(PinpointScenario):
    """A pinpoint landing that ends at touchdown on the target, with a throttleable engine.

    The geometry, dynamics and fields are :class:`PinpointScenario`'s; the target lies on the
    landing surface (``target.altitude_m`` is the height of the site above the reference sphere,
    0 on it), and the engine throttles between ``throttle_min`` and 1 of ``vehicle.thrust_n``.

    The family differs from ``"pinpoint"``: the per-case optimum is another problem (minimum
    propellant with the throttle's max–min–max arcs, not [001]'s constant-thrust minimum time)
    and a thrust command's throttle maps onto [throttle_min, 1], so the optimum and the
    guidance encoder of the family are their own (:mod:`optimizers.optimum.touchdown`,
    :mod:`guidance.families.touchdown`).

    Attributes
    ----------
    throttle_min : float
        Lowest throttle of the running engine, a fraction of ``vehicle.thrust_n`` in (0, 1):
        the engine is lit for the whole descent and throttles in [throttle_min, 1] (it stops
        only when the propellant is exhausted).
    """

    throttle_min: float = 0.2

    family = "pinpoint_touchdown"

    def __post_init__(self) -> None:
        super().__post_init__()
        v = self.throttle_min
        if not (isinstance(v, numbers.Real) and not isinstance(v, bool) and 0.0 < v < 1.0):
            raise ValueError(f"{self.name}.throttle_min = {v!r} is not allowed; it must be in "
                             "(0, 1) (a fraction of the maximum thrust)")

    @property
    def thrust_min_n(self) -> float:
        """Lowest thrust of the running engine (N)."""
        return self.throttle_min * self.vehicle.thrust_n


# ---------------------------------------------------------------------------------------------
# Two-impulse transfer / interception ([004])
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ImpulsiveTransferScenario:
    """Free-time two-impulse transfer or interception between two given states ([004]).

    Attributes
    ----------
    r1_m, v1_m_s : 3-tuples
        Departure position and velocity before the first impulse.
    r2_m, v2_m_s : 3-tuples
        Arrival position and the velocity to match (transfer) at the second impulse.
    time_bounds_s : (float, float)
        Bounds of the transfer time T.
    """

    name: str
    reference: str
    body: Body
    r1_m: tuple[float, float, float]
    v1_m_s: tuple[float, float, float]
    r2_m: tuple[float, float, float]
    v2_m_s: tuple[float, float, float]
    time_bounds_s: tuple[float, float]

    model = "impulsive"

    def __post_init__(self) -> None:
        for n in ("r1_m", "v1_m_s", "r2_m", "v2_m_s"):
            v = getattr(self, n)
            if len(v) != 3:
                raise ValueError(f"{self.name}.{n} = {v!r} must have 3 components")
            require_finite(f"{self.name}.{n}", v)
        require_range(f"{self.name}.time_bounds_s", self.time_bounds_s)
        if not self.time_bounds_s[0] > 0:
            raise ValueError(f"{self.name}.time_bounds_s = {self.time_bounds_s!r}: T must be > 0")
        for n in ("r1_m", "r2_m"):
            if np.linalg.norm(getattr(self, n)) <= self.body.radius_m:
                raise ValueError(f"{self.name}.{n} = {getattr(self, n)!r} is inside the body")


# ---------------------------------------------------------------------------------------------
# Registry
# ---------------------------------------------------------------------------------------------

_REGISTRY: dict[str, object] = {}


def register_scenario(scenario, *aliases: str, overwrite: bool = False) -> None:
    """Add a scenario to the registry under its name (and aliases)."""
    for key in (scenario.name, *aliases):
        if key in _REGISTRY and not overwrite:
            raise ValueError(f"scenario {key!r} is already registered; pass overwrite=True")
        _REGISTRY[key] = scenario


def get_scenario(name: str):
    """Return the registered scenario ``name``.

    Raises
    ------
    KeyError
        Naming the registered scenarios.
    """
    try:
        return _REGISTRY[name]
    except KeyError:
        raise KeyError(f"unknown scenario {name!r}; registered: {sorted(_REGISTRY)}") from None


def list_scenarios() -> list[str]:
    return sorted(_REGISTRY)


_deg = math.radians

# [000] Zhu & Xu 2007: r0 = 1753 km, v0 = 0, ω0 = 9.65e-4 rad/s, m0 = 600 kg, F = 1350 N,
# Isp = 300·9.8 m/s; rf = 1738 km, vf = ωf = 0; tf in [500, 700] s (eq. 24-25).
# Dry mass: not stated; the same 600 kg lander as [001] with its 300 kg propellant budget.
ZHU2007 = PlanarScenario(
    name="zhu2007",
    reference="[000] Zhu & Xu 2007, Acta Aeronautica et Astronautica Sinica 28(4)",
    body=MOON,
    vehicle=Vehicle(mass_kg=600.0, thrust_n=1350.0, isp_s=300.0, dry_mass_kg=300.0),
    initial=PlanarState(1753.0e3, 0.0, 0.0, 9.65e-4 * 1753.0e3, 600.0),
    target=PlanarTarget(1738.0e3, 0.0, 0.0),
    dispersion=PlanarDispersion(altitude_m=(-1000.0, 1000.0),
                                tangential_velocity_m_s=(-15.0, 15.0),
                                mass_kg=(-20.0, 20.0), theta_rad=(-0.01, 0.01)),
    tf_bounds_s=(500.0, 700.0),
)

# [001] Peng et al. 2012, eq. (20). The initial velocity is along-track (u0 = w0 = 0) in the
# plane inclined 30° to the equator through (10°E, 0°N), heading north-east: that plane's
# ground track passes (25.95°E, 9°N), next to the target (25°E, 9°N), which the lander reaches
# with a small cross-range correction. (Reading the 30° as the inertial orbit's inclination
# instead changes the heading by under 0.2°: Ω·r0 = 4.7 m/s against 1713.8 m/s.)
PENG2012 = PinpointScenario(
    name="peng2012",
    reference="[001] Peng, Li, Shen, Tang 2012, J. National Univ. Defense Tech. 34(2)",
    body=MOON_ROTATING,
    vehicle=Vehicle(mass_kg=600.0, thrust_n=1500.0, isp_s=300.0, dry_mass_kg=300.0),
    initial=PinpointState(altitude_m=15.0e3, longitude_rad=_deg(10.0), latitude_rad=0.0,
                          u_m_s=0.0, v_m_s=1713.8, w_m_s=0.0, inclination_rad=_deg(30.0),
                          mass_kg=600.0),
    target=PinpointTarget(altitude_m=2.0e3, longitude_rad=_deg(25.0), latitude_rad=_deg(9.0)),
    dispersion=PinpointDispersion(altitude_m=(-500.0, 500.0), speed_m_s=(-5.0, 5.0),
                                  mass_kg=(-10.0, 10.0), longitude_rad=(-_deg(0.05), _deg(0.05)),
                                  latitude_rad=(-_deg(0.05), _deg(0.05))),
    tf_bounds_s=(300.0, 800.0),
    alpha_bounds_rad=(_deg(-50.0), _deg(40.0)),
    beta_bounds_rad=(_deg(130.0), _deg(220.0)),
    uw_bound_m_s=110.0,
    fuel_max_kg=300.0,
)

# [001]'s start continued to touchdown on the target (25°E, 9°N) on the reference sphere, through
# approach and terminal descent (LunarPinpointLanding-v3). Start, dispersion, body, thrust and Isp
# are peng2012's. The thrust elevation may reach the vertical (a lander hovers and descends
# vertically at the end) and the azimuth covers the whole circle (terminal descent corrects
# its horizontal velocity in any direction); [001]'s |u|, |w| <= 110 m/s belong to its braking
# phase and are not carried over.
# Throttle: the engine class of Chang'e-3's 7500 N variable-thrust engine, throttled
# continuously from 1500 N to 7500 N (SASTIND / Xinhua, 5 Dec 2013; the engine's development:
# Sci. Sin. Technol. 44(6), 2014), i.e. throttle_min = 1500/7500 = 0.2 of full thrust.
# Propellant: peng2012's 300 kg load is kept (dry mass 300 kg), a decision measured against a
# flown margin. The nominal minimum-fuel landing to touchdown with this throttle uses 277.58 kg
# (optimizers.optimum.touchdown, two methods agreeing), leaving 22.4 kg: 126 s of hover at the
# touchdown mass (322 kg, 1.623 m/s², c = 2940 m/s). Apollo's landings touched down with 45 s
# (Apollo 11) to 117 s (Apollo 17) of hover propellant left (Apollo Lunar Surface Journal,
# landing commentaries). The dispersion's most demanding start (the corner of the box with the
# lightest tank) keeps 16.7 kg, 96 s: more than Apollo 11's (tests/optimizers/
# test_touchdown_optimum.py measures both). A larger load would only add margin the guidance
# laws are not asked to need; a smaller one would leave less than Apollo 11 at the corners.
PENG2012_TOUCHDOWN = TouchdownScenario(
    name="peng2012_touchdown",
    reference="[001] Peng, Li, Shen, Tang 2012 (start, vehicle), continued to touchdown",
    body=MOON_ROTATING,
    vehicle=PENG2012.vehicle,
    initial=PENG2012.initial,
    target=PinpointTarget(altitude_m=0.0, longitude_rad=_deg(25.0), latitude_rad=_deg(9.0)),
    dispersion=PENG2012.dispersion,
    tf_bounds_s=PENG2012.tf_bounds_s,
    alpha_bounds_rad=(_deg(-50.0), _deg(90.0)),
    beta_bounds_rad=(0.0, 2 * math.pi),
    throttle_min=1500.0 / 7500.0,
)

# [003] Wang et al. 2003: m0 = 500 kg, Isp = 300 s, T in [0, 4] kN (vehicle thrust = the upper
# bound; the design thrust is a throttle on it), h0 = 15 km, v_t0 = 1692.04 m/s. μ and R_L are
# not stated: those of [000]. Dry mass: not stated; 150 kg leaves the 44.38 % burn room.
WANG2003 = PlanarScenario(
    name="wang2003",
    reference="[003] Wang, Li, Cui, Liu 2003, J. Tsinghua Univ. 43(8)",
    body=MOON,
    vehicle=Vehicle(mass_kg=500.0, thrust_n=4000.0, isp_s=300.0, dry_mass_kg=150.0),
    initial=PlanarState(1753.0e3, 0.0, 0.0, 1692.04, 500.0),
    target=PlanarTarget(1738.0e3, 0.0, 0.0),
    dispersion=PlanarDispersion(altitude_m=(-1000.0, 1000.0),
                                tangential_velocity_m_s=(-15.0, 15.0), mass_kg=(-10.0, 10.0)),
    tf_bounds_s=(100.0, 800.0),
)

# [002] Earth–Mars low-thrust transfer: heliocentric, circular coplanar orbits. w is given as
# an exhaust velocity (3.726527e4 m/s); it is stored as Isp with standard g0. Dry mass: not
# stated; 400 kg leaves more than the ~250 kg a >200-day 0.5 N burn uses.
_AU = 1.496e11
PENG_MARS = PlanarScenario(
    name="peng_mars",
    reference="[002] Peng, Xu, Guo, Wang: guiding artificial immune algorithm, Earth–Mars",
    body=SUN,
    vehicle=Vehicle(mass_kg=800.0, thrust_n=0.5, isp_s=3.726527e4 / G0_STANDARD_M_S2,
                    dry_mass_kg=400.0, g0_m_s2=G0_STANDARD_M_S2),
    initial=PlanarState(_AU, 0.0, _deg(-10.0), math.sqrt(1.32715e20 / _AU), 800.0),
    target=PlanarTarget(2.2794e11, 0.0, math.sqrt(1.32715e20 / 2.2794e11)),
    dispersion=PlanarDispersion(mass_kg=(-10.0, 10.0)),
    # normalised tf in [3.5, 4] time units of sqrt(r0³/μ)
    tf_bounds_s=(3.5 * math.sqrt(_AU**3 / 1.32715e20), 4.0 * math.sqrt(_AU**3 / 1.32715e20)),
)

# [004] Wang et al. 2001: Earth, R1, V1 before the first impulse; R2, V2 at arrival.
WANG2001 = ImpulsiveTransferScenario(
    name="wang2001",
    reference="[004] Wang, Zhu, Dai, Ren 2001, J. National Univ. Defense Tech. 23(5)",
    body=EARTH,
    r1_m=(0.0, 7_380_000.0, 0.0),
    v1_m_s=(7349.21, 0.0, 0.0),
    r2_m=(6_401_659.785, 3_696_000.0, 0.0),
    v2_m_s=(3671.622, -6359.435, 0.0),
    time_bounds_s=(100.0, 10_000.0),
)

register_scenario(ZHU2007)
register_scenario(PENG2012)
register_scenario(PENG2012_TOUCHDOWN)
register_scenario(WANG2003)
register_scenario(PENG_MARS)
register_scenario(WANG2001, "wang2001_transfer")
