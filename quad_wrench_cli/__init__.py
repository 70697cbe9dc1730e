"""The ``quad-wrench`` command line (also ``python -m quad_wrench_env``): one subcommand per job.

:mod:`quad_wrench_cli.main` builds the parser from the command modules; each module exposes
``add_arguments(parser)`` and ``run(args) -> int`` and holds the job's own code (the former
``scripts/``). :mod:`quad_wrench_cli.common` has what they share: config files, argument types,
errors of the user's making (exit code 2) and output for the terminal and for tools.
"""
