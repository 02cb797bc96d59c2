"""The 0.1 home of the planar Pontryagin solver; its names are re-exported from
:mod:`optimizers.indirect.planar` and :mod:`optimizers.indirect.batch` (see CHANGELOG.md).

``python -m optimizers.pontryagin`` still runs the command line, now
``python -m optimizers.indirect.cli``.
"""

from .indirect.batch import nearest_neighbour_order, solve_many
from .indirect.planar import (
    PontryaginGuess,
    PontryaginSolution,
    hamiltonian,
    nominal_guess,
    optimal_thrust_angle,
    replay_reference,
    solve_planar_min_fuel,
)

__all__ = ["PontryaginGuess", "PontryaginSolution", "solve_planar_min_fuel", "solve_many",
           "nominal_guess", "nearest_neighbour_order", "optimal_thrust_angle", "hamiltonian",
           "replay_reference"]

if __name__ == "__main__":
    from .indirect.cli import main

    raise SystemExit(main())
