"""Problems, each stated once: black-box :class:`~optimizers.common.problem.Problem` s for the
global optimisers and :class:`~optimizers.common.ocp.OCP` s for the transcriptions and the
indirect solvers, on the shared lunar_env dynamics."""

from .landing import PlanarLandingProblem
from .low_thrust import LowThrustTransferProblem
from .penalised import PenalisedProblem
from .pinpoint import PinpointOCP
from .planar_ocp import PlanarOCP
from .thrust_design import ThrustDesignProblem
from .two_impulse import TwoImpulseProblem

__all__ = ["PlanarLandingProblem", "PenalisedProblem", "PlanarOCP", "PinpointOCP",
           "TwoImpulseProblem", "LowThrustTransferProblem", "ThrustDesignProblem"]
