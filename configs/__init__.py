"""The shipped config files, installed with the package as ``quad_wrench_env.configs``.

This folder stays at the top level (the docs and the configs' own comments name ``configs/...``);
``pyproject.toml`` maps it to the subpackage, and ``quad_wrench_env.config.config_path(name)`` finds a
file in any install. This file makes it a regular package, which an editable install needs to import it.
"""
