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

**Navigation**: the observation encodes the *navigated* state, the truth plus a bias per
episode and white noise per decision, in position (m) and velocity (m/s) along up, downrange,
crossrange. Before a landing radar acquires the ground, navigation propagates the orbit
determination and is worst at altitude. ``radar_altitude_m`` is where the terminal sensors
(a landing radar or Doppler lidar, with terrain-relative navigation) lock: there the errors
(bias and noise) drop to ``radar_lock_fraction`` of themselves and below it they shrink in
proportion to the altitude (a range sensor's error is a fraction of its range) down to the
floors ``near_ground_position_fraction`` (position) and ``near_ground_velocity_fraction``
(velocity) of themselves. The flight computer's mass estimate
is the planned initial mass minus the propellant it believes burnt, so it misses by the wet
mass error (a constant offset).

Every draw is a standard normal truncated at ±:data:`TRUNCATION_SIGMA` times its σ, so the
plant scale factors stay positive and a single freak draw cannot dominate a campaign's tail.
Every σ has a documented upper limit (:data:`SIGMA_LIMITS`), checked when the model is built.

**Common random numbers.** The errors of an episode come from a stream of their own, seeded by
the episode's reset seed (:func:`error_stream`): case k of a campaign (sub-env k reset with
``seed + k``) sees the same errors whatever the number of landers, the workers or the law
flown, and the same standard-normal draws under every scale of the model
(:meth:`UncertaintyModel.scaled`), so a robustness curve is smooth. The per-decision noise is
a counter-based function of the episode's key and the decision index
(:func:`navigation_noise`), so it too is the same whatever the batch.

Named sets (:data:`NAMED_SETS`): ``none`` (no error at all; the envs are bit for bit those
without the model), ``standard`` and ``stress`` (3 × standard). Build your own the same way::

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
    MODEL_VERSION,
    NAMED_SETS,
    SIGMA_LIMITS,
    UncertaintyModel,
    get_uncertainty,
    resolve_uncertainty,
)
from .navigation import navigation_noise

__all__ = ["UncertaintyModel", "EpisodeErrors", "NAMED_SETS", "SIGMA_LIMITS", "get_uncertainty",
           "resolve_uncertainty", "error_stream", "navigation_noise", "TRUNCATION_SIGMA",
           "N_NORMALS", "MODEL_VERSION"]
