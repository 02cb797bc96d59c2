"""The planar soft-landing family (``LunarSoftLanding-v0``): ``expert`` (the Pontryagin expert and
the planar laws), ``data`` (datasets and DAgger labels), ``features`` (its observation
features), ``family`` (:class:`PlanarFamily`)."""
