"""The env classes of every registered task (:func:`quad_wrench_env.registry.register`): for a task
``Name``, ``NameEnv`` (single vehicle) and ``NameVectorEnv`` (``gym.make_vec``'s vector entry point),
attributes of this module made on first use, so that they pickle by reference and their entry points
(:func:`quad_wrench_env.registry.env_entry_points`) are strings."""

from __future__ import annotations

from typing import Any

from quad_wrench_env.envs.base import QuadWrenchEnv
from quad_wrench_env.envs.vector import QuadWrenchVectorEnv
from quad_wrench_env.registry import registered


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


def __getattr__(name: str) -> Any:
    """``<Task>Env`` or ``<Task>VectorEnv`` of a registered task, made once and kept here."""
    for task in registered("task").values():
        if name in (f"{task.__name__}Env", f"{task.__name__}VectorEnv"):
            single, vector = env_classes(task)
            globals()[single.__name__], globals()[vector.__name__] = single, vector
            return globals()[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
