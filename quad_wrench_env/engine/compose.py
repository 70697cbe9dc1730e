"""The compiled physics step of one composition of components, written as source and compiled once.

The engine's own arithmetic (:mod:`.kernels`) does not know the components: for each set of wind
fields, point loads and rotor modifiers (in order) this module writes the source of a step that calls
the engine's kernels and each component's kernels (named by its
:class:`~quad_wrench_env.disturbances.base.CompiledForm`) in the order of one physics step, and
compiles it with numba. Generated source, rather than numba's first-class functions or
``literal_unroll`` over a tuple of kernels, because only a function in a file is cached on disk by
numba (a step that takes kernels as arguments is compiled again in every process, about 5 s; measured
with numba 0.68). The file's name is a hash of its source, of the components' kernel modules and of
the shared helpers (``quad_wrench_env/numerics/*.py``), so a changed component gives a new step, and
the same composition reuses the disk cache in every later process. Like every numba disk cache, a
function the step calls from another file (the engine's kernels) is cached against its own file
alone: after editing a kernel that others call or inline (``numerics/quaternions.py``, ``linalg.py``,
``disturbances/jet_kernels.py``), clear the caches (``make clean-cache``).

One physics step, as written for every composition::

    controls (autopilot, motors) -> drag points in the world -> each wind field adds its air velocity
    -> body and rotor drag -> each rotor modifier adds thrust at the hubs -> each point load adds its
    [F, τ] -> forces and torques PyBullet applies
    (PyBullet steps)
    true state -> each wind field advances on its own normal draws -> sensors
    (after the policy step's last physics step) the air at the centres of mass

The step's scratch arrays (the drag points, the air there, the normal draws, the rotors' thrusts) are
regions of the step buffer (:mod:`.step_buffer`): no array is allocated per step.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import os
import sys
import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

from quad_wrench_env.disturbances.base import CompiledForm
from quad_wrench_env.engine.step_buffer import StepLayout

ROLES = {"wind": ("velocity", "advance"), "load": ("load",), "rotor": ("thrust",)}
"""The kernels each kind of component must name (:mod:`quad_wrench_env.disturbances.base`)."""


@dataclass(frozen=True)
class Slot:
    """One component of a composition: its kind, compiled form and what of the buffer is its own."""

    kind: str
    """``"wind"``, ``"load"`` or ``"rotor"``."""
    form: CompiledForm
    state_width: int
    """Floats of state per vehicle (0: none)."""
    noise: tuple[int, int] = (0, 0)
    """The columns of each step's normal draws that are the component's own (wind fields)."""

    def __post_init__(self) -> None:
        modules = {self.form.module} | {name.rpartition(":")[0] for _, name in self.form.kernels} - {""}
        if "__main__" in modules:
            raise ValueError(
                "a compiled form's kernels must live in an importable module, not in __main__ (a script "
                "or notebook): move them to a module file"
            )
        roles = dict(self.form.kernels)
        missing = [role for role in ROLES[self.kind] if role not in roles]
        if missing:
            raise ValueError(f"the compiled form in {self.form.module} names no {missing} kernel(s)")


def _arguments(k: int, slot: Slot, layout: StepLayout) -> str:
    """Source of component ``k``'s first three kernel arguments: numbers, table, state."""
    table = f"table_{k}" if slot.form.table else "_NO_TABLE"
    if slot.state_width:
        state = f"rows_view(buffer, {layout.start[f'state_{k}']} * n, n, {slot.state_width})"
    else:
        state = "_NO_TABLE"
    return f"_engine.component_slice(constants, {k}), {table}, {state}"


def source(slots: list[Slot], layout: StepLayout) -> str:
    """Python source of the step for ``slots`` (in order) on a step buffer laid out by ``layout``
    (:mod:`.step_buffer`: the slots' states and the scratch space); every offset is written in as a
    number, read from the layout by its region's name."""
    if tuple(slot.state_width for slot in slots) != layout.state_widths:
        raise ValueError(
            f"the slots' state widths {[slot.state_width for slot in slots]} are not the layout's "
            f"{list(layout.state_widths)}"
        )
    field, points, noise_width = layout.start, layout.points, layout.noise_width
    imports, winds, rotors, loads, advances, centre = [], [], [], [], [], []
    for k, slot in enumerate(slots):
        names = dict(slot.form.kernels)
        for role in ROLES[slot.kind]:
            module, _, function = names[role].rpartition(":")
            imports.append(f"from {module or slot.form.module} import {function} as c{k}_{role}")
        head = _arguments(k, slot, layout)
        if slot.kind == "wind":
            a, b = slot.noise
            winds.append(f"    c{k}_velocity({head}, points, time, air)")
            advances.append(f"    c{k}_advance({head}, position, velocity, dt, normals[:, {a}:{b}])")
            centre.append(f"    c{k}_velocity({head}, centre, time, air)")
        elif slot.kind == "rotor":
            rotors.append(f"    c{k}_thrust({head}, hubs, rotation, thrusts, added)")
        else:
            loads.append(
                f"    c{k}_load({head}, time, position, velocity, angular_velocity, rotation, loads)"
            )
    offsets_at, points_at, air_at = field["point_offsets"], field["points"], field["air"]
    normals_at, thrusts_at, added_at = field["normals"], field["rotor_thrusts"], field["added_thrust"]
    centre_at, centre_air_at = field["centre"], field["centre_air"]
    tables = "".join(f", table_{k}" for k, slot in enumerate(slots) if slot.form.table)
    rotor_block = [
        f"    thrusts = rows(buffer, {thrusts_at}, n, 4)",
        f"    added = rows(buffer, {added_at}, n, 4)",
        "    added[:] = 0.0",
        "    _engine.rotor_thrusts(buffer, n, thrusts)",
        "    hubs = points[:, :4]",
        *rotors,
        "    _engine.added_thrust_loads(buffer, offsets, added)",
    ]
    body_block = [
        f"    position = rows(buffer, {field['position']}, n, 3)",
        f"    velocity = rows(buffer, {field['velocity']}, n, 3)",
        f"    angular_velocity = rows(buffer, {field['angular_velocity']}, n, 3)",
    ]
    time = f"buffer[{field['time']} * n : {field['time'] + 1} * n]"
    lines = [
        '"""Generated by quad_wrench_env.engine.compose: one composition\'s physics step (do not edit)."""',
        "import numpy as np",
        "from quad_wrench_env.engine import kernels as _engine",
        "from quad_wrench_env.engine.kernels import matrices, point_rows, rows",
        "from quad_wrench_env.numerics import njit",
        "from quad_wrench_env.numerics.linalg import rows_view",
        *imports,
        "",
        "_NO_TABLE = np.zeros((1, 0))",
        "",
        "",
        "@njit",
        f"def before_world_step(actions, buffer, saturated, constants{tables}):",
        "    n = actions.shape[0]",
        "    _engine.controls(actions, buffer, saturated, constants)",
        f"    time, rotation = {time}, matrices(buffer, {field['rotation']}, n, 3)",
        f"    loads = rows(buffer, {field['loads']}, n, 6)",
        f"    offsets = point_rows(buffer, {offsets_at}, n, {points})",
        f"    points = point_rows(buffer, {points_at}, n, {points})",
        f"    air = point_rows(buffer, {air_at}, n, {points})",
        "    _engine.point_offsets(buffer, constants, n, offsets, points)",
        "    air[:] = 0.0",
        *winds,
        "    _engine.drag_loads(buffer, constants, offsets, air)",
        *(rotor_block if rotors else []),
        *(body_block if loads else []),
        *loads,
        "    _engine.apply_loads(buffer, n)",
        "",
        "",
        "@njit",
        f"def before_world_step_one(actions, buffer, saturated, constants{tables}):",
        f"    before_world_step(actions, buffer, saturated, constants{tables})",
        f"    position = rows(buffer, {field['position']}, 1, 3)",
        f"    forces = rows(buffer, {field['forces']}, 1, 3)",
        f"    torques = rows(buffer, {field['torques']}, 1, 3)",
        "    return (",
        "        (forces[0, 0], forces[0, 1], forces[0, 2]),",
        "        (torques[0, 0], torques[0, 1], torques[0, 2]),",
        "        (position[0, 0], position[0, 1], position[0, 2]),",
        "    )",
        "",
        "",
        "@njit",
        f"def after_world_step(flat, buffer, noise_buffer, noise_cursor, constants{tables}):",
        "    n = flat.shape[0] // 13",
        "    _engine.read_state(flat, buffer, constants)",
        f"    normals = rows(buffer, {normals_at}, n, {noise_width})",
        "    _engine.take_normals(noise_buffer, noise_cursor, normals)",
        f"    time, position = {time}, rows(buffer, {field['position']}, n, 3)",
        f"    velocity, dt = rows(buffer, {field['velocity']}, n, 3), _engine.time_step(constants)",
        *advances,
        "    _engine.sense(buffer, normals, constants)",
        "",
        "",
        "@njit",
        f"def after_world_step_one(readings, buffer, noise_buffer, noise_cursor, constants{tables}):",
        "    (position, orientation), (linear, angular) = readings",
        "    row = np.empty(13)",
        "    for i in range(3):",
        "        row[i], row[7 + i], row[10 + i] = position[i], linear[i], angular[i]",
        "    for i in range(4):",
        "        row[3 + i] = orientation[i]",
        f"    after_world_step(row, buffer, noise_buffer, noise_cursor, constants{tables})",
        "",
        "",
        "@njit",
        f"def centre_wind(n, buffer, constants{tables}):",
        '    """The air velocity at each centre of mass into the buffer\'s ``wind_velocity``."""',
        f"    time, position = {time}, rows(buffer, {field['position']}, n, 3)",
        f"    centre, air = point_rows(buffer, {centre_at}, n, 1), point_rows(buffer, {centre_air_at}, n, 1)",
        "    centre[:, 0, :] = position",
        "    air[:] = 0.0",
        *centre,
        f"    rows(buffer, {field['wind_velocity']}, n, 3)[:] = air[:, 0, :]",
        "",
    ]
    return "\n".join(lines)


def cache_folder() -> Path:
    """Where generated steps are written (and numba caches them): ``$QUAD_WRENCH_CACHE_DIR``, else the
    user's cache folder, else the system's temporary folder when that is not writable."""
    configured = os.environ.get("QUAD_WRENCH_CACHE_DIR")
    base = Path(configured) if configured else Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache"))
    folder = base if configured else base / "quad_wrench_env"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        probe = folder / f".probe-{os.getpid()}"
        probe.touch()
        probe.unlink()
    except OSError:  # a folder of this user's alone: nobody else can plant a step there
        folder = Path(tempfile.gettempdir()) / f"quad_wrench_env-{os.getuid()}"
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        if folder.stat().st_uid != os.getuid():
            raise PermissionError(f"{folder} belongs to another user; set QUAD_WRENCH_CACHE_DIR") from None
    return folder / "compositions"


_LOADED: dict[str, ModuleType] = {}


def _fingerprint(text: str, slots: list[Slot]) -> str:
    """Hash of the step's source, of every module whose kernels it calls and of the shared kernel
    helpers they inline (``quad_wrench_env/numerics/*.py``): numba's disk cache checks only a function's
    own file, so a change to any of these must give the step a new file."""
    digest = hashlib.sha256(text.encode())
    named = {name.rpartition(":")[0] for slot in slots for _, name in slot.form.kernels} - {""}
    modules = sorted({"quad_wrench_env.engine.kernels", *named, *(slot.form.module for slot in slots)})
    files = []
    for name in modules:
        spec = importlib.util.find_spec(name)
        if spec is None or spec.origin is None:
            raise ValueError(f"compiled form module {name!r} cannot be found")
        files.append(Path(spec.origin))
    helpers = Path(importlib.util.find_spec("quad_wrench_env.numerics").origin).parent  # type: ignore[union-attr, arg-type]
    for path in [*files, *sorted(helpers.glob("*.py"))]:
        digest.update(path.read_bytes())
    return digest.hexdigest()[:20]


def compose(slots: list[Slot], layout: StepLayout) -> ModuleType:
    """The module holding the step for ``slots`` (``before_world_step``, ``before_world_step_one``,
    ``after_world_step``, ``after_world_step_one``, ``centre_wind``), written and imported on first
    use (arguments as :func:`source`)."""
    text = source(slots, layout)
    key = _fingerprint(text, slots)
    if key in _LOADED:
        return _LOADED[key]
    folder = cache_folder()
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"step_{key}.py"
    if not path.exists() or path.read_text() != text:
        partial = folder / f".step_{key}.{os.getpid()}.{threading.get_ident()}.tmp"
        partial.write_text(text)
        partial.replace(path)  # atomic: another process never reads half a file
    name = f"quad_wrench_env_step_{key}"
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise RuntimeError(f"cannot import the generated step {path}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    _LOADED[key] = module
    return module
