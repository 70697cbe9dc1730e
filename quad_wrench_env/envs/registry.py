"""The env classes of every task, generated from :data:`quad_wrench_env.tasks.TASKS`: for a task
``Name``, ``NameEnv`` (single vehicle) and ``NameVectorEnv`` (``gym.make_vec``'s vector entry point),
attributes of this module, so that they pickle by reference and their entry points are strings."""

from __future__ import annotations

from typing import Any

from quad_wrench_env.envs.base import QuadWrenchEnv
from quad_wrench_env.envs.vector import QuadWrenchVectorEnv
from quad_wrench_env.tasks import TASKS


def entry_points(task: type) -> tuple[str, str]:
    """The single and the vector entry point of ``task``'s env id."""
    return f"{__name__}:{task.__name__}Env", f"{__name__}:{task.__name__}VectorEnv"


def env_classes(task: type) -> tuple[type, type]:
    """New single and vector env classes for ``task`` (named after it, in this module)."""
    single = type(
        f"{task.__name__}Env",
        (QuadWrenchEnv,),
        {"task_class": task, "__module__": __name__, "__doc__": f"``{task.env_id}``: {task.__doc__}"},
    )
    vector = type(
        f"{task.__name__}VectorEnv",
        (QuadWrenchVectorEnv,),
        {
            "env_class": single,
            "__module__": __name__,
            "__doc__": f"N vehicles of ``{task.env_id}``, flown together.",
        },
    )
    return single, vector


ENV_CLASSES: dict[str, tuple[Any, Any]] = {}
"""Env id -> (single env class, vector env class)."""
for _task in TASKS:
    _single, _vector = env_classes(_task)
    globals()[_single.__name__], globals()[_vector.__name__] = _single, _vector
    ENV_CLASSES[_task.env_id] = (_single, _vector)
