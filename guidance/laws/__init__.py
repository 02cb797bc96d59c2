"""The non-learned guidance laws, registered by name for law specs (:mod:`guidance.registry`).

=================  ===========================================================================
name               law
=================  ===========================================================================
``apollo``         augmented Apollo explicit guidance, k_r = 12 (:mod:`.apollo`)
``zem-zev``        the same law at k_r = 6 (ZEM/ZEV feedback)
``gravity-turn``   thrust against the surface-relative velocity
``open-loop``      each case's optimum (nominal plant, navigated start), replayed
``feedback``       the family's re-planning expert (:mod:`.feedback`; touchdown:
                   :mod:`.touchdown_baselines`)
``convex``         successive-convexification re-planning (:mod:`.convex`; needs cvxpy)
``min-time``       v3: the minimum-time Pontryagin feedback to touchdown, then terminal descent
                   (:mod:`.min_time_touchdown`)
``random``         uniform-random actions (the benchmark score's 0, :mod:`.random`)
=================  ===========================================================================

Each name maps to a lazy factory, so importing this package imports no law module.
"""

from guidance.registry import register_law

register_law("apollo", "guidance.laws.apollo_specs:apollo_from_spec",
             summary="augmented Apollo explicit guidance, k_r = 12 (options: kr, tgo, "
                     "tgo_margin, lead, rotation, terminal, aim; v3 phases: phased, "
                     "high_gate, hg_angle, hg_speed, low_gate, rate, switch, rate_tau, h_tau, "
                     "tilt; v3: min_time_slack)")
register_law("zem-zev", "guidance.laws.apollo_specs:zem_zev_from_spec",
             summary="ZEM/ZEV feedback guidance (augmented Apollo at k_r = 6; same options)")
register_law("gravity-turn", "guidance.laws.apollo_specs:gravity_turn_from_spec",
             summary="thrust against the surface-relative velocity (option: rotation)")
register_law("open-loop", "guidance.laws.feedback:open_loop_from_spec",
             summary="each case's optimum from the navigated start, replayed")
register_law("feedback", "guidance.laws.feedback:feedback_from_spec",
             summary="the family's Pontryagin re-planning expert (pinpoint options: "
                     "thrust_reserve, switch_m, stop_above_m, estimate_thrust, "
                     "terminal_window; touchdown options: every, min_tgo)")
register_law("convex", "guidance.laws.convex:convex_from_spec",
             summary="successive-convexification re-planning (options: every, nodes, iters, "
                     "first_iter, engine, tmax, min_tgo)")
register_law("min-time", "guidance.laws.min_time_touchdown:min_time_from_spec",
             summary="LunarPinpointLanding-v3: minimum-time Pontryagin feedback to touchdown "
                     "on the measured engine, then terminal descent (options: reserve, "
                     "stop_above, switch_tgo, switch_m)")
register_law("random", "guidance.laws.random:random_from_spec",
             summary="uniform-random actions (option: seed)")
