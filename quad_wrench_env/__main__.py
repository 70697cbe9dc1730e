"""``python -m quad_wrench_env``: the ``quad-wrench`` command line (:mod:`quad_wrench_cli`), the one place
under ``quad_wrench_env/`` that reaches the agents (through the command line's modules)."""

import sys

if __name__ == "__main__":
    from quad_wrench_cli.main import main

    sys.exit(main(prog="python -m quad_wrench_env"))
