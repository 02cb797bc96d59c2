"""The planar soft-landing family (``LunarSoftLanding-v0``): ``expert`` (the Pontryagin expert and
the planar laws), ``data`` (datasets and DAgger labels), ``family`` (:class:`PlanarFamily`)."""
