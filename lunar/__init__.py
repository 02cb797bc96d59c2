"""``lunar``: one command line for the project's jobs (:mod:`lunar.cli`)."""
