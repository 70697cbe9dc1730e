"""The physics step's buffer: one flat float array per fleet, its layout declared here and nowhere else.

Per vehicle, in order (floats per vehicle):

========================  =======================================================================
region                    what it holds
========================  =======================================================================
``STEP_FIELDS``           the engine's arrays (:data:`~quad_wrench_env.engine.kernels.STEP_FIELDS`):
                          true state, loads, measurements, the autopilot's and the rotors' state
``state_<k>``             component ``k``'s declared state (its ``CompiledForm.state``; width 0
                          without one), in the composition's order
``point_offsets``         the drag points' world offsets from the centre of mass (3 P)
``points``, ``air``       the drag points in the world and the air velocity there (3 P each)
``normals``               the physics step's standard normal draws (wind fields', then sensors')
``rotor_thrusts``         the true rotors' thrusts and the rotor modifiers' added thrust (4 each)
``added_thrust``
``centre``, ``centre_air``  the centres of mass and the air there (3 each)
``delay_line``            the motion capture's delay line (1 + 7 L for a latency of L steps)
========================  =======================================================================

Region ``r`` of ``n`` vehicles is the floats ``[n·start_r, n·(start_r + width_r))`` of the buffer,
vehicle-major within it: one (n, width) array, so a kernel reads a whole region with one offset and one
array argument. :class:`StepLayout` says where each region starts; :class:`StepBuffer` holds the array
and hands each part of the fleet its named view (:meth:`StepBuffer.hand_over`), which everything then
updates in place.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from quad_wrench_env.engine.kernels import STEP_FIELDS, offsets, step_views


@dataclass(frozen=True)
class StepLayout:
    """Where each region of the step buffer starts (floats per vehicle)."""

    state_widths: tuple[int, ...]
    """Floats per vehicle of each component's state, in the composition's order (0: none)."""
    points: int
    """Drag points P."""
    noise_width: int
    """Standard normal draws per vehicle and physics step."""
    delay_width: int
    """Floats per vehicle of the motion capture's delay line (0 without latency)."""

    @cached_property
    def regions(self) -> tuple[tuple[str, int], ...]:
        """Every region ``(name, width)`` in order (module docstring)."""
        p = self.points
        return (
            *STEP_FIELDS,
            *((f"state_{k}", width) for k, width in enumerate(self.state_widths)),
            ("point_offsets", 3 * p),
            ("points", 3 * p),
            ("air", 3 * p),
            ("normals", self.noise_width),
            ("rotor_thrusts", 4),
            ("added_thrust", 4),
            ("centre", 3),
            ("centre_air", 3),
            ("delay_line", self.delay_width),
        )

    @cached_property
    def start(self) -> dict[str, int]:
        """Each region's start (floats per vehicle into the buffer)."""
        return offsets(self.regions)

    @cached_property
    def width(self) -> int:
        """Floats per vehicle of the whole buffer."""
        return sum(width for _, width in self.regions)

    def width_of(self, region: str) -> int:
        """Floats per vehicle of ``region``."""
        return dict(self.regions)[region]


class StepBuffer:
    """The step buffer of ``count`` vehicles laid out by ``layout``."""

    def __init__(self, layout: StepLayout, count: int) -> None:
        self.layout = layout
        self.count = count
        self.array = np.zeros(count * layout.width)
        """The flat buffer the compiled step reads and writes."""
        self.fields = dict(zip((name for name, _ in STEP_FIELDS), step_views(self.array, count), strict=True))
        """Each :data:`~quad_wrench_env.engine.kernels.STEP_FIELDS` array by name (rotation (n, 3, 3),
        time (n,), the others (n, width))."""

    def region(self, name: str) -> np.ndarray:
        """Region ``name`` as a (count, width) view of :attr:`array`."""
        start, width, n = self.layout.start[name], self.layout.width_of(name), self.count
        return self.array[start * n : (start + width) * n].reshape(n, width)

    def hand_over(self, owner: object, attribute: str, region: str) -> None:
        """Give ``owner``'s array ``attribute`` its home in the buffer: the numbers it holds are copied
        into region ``region`` (an engine field or a component's state), which becomes the attribute."""
        view = self.fields[region] if region in self.fields else self.region(region)
        held = getattr(owner, attribute)
        if held.shape != view.shape:
            raise ValueError(
                f"{type(owner).__name__}.{attribute} has shape {held.shape}; region {region!r} of the step "
                f"buffer holds {view.shape}"
            )
        view[...] = held
        setattr(owner, attribute, view)
