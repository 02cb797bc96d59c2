"""The 3D pinpoint family (``LunarPinpointLanding-v*``): ``expert`` (the Pontryagin feedback
expert, and the one with a thrust reserve), ``engine_estimate`` (the engine's thrust from
navigation), ``terminal`` (the terminal window), ``optimum`` (the per-case optimum's cache and its
open-loop law), ``data`` (datasets and DAgger labels), ``features`` (its observation features),
``family`` (:class:`PinpointFamily`)."""
