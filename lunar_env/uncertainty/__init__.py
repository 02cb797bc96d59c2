"""Plant and navigation errors: the uncertainty model of the landing envs (SI, 1σ).

A GNC engineer judges a guidance law by Monte Carlo campaigns over the errors of the real
world. :class:`UncertaintyModel` is a frozen, validated set of 1σ errors that the envs draw
once per episode (and, for navigation noise, once per decision):

**Entry** (the state at powered-descent initiation): position errors along the local up,
downrange and crossrange axes (m) and velocity errors along the same axes (m/s), added to the
planned start (the scenario's dispersed draw, or the state pinned by ``reset`` options).

**Plant**: thrust scale error (relative, 1σ), specific-impulse scale error (relative),
thrust-direction misalignment (rad, a fixed bias per episode on each gimbal angle: the planar
thrust angle φ; the pinpoint elevation α and azimuth β), and initial wet-mass error (kg). The
flight computer is not told any of them.

**Navigation**: the observation encodes the *navigated* state, the truth plus an error in
position (m) and velocity (m/s) along up, downrange, crossrange. Before the terminal sensors
acquire the ground, navigation propagates the orbit determination with the IMU: a bias per
episode and white noise per decision, worst at altitude. ``sensor_altitude_m`` is where the
terminal sensors (an altimeter and velocimeter, a landing radar or Doppler lidar, with
terrain-relative navigation for the horizontal position) acquire: below it, over a short
hand-over band, the error becomes theirs, drawn independently of the inertial solution's: a
per-episode error and a per-decision noise that are fractions of the altitude (a range
sensor's error is a fraction of its range) plus a per-episode floor (the terrain map's), and
the velocimeter's bias and noise. The flight computer's mass estimate is the planned initial
mass minus the propellant it believes burnt, so it misses by the wet mass error (a constant
offset).

**IMU**: the accelerometers measure the specific force, the true thrust acceleration along
the misaligned thrust axis, with a bias per axis and a scale-factor error per episode and
white noise per decision (the velocity random walk over the decision interval). The envs give
it to the flight computer (:meth:`~lunar_env.envs.base.LanderVectorEnv.sensor_readings`), and
to a policy as observation channels with ``sensors=("imu",)``.

The model's fields fall into four groups (:data:`GROUPS`: entry, engine, navigation,
sensors); a named set isolates each, and :meth:`UncertaintyModel.without` leaves one out.
:data:`MODEL_VERSION` names the model's meaning; campaigns record it.

Every draw is a standard normal truncated at ±:data:`TRUNCATION_SIGMA` times its σ, so the
plant scale factors stay positive and a single freak draw cannot dominate a campaign's tail.
Every σ has a documented upper limit (:data:`SIGMA_LIMITS`), checked when the model is built.

**Common random numbers.** The errors of an episode come from a stream of their own, seeded by
the episode's reset seed (:func:`error_stream`): case k of a campaign (sub-env k reset with
``seed + k``) sees the same errors whatever the number of landers, the workers or the law
flown, and the same standard-normal draws under every scale of the model
(:meth:`UncertaintyModel.scaled`), so a robustness curve is smooth. The per-decision noise is
a counter-based function of the episode's key and the decision index
(:func:`navigation_noise`), so it too is the same whatever the batch; the sensors' draws are
counter-based streams of that key's own, so the inertial solution's draws do not depend on
whether the model has sensors.

Named sets (:data:`NAMED_SETS`): ``none`` (no error at all; the envs are bit for bit those
without the model), ``standard``, ``stress`` (3 × standard), and ``entry``, ``engine``,
``navigation``, ``sensors`` (``standard``'s errors of that group alone). Build your own::

    from lunar_env.uncertainty import UncertaintyModel, get_uncertainty
    mine = get_uncertainty("standard").replace(thrust_scale=0.05)
    env = gym.make("LunarSoftLanding-v0", uncertainty=mine)      # or uncertainty="standard"

The package, one job a module:

=============================  ===============================================================
``model``                      :class:`UncertaintyModel` (the frozen spec, its σ limits),
                               the named sets, :func:`get_uncertainty`,
                               :func:`resolve_uncertainty`
``episode``                    :class:`EpisodeErrors` (an episode's draws, and how they act:
                               true start, plant parameters, gimbal angles, navigation
                               errors), :func:`error_stream`
``navigation``                 the per-decision noise (:func:`navigation_noise`) and the one
                               navigation-error kernel the tasks' compiled navigation calls
=============================  ===============================================================
"""

from ._random import TRUNCATION_SIGMA
from .episode import N_NORMALS, EpisodeErrors, error_stream
from .model import (
    GROUPS,
    MODEL_VERSION,
    NAMED_SETS,
    SIGMA_LIMITS,
    UncertaintyModel,
    get_uncertainty,
    resolve_uncertainty,
)
from .navigation import navigation_noise

__all__ = ["UncertaintyModel", "EpisodeErrors", "NAMED_SETS", "SIGMA_LIMITS", "GROUPS",
           "MODEL_VERSION", "get_uncertainty",
           "resolve_uncertainty", "error_stream", "navigation_noise", "TRUNCATION_SIGMA",
           "N_NORMALS"]
