"""Apollo lunar-descent guidance in fifteen lines, as a user writes a law in their own module.

The law reads the navigated state in the env's guidance frame (``nav.frame``: target position
and velocity along the local horizontal axes and up, the known acceleration g, the mass
estimate) and commands a thrust direction and throttle; the env encodes it into its actions,
so the same law flies the planar and the pinpoint envs. It is [K74]'s law (Klumpp, "Apollo
lunar descent guidance", Automatica 10, 1974) at k_r = 12 with the target at rest and a_T = 0,
the time to go chosen so that the command equals the engine's T/m (a constant-thrust engine
then flies it exactly). The library's ``apollo`` law adds the options (gain, t_go rules, lead
time, aim point, the pointing-bound target acceleration).

Fly it in a campaign, beside the library's laws (the module registers ``apollo-15``)::

    lunar campaign --import examples/apollo_in_15_lines.py --laws apollo-15 apollo \\
        --env LunarSoftLanding-v0 --env-kwargs '{"dt_s": 2.5}' --cases 100
"""

import numpy as np

from guidance import GuidanceLaw, ThrustCommand, register_law
from guidance.explicit import augmented_apollo_thrust, free_position_thrust, thrust_matched_tgo


class Apollo(GuidanceLaw):
    name = "apollo-15"

    def act(self, nav):
        f = nav.frame
        a_max = self.computer.thrust_n / f.mass_kg  # what the engine gives (m/s²)

        def command(t_go, rows):  # the thrust acceleration of [K74]'s law at this t_go
            a = augmented_apollo_thrust(0.0, f.v[rows], f.r_to_target[rows], 0.0, 0.0,
                                        f.g[rows], t_go, 12.0, check=False)
            for ax in f.free_axes:  # an axis without a target: the free-end optimum
                a[:, ax] = free_position_thrust(f.v[rows, ax:ax + 1], 0.0,
                                                f.g[rows, ax:ax + 1], t_go, check=False)[:, 0]
            return a

        t_go = thrust_matched_tgo(command, a_max, 0.05, 3000.0, "long")[0]
        a = command(t_go, slice(None))
        return ThrustCommand(a, np.linalg.norm(a, axis=1) / a_max)


register_law("apollo-15", lambda spec, context: Apollo(),
             summary="Apollo in fifteen lines (examples/apollo_in_15_lines.py)")
