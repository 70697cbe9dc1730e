"""N wrench estimators of one kind stepped together: what the environments run.

An :class:`EstimatorBank` holds one estimator per vehicle and steps them all at once as one batched
computation, arrays with a leading dimension N in and out: ``UnscentedFilterBank``,
``ExtendedFilterBank``, ``ObserverBank`` and :class:`OracleBank` (a copy of the truth). Each
single-vehicle estimator (the :class:`~quad_wrench_env.estimators.base.Estimator` protocol) is a bank
of one, and each filter bank steps by its kernel (:mod:`quad_wrench_env.numerics`), so there is one
implementation of each algorithm.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple, Protocol, runtime_checkable

import numpy as np

from quad_wrench_env.estimators.base import StateEstimate, WrenchEstimate
from quad_wrench_env.numerics import bind


class EstimatorInputs(NamedTuple):
    """What every estimator bank reads at each physics step (docs/estimators.md, "What an estimator
    sees"), one row per vehicle: the ``thrusts`` (N,) and ``body_torques`` (N, 3) of the nominal mixer
    from the reported motor speeds, the ``positions`` (N, 3) and ``quaternions`` (N, 4, wxyz) measured
    at the step's end, and the ``velocities`` and ``body_rates`` (N, 3) an onboard state estimator
    measures (None without one)."""

    thrusts: np.ndarray
    body_torques: np.ndarray
    positions: np.ndarray
    quaternions: np.ndarray
    velocities: np.ndarray | None = None
    body_rates: np.ndarray | None = None


@runtime_checkable
class EstimatorBank(Protocol):
    """N estimators stepped at the motion-capture rate."""

    name: str
    count: int

    def reset(self, index: int, position: np.ndarray, quaternion_wxyz: np.ndarray) -> None:
        """Restart estimator ``index`` from a known pose, at rest, with no external wrench."""

    def step(self, inputs: EstimatorInputs) -> None:
        """One step of every estimator on this step's :class:`EstimatorInputs`."""

    def wrenches(self) -> np.ndarray:
        """(N, 6) estimated ``[f, τ]``, world frame."""

    def estimates(self) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`states` and :meth:`wrenches` together (one compiled call where the bank has one: what
        the envs read after every policy step)."""

    def wrench_covariances(self) -> np.ndarray:
        """(N, 6, 6) covariance of ``[f, τ]`` in the world frame, the frame of :meth:`wrenches` (the
        force-torque cross blocks included); zeros for the oracle (the truth), NaN where an estimator
        carries none (the observer)."""

    def states(self) -> np.ndarray:
        """(N, 13) estimated position, velocity, quaternion ``[w, x, y, z]`` and body rates."""

    def statuses(self) -> list[str]:
        """Each estimator's status, ``"ok"`` or ``"reinitialised"``."""


def check_finite_batch(name: str, **inputs: np.ndarray | None) -> None:
    """Refuse non-finite inputs to a bank, naming them (one sum per input: NaN and inf propagate)."""
    given = {key: value for key, value in inputs.items() if value is not None}
    if not np.isfinite(sum(float(np.sum(value)) for value in given.values())):
        bad = [key for key, value in given.items() if not np.all(np.isfinite(value))]
        raise ValueError(f"{name} bank step got non-finite input(s) {bad}; allowed: finite numbers")


_UNMEASURED = np.empty((0, 3))
"""What the kernels get for a velocity or body-rate measurement the sensors do not make."""


def _kernel_inputs(inputs: EstimatorInputs) -> EstimatorInputs:
    """A step's inputs as the kernels take them: :data:`_UNMEASURED` for a missing measurement."""
    thrusts, body_torques, positions, quaternions, velocities, body_rates = inputs
    if velocities is not None and body_rates is not None:
        return inputs
    return EstimatorInputs(
        thrusts,
        body_torques,
        positions,
        quaternions,
        _UNMEASURED if velocities is None else velocities,
        _UNMEASURED if body_rates is None else body_rates,
    )


class FilterBank:
    """What the UKF, EKF and observer banks share: one ``step`` that runs the bank's kernel (compiled,
    or plain Python under ``NUMBA_DISABLE_JIT=1``, :mod:`quad_wrench_env.numerics`) and refuses
    non-finite inputs by name before anything enters a filter. Subclasses implement ``_kernel`` (the
    step kernel and its arguments; the kernel returns False, changing nothing, on a non-finite input)
    and ``_estimates_kernel``."""

    name: str
    count: int

    def step(self, inputs: EstimatorInputs) -> None:
        """One step of every filter (see :class:`EstimatorBank`)."""
        kernel, arguments = self._kernel(_kernel_inputs(inputs))
        if not kernel(*arguments):
            self._refuse(inputs)

    def bind_step(self, inputs: EstimatorInputs) -> Callable[[], None]:
        """:meth:`step` on these input arrays, as a call without arguments that reads them afresh
        each time (the caller refills them in place). The kernel, compiled for these arguments'
        types, and its arguments, the bank's state arrays among them, are bound once
        (:func:`~quad_wrench_env.numerics.bind`; the kernel updates them in place), which :meth:`step`
        does on every call."""
        kernel, arguments = self._kernel(_kernel_inputs(inputs))
        kernel_step = bind(kernel, *arguments)

        def bound_step() -> None:
            if not kernel_step():
                self._refuse(inputs)

        return bound_step

    def _refuse(self, inputs: EstimatorInputs) -> None:
        check_finite_batch(self.name, **inputs._asdict())

    def estimates(self) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`states` and :meth:`wrenches` (see :class:`EstimatorBank`) from one call of the
        bank's ``_estimates_kernel``."""
        states, wrenches = np.empty((self.count, 13)), np.empty((self.count, 6))
        kernel, arguments = self._estimates_kernel()
        kernel(*arguments, states, wrenches)
        return states, wrenches

    def bind_estimates(self, states: np.ndarray, wrenches: np.ndarray) -> Callable[[], None]:
        """:meth:`estimates` into ``states`` (N, 13) and ``wrenches`` (N, 6) by a call without
        arguments, the kernel and the bank's arrays bound once (as :meth:`bind_step`)."""
        kernel, arguments = self._estimates_kernel()
        return bind(kernel, *arguments, states, wrenches)

    def _estimates_kernel(self) -> tuple[Callable[..., None], tuple]:
        """The kernel of :meth:`estimates` and its arguments, less the two outputs."""
        raise NotImplementedError

    def _kernel(self, inputs: EstimatorInputs) -> tuple[Callable[..., bool], tuple]:
        """The step kernel and its arguments for these inputs (an empty array for a velocity or
        body-rate measurement the sensors do not make)."""
        raise NotImplementedError


class OracleBank:
    """The truth for N vehicles, handed over by the env before each step (see ``OracleEstimator``)."""

    name = "oracle"

    def __init__(self, count: int) -> None:
        self.count = count
        self._states = np.zeros((count, 13))
        self._states[:, 6] = 1.0
        self._wrenches = np.zeros((count, 6))

    def reset(self, index: int, position: np.ndarray, quaternion_wxyz: np.ndarray) -> None:
        self._states[index] = 0.0
        self._states[index, 0:3] = position
        self._states[index, 6:10] = quaternion_wxyz
        self._wrenches[index] = 0.0

    def observe_truth(self, states: np.ndarray, wrenches: np.ndarray) -> None:
        """(N, 13) true states (as :meth:`states`) and (N, 6) true external wrenches."""
        self._states = states
        self._wrenches = wrenches

    def step(self, inputs: EstimatorInputs) -> None:
        """The truth needs no step."""

    def wrenches(self) -> np.ndarray:
        return self._wrenches

    def estimates(self) -> tuple[np.ndarray, np.ndarray]:
        return self._states, self._wrenches

    def wrench_covariances(self) -> np.ndarray:
        return np.zeros((self.count, 6, 6))

    def states(self) -> np.ndarray:
        return self._states

    def statuses(self) -> list[str]:
        return ["ok"] * self.count


class TruthRecorder:
    """Wraps the env's oracle bank and hands it every call: a subclass records what passes (its
    ``step`` the estimator interface's inputs, :attr:`truth` the last truth handed over)."""

    def __init__(self, inner: OracleBank) -> None:
        self.inner, self.name, self.count = inner, inner.name, inner.count
        self.truth: tuple[np.ndarray, np.ndarray] = (inner.states(), inner.wrenches())

    def reset(self, index: int, position: np.ndarray, quaternion_wxyz: np.ndarray) -> None:
        self.inner.reset(index, position, quaternion_wxyz)

    def observe_truth(self, states: np.ndarray, wrenches: np.ndarray) -> None:
        self.inner.observe_truth(states, wrenches)
        self.truth = (states.copy(), wrenches.copy())

    def step(self, inputs: EstimatorInputs) -> None:
        raise NotImplementedError

    def wrenches(self) -> np.ndarray:
        return self.inner.wrenches()

    def states(self) -> np.ndarray:
        return self.inner.states()

    def estimates(self) -> tuple[np.ndarray, np.ndarray]:
        return self.inner.estimates()

    def wrench_covariances(self) -> np.ndarray:
        return self.inner.wrench_covariances()

    def statuses(self) -> list[str]:
        return self.inner.statuses()


class BankOfOne:
    """A single-vehicle estimator (the :class:`~quad_wrench_env.estimators.base.Estimator` protocol)
    run on a bank of one, so that each algorithm has one implementation; subclasses set ``bank``."""

    bank: EstimatorBank

    def reset(self, position: np.ndarray, quaternion_wxyz: np.ndarray) -> None:
        self.bank.reset(0, position, quaternion_wxyz)

    def step(
        self,
        thrust: float,
        body_torque: np.ndarray,
        position: np.ndarray,
        quaternion_wxyz: np.ndarray,
        velocity: np.ndarray | None = None,
        body_rates: np.ndarray | None = None,
    ) -> WrenchEstimate:
        """One step of the bank with these inputs as its one row (see :class:`EstimatorBank`)."""

        def row(value):  # a measurement not made: as the kernels take it (no second record built)
            return _UNMEASURED if value is None else np.asarray(value, dtype=float)[None, :]

        self.bank.step(
            EstimatorInputs(
                np.array((thrust,), dtype=float),
                row(body_torque),
                row(position),
                row(quaternion_wxyz),
                row(velocity),
                row(body_rates),
            )
        )
        return self.estimate

    @property
    def estimate(self) -> WrenchEstimate:
        w = self.bank.wrenches()[0]
        return WrenchEstimate(w[:3].copy(), w[3:].copy(), self.bank.wrench_covariances()[0])

    @property
    def state(self) -> StateEstimate:
        s = self.bank.states()[0]
        return StateEstimate(s[0:3].copy(), s[3:6].copy(), s[6:10].copy(), s[10:13].copy())

    @property
    def status(self) -> str:
        return self.bank.statuses()[0]
