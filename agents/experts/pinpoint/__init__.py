"""The 3D pinpoint family (``LunarPinpointLanding-v*``): ``expert`` (the Pontryagin feedback
expert), ``optimum`` (the per-case optimum's cache and its open-loop law), ``data`` (datasets and
DAgger labels), ``features`` (its observation features), ``family`` (:class:`PinpointFamily`)."""
