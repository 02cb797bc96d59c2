"""Monte Carlo campaigns: every law on the same dispersed cases, against each case's omniscient
optimum (:mod:`.run`), their statistics, plots and command line
(``python -m guidance.campaign``)."""
