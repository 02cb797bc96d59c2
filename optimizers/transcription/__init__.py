"""Direct transcriptions of optimal-control problems (:class:`optimizers.common.ocp.OCP`):
Gauss pseudospectral collocation (:mod:`.gpm`), direct shooting (:mod:`.direct_shooting`), the
serial GPM → shooting strategy of [001] (:mod:`.serial`) and its per-case optima over a batch
of initial states (:mod:`.batch`), Hermite–Simpson collocation (:mod:`.collocation`),
polynomial single shooting (:mod:`.polynomial_shooting`) and successive convexification as
second-order cone programs (:mod:`.convex`, needs the ``convex`` extra: cvxpy, Clarabel)."""
