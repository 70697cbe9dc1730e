"""``python -m quad_wrench_env``: the ``quad-wrench`` command line (:mod:`quad_wrench_cli`)."""

import sys

if __name__ == "__main__":
    from quad_wrench_cli.main import main

    sys.exit(main(prog="python -m quad_wrench_env"))
