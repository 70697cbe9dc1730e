"""Classical controllers' equations for a batch of vehicles, below the agents and the envs: the agents fly
them for one vehicle, the env's ``residual`` action type for every vehicle of the env under a policy's
correction (:mod:`quad_wrench_env.control.residual`)."""
