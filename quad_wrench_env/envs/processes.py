"""The vehicles of one training env stepped in several processes at once: both cores of a 2-core
machine for one training run.

    venv = ProcessVectorEnv("QuadWrench/FanTracking-v1", num_envs=32, processes=2, estimator="ukf")
    model = PPO("MlpPolicy", VecNormalize(VecMonitor(SB3VecEnv(venv))), ...)

The ``num_envs`` vehicles are split into ``processes`` groups of consecutive vehicles, as even as
they go (``numpy.array_split``). The last group flies in this process; each other group flies in a
worker process of its own (a :class:`~quad_wrench_env.envs.vector.QuadWrenchVectorEnv` of that
group). ``group_env`` (one mapping per process, the workers' first) puts settings of its own on
top of each group's env (merged key by key), e.g. ``[{"vehicle": "ardrone2"}, {"vehicle":
"hummingbird"}]`` to train one policy across two presets; the groups must agree on the observation
and action layouts and the control period (``TrainConfig`` refuses groups that set them). A step
hands each worker its vehicles' actions, steps this process's group meanwhile, and joins the
results in vehicle order. A vehicle's episode depends only on its own seed, actions and
options (the same bits in a vector env of any size, ``tests/test_determinism.py``), so the split
env gives every vehicle exactly the numbers of one :class:`QuadWrenchVectorEnv` of ``num_envs``
vehicles, and a training run the same model.

**The hand-off.** A pipe's round trip on a virtual machine costs as much as stepping several
vehicles (the idle side's core sleeps, and waking it goes through the hypervisor; docs/architecture.md,
"Measurements behind the hot paths"). Steps
therefore go through shared memory: the actions and each step's arrays (laid out after the
worker's first step, which comes through the pipe) and two sequence numbers, which each side
watches in a busy loop while it waits. A worker waits that way for :data:`SPIN_SECONDS` and then
sleeps on its pipe (a learner's update), so an idle run does not hold a core. Resets, errors and
``close`` use the pipe. Workers are started with the ``spawn`` method (a forked PyBullet client or
torch thread pool is not safe) and end with :meth:`close`, or with this process.

It offers what :class:`~quad_wrench_env.envs.sb3_vec_env.SB3VecEnv` steps: ``step_arrays`` and
``reset_vehicles`` (no Gymnasium ``step``: watch or evaluate a vehicle with a single env).
"""

from __future__ import annotations

import contextlib
import multiprocessing
import time
import traceback
import weakref
from collections.abc import Mapping, Sequence
from multiprocessing.connection import Connection
from multiprocessing.shared_memory import SharedMemory
from typing import Any

import gymnasium as gym
import numpy as np

from quad_wrench_env.config import merged
from quad_wrench_env.envs.base import closed_error
from quad_wrench_env.envs.vector import QuadWrenchVectorEnv, Transition

SPIN_SECONDS = 0.005
"""How long a worker watches for the next step before it sleeps on its pipe."""

_REQUEST, _REPLY, _ASLEEP, _FAILED = range(4)
"""Indices of a worker's control numbers (int64, in its shared block): the step asked for, the
step answered, whether the worker sleeps on its pipe, whether its last step failed."""

Layout = list[tuple[tuple[str, ...], str, tuple[int, ...]]]
"""Where a step's arrays lie in shared memory: (path in the :class:`Transition`, dtype, shape)."""


def _vector_env(env_id: str, count: int, env_kwargs: Mapping[str, Any]) -> QuadWrenchVectorEnv:
    """The task's vector env of ``count`` vehicles."""
    import quad_wrench_env  # noqa: F401  (registers the env ids in a fresh worker)

    venv = gym.make_vec(env_id, num_envs=count, vectorization_mode="vector_entry_point", **env_kwargs)
    return venv.unwrapped


def _arrays(transition: Transition) -> dict[tuple[str, ...], np.ndarray]:
    """The transition's arrays by path, e.g. ``("reward_terms", "effort")``."""
    out: dict[tuple[str, ...], np.ndarray] = {}
    for name in Transition.__dataclass_fields__:
        value = getattr(transition, name)
        if isinstance(value, Mapping):
            out.update({(name, key): np.asarray(item) for key, item in value.items()})
        else:
            out[(name,)] = np.asarray(value)
    return out


def _layout(transition: Transition) -> Layout:
    return [(path, array.dtype.str, array.shape) for path, array in _arrays(transition).items()]


class _Block:
    """One worker's shared memory: control numbers, actions and one step's arrays as views."""

    def __init__(self, memory: SharedMemory, count: int, layout: Layout) -> None:
        self.memory = memory
        buffer, offset = memory.buf, 0
        self.control = np.ndarray((4,), np.int64, buffer, offset)
        offset += self.control.nbytes
        self.actions = np.ndarray((count, 4), np.float64, buffer, offset)
        offset += self.actions.nbytes
        self.views: dict[tuple[str, ...], np.ndarray] = {}
        for path, dtype, shape in layout:
            view = np.ndarray(shape, np.dtype(dtype), buffer, offset)
            self.views[path] = view
            offset += -(-view.nbytes // 8) * 8

    @staticmethod
    def size(count: int, layout: Layout) -> int:
        sizes = (int(np.prod(shape)) * np.dtype(dtype).itemsize for _, dtype, shape in layout)
        arrays = sum(-(-size // 8) * 8 for size in sizes)
        return 4 * 8 + count * 4 * 8 + arrays

    def write(self, transition: Transition) -> None:
        arrays = _arrays(transition)
        if arrays.keys() != self.views.keys():
            raise ValueError(
                f"this step's arrays {sorted(arrays)} differ from the first step's {sorted(self.views)}"
            )
        for path, view in self.views.items():
            view[...] = arrays[path]

    def read(self) -> Transition:
        fields: dict[str, Any] = {}
        for path, view in self.views.items():
            if len(path) == 1:
                fields[path[0]] = view.copy()
            else:
                fields.setdefault(path[0], {})[path[1]] = view.copy()
        return Transition(**fields)

    def close(self) -> None:
        del self.control, self.actions, self.views
        self.memory.close()


def _serve(connection: Connection, env_id: str, count: int, env_kwargs: Mapping[str, Any]) -> None:
    """A worker: builds its group's vector env, then answers pipe requests (``("reset", args)``,
    ``("step", actions)`` for the first step, ``("attach", (name, layout))``, ``("close", None)``)
    with ``("ok", result)`` or ``("error", traceback)``, and, once attached, steps asked for in
    shared memory."""
    try:
        venv = _vector_env(env_id, count, env_kwargs)
    except Exception:
        connection.send(("error", traceback.format_exc()))
        return
    connection.send(("ok", None))
    block: _Block | None = None
    answered = 0
    while True:
        if block is not None and _watch(block, answered):
            control = block.control
            answered = int(control[_REQUEST])
            try:
                block.write(venv.step_arrays(block.actions))
            except Exception:
                control[_FAILED] = 1
                connection.send(("error", traceback.format_exc()))
            control[_REPLY] = answered
            continue
        command, payload = connection.recv()
        if block is not None:
            block.control[_ASLEEP] = 0
        if command == "wake":
            continue
        try:
            if command == "step":
                result: Any = venv.step_arrays(payload)
            elif command == "reset":
                result = venv.reset_vehicles(*payload)
            elif command == "attach":
                name, layout = payload
                block = _Block(SharedMemory(name=name), count, layout)  # the creator unlinks it
                result = None
            else:  # close
                if block is not None:
                    block.close()
                venv.close()
                connection.send(("ok", None))
                return
        except Exception:
            connection.send(("error", traceback.format_exc()))
            continue
        connection.send(("ok", result))


def _watch(block: _Block, answered: int) -> bool:
    """Whether a step past ``answered`` is asked for within :data:`SPIN_SECONDS`; if not, the worker
    marks itself asleep (and looks once more, so a request made meanwhile is not missed)."""
    control = block.control
    deadline = time.perf_counter() + SPIN_SECONDS
    while control[_REQUEST] == answered:
        if time.perf_counter() > deadline:
            control[_ASLEEP] = 1
            if control[_REQUEST] != answered:
                control[_ASLEEP] = 0
                return True
            return False
    return True


class WorkerError(RuntimeError):
    """A worker process failed; the message carries its traceback."""


def _answer(connection: Connection, group: int) -> Any:
    """The result of worker ``group``'s last pipe request (its error raised here, with its traceback)."""
    try:
        status, result = connection.recv()
    except EOFError as error:
        raise WorkerError(f"the worker of vehicle group {group} ended without answering") from error
    if status == "error":
        raise WorkerError(f"the worker of vehicle group {group} failed:\n{result}")
    return result


def _join(parts: Sequence[Any]) -> Any:
    """Arrays over vehicles (or dicts of them, nested) of consecutive groups, joined in order."""
    first = parts[0]
    if isinstance(first, Mapping):
        return {key: _join([part[key] for part in parts]) for key in first}
    return np.concatenate(parts, axis=0)


def _stop(
    connections: list[Connection], workers: list[multiprocessing.Process], memories: list[SharedMemory]
) -> None:
    """Ask every worker to close, make sure each has ended, and free the shared memory."""
    for connection in connections:
        try:
            connection.send(("close", None))
            while connection.poll(10) and connection.recv()[0] == "error":
                pass  # a failed step's report, still unread
        except (BrokenPipeError, EOFError, ConnectionResetError, OSError):
            pass
        connection.close()
    for worker in workers:
        worker.join(timeout=10)
        if worker.is_alive():
            worker.terminate()
            worker.join()
    for memory in memories:
        with contextlib.suppress(BufferError):  # views held by an env never closed go with it
            memory.close()
        memory.unlink()


class ProcessVectorEnv:
    """``num_envs`` vehicles of ``env_id`` in ``processes`` processes (see the module docstring)."""

    render_mode = None
    """It does not render (see the module docstring)."""

    def __init__(
        self,
        env_id: str,
        num_envs: int,
        processes: int = 2,
        group_env: Sequence[Mapping[str, Any]] | None = None,
        **env_kwargs: Any,
    ) -> None:
        if not (isinstance(num_envs, int) and num_envs >= 1):
            raise ValueError(f"num_envs={num_envs!r} must be an integer >= 1")
        if not (isinstance(processes, int) and 1 <= processes <= num_envs):
            raise ValueError(f"processes={processes!r} must be an integer from 1 to num_envs={num_envs}")
        if group_env is not None and len(group_env) != processes:
            raise ValueError(
                f"group_env has {len(group_env)} entries; give one per process ({processes}) or none"
            )
        # each group's env settings: env_kwargs with its entry of group_env (e.g. a vehicle preset) merged in
        kwargs = [merged(env_kwargs, group_env[k] if group_env else {}) for k in range(processes)]
        split = np.array_split(np.arange(num_envs), processes)
        self.groups = [range(int(group[0]), int(group[-1]) + 1) for group in split]
        """The vehicles of each process (``numpy.array_split``'s sizes): the workers' first, this
        process's last (the smallest, as this process also runs the learner)."""
        context = multiprocessing.get_context("spawn")
        self._connections: list[Connection] = []
        self._workers: list[multiprocessing.Process] = []
        self._memories: list[SharedMemory] = []
        self._blocks: list[_Block] = []
        self._closed = False
        self._finalizer = weakref.finalize(self, _stop, self._connections, self._workers, self._memories)
        try:
            for group, settings in zip(self.groups[:-1], kwargs[:-1], strict=True):
                mine, theirs = context.Pipe()
                worker = context.Process(
                    target=_serve, args=(theirs, env_id, len(group), settings), daemon=True
                )
                worker.start()
                theirs.close()
                self._connections.append(mine)
                self._workers.append(worker)
            self.local = _vector_env(env_id, len(self.groups[-1]), kwargs[-1])
            """This process's group of vehicles."""
            for number, connection in enumerate(self._connections):
                _answer(connection, number)
        except BaseException:
            self._finalizer()
            raise
        local = self.local
        self.num_envs = num_envs
        self.single_observation_space = local.single_observation_space
        self.single_action_space = local.single_action_space
        self.obs_layout = local.obs_layout
        self.action_scaling = local.action_scaling
        self.dt, self.physics_dt = local.dt, local.physics_dt
        self.cfg = local.cfg

    @property
    def unwrapped(self) -> ProcessVectorEnv:
        return self

    def step_arrays(self, actions: np.ndarray) -> Transition:
        """:meth:`QuadWrenchVectorEnv.step_arrays` of all vehicles, the groups stepped at once."""
        if self._closed:
            raise closed_error(self)
        actions = np.asarray(actions)
        if actions.shape[:1] != (self.num_envs,):
            raise ValueError(f"actions of shape {actions.shape}; expected ({self.num_envs}, 4)")
        workers = self.groups[:-1]
        if not self._blocks:
            return self._first_step(actions)
        for group, block, connection in zip(workers, self._blocks, self._connections, strict=True):
            control = block.control
            block.actions[...] = actions[group.start : group.stop]
            control[_REQUEST] += 1
            if control[_ASLEEP]:
                connection.send(("wake", None))
        last = self.groups[-1]
        mine = self.local.step_arrays(actions[last.start : last.stop])
        parts = [self._reply(number, block) for number, block in enumerate(self._blocks)]
        return self._joined([*parts, mine])

    def _reply(self, number: int, block: _Block) -> Transition:
        """Worker ``number``'s step, once it has answered."""
        control, worker = block.control, self._workers[number]
        spins = 0
        while control[_REPLY] != control[_REQUEST]:
            spins += 1
            if spins % 10_000 == 0:
                if not worker.is_alive():
                    raise WorkerError(f"the worker of vehicle group {number} ended during a step")
                if control[_ASLEEP]:  # it fell asleep as the request came: wake it again
                    self._connections[number].send(("wake", None))
        if control[_FAILED]:
            control[_FAILED] = 0
            _answer(self._connections[number], number)
        return block.read()

    def _first_step(self, actions: np.ndarray) -> Transition:
        """The first step, through the pipes: it lays out each worker's shared memory."""
        workers = self.groups[:-1]
        for group, connection in zip(workers, self._connections, strict=True):
            connection.send(("step", actions[group.start : group.stop]))
        last = self.groups[-1]
        mine = self.local.step_arrays(actions[last.start : last.stop])
        parts = [_answer(c, number) for number, c in enumerate(self._connections)]
        for group, part, connection in zip(workers, parts, self._connections, strict=True):
            layout = _layout(part)
            memory = SharedMemory(create=True, size=_Block.size(len(group), layout))
            self._memories.append(memory)
            self._blocks.append(_Block(memory, len(group), layout))
            connection.send(("attach", (memory.name, layout)))
        for number, connection in enumerate(self._connections):
            _answer(connection, number)
        return self._joined([*parts, mine])

    @staticmethod
    def _joined(parts: Sequence[Transition]) -> Transition:
        return Transition(
            *(_join([getattr(part, name) for part in parts]) for name in Transition.__dataclass_fields__)
        )

    def reset_vehicles(
        self,
        indices: Sequence[int],
        seeds: Sequence[int | None],
        options: Sequence[Mapping[str, Any] | None],
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """:meth:`QuadWrenchVectorEnv.reset_vehicles` over all vehicles: each group restarts its own."""
        if self._closed:
            raise closed_error(self)
        chosen = [int(i) for i in indices]
        if len(chosen) != len(seeds) or len(chosen) != len(options):
            raise ValueError("indices, seeds and options must have one entry per restarted vehicle")
        requests = []
        for group in self.groups:
            picked = [k for k, i in enumerate(chosen) if i in group]
            local = [chosen[k] - group.start for k in picked]
            requests.append((local, [seeds[k] for k in picked], [options[k] for k in picked]))
        for request, connection in zip(requests[:-1], self._connections, strict=True):
            connection.send(("reset", request))
        mine = self.local.reset_vehicles(*requests[-1])
        parts = [_answer(c, number) for number, c in enumerate(self._connections)] + [mine]
        return _join([obs for obs, _ in parts]), _join([info for _, info in parts])

    def close(self) -> None:
        """End the workers, free the shared memory and release every PyBullet client; safe to call
        more than once."""
        if self._closed:
            return
        self._closed = True
        for block in self._blocks:
            block.close()
        self._blocks.clear()
        self._finalizer()
        self.local.close()
