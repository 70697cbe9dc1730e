"""Gymnasium environments of quad-wrench-env: the single env (:mod:`.base`), the vector env
(:mod:`.vector`) and the classes generated for every task (:mod:`.env_classes`)."""
