"""pick_x's window, placed on the range RoboCasa samples the pick object's centre in, in the episode's own kitchen.

RoboCasa 1.0.1 clips a task's declared region to the fixture it lies on (``utils/env_utils.py``
``_get_placement_initializer``: ``inner_size = min(outer_size - margin, size)``, then centres it by ``pos``), so in
a narrow kitchen the object is drawn from less than the declared width (CounterToBlender seed 6: 0.20 of 0.50 m).
Its ``UniformRandomSampler._sample_x`` (``utils/placement_samplers.py``) then draws the centre in that range less
``buffer = min(obj_size[0], obj_size[1]) / 2`` at each end, and ``obj_in_region`` rejects a draw whose rotated
footprint leaves the range (``ensure_object_boundary_in_range``, on for every pick_x task). Appendix B divides "the
valid sampling region" by the number of progressions: here the centre range ``[lo + buffer, hi - buffer]``. T0's
window is ``2 x PICK_JITTER`` at its low end, or one level's step where that is narrower (``window_width``), and
level k moves it k steps: the task's own step is 1/5 of that centre range (the declared width / 5 only for an object
without a footprint where the kitchen does not clip the region), a --step is the user's metres. RoboCasa's draw,
``rng.uniform(low, high)``, is half-open, so windows one step wide tile the centre range without sharing a point.
A kitchen and object whose centre range cannot hold the levels 0..top (``level_offset``) host none of them.

Runs in RoboCasa's venv, loaded by ``backend.py`` by path; imports only the standard library and numpy at module
level, so our own venv's tests import it as ``scenes.robocasa.pick_window``.
"""

from __future__ import annotations

import types

import numpy as np

PICK_JITTER = 0.02  # T0's window: 2 x 2 cm of centre x at the low end of RoboCasa's range (levels shift it)
PICK_KEY = "indgen_pick_window"  # what the worker's ep_meta reports of the episode's window (not an edit)
TOL = 1e-9


class LevelUnavailable(Exception):
    """This episode's kitchen cannot hold the pick_x levels: its seed decides it, so the worker replies
    ``unavailable`` and the engine records the episode once as an error at every level, never retried."""

    unavailable = True


def level_step(width: float, pick: dict, buffer: float = 0.0) -> float:
    """One level's offset (m) in a kitchen whose range is ``width`` wide, for an object RoboCasa keeps ``buffer`` (m)
    inside each end: the task's own step, 1/``progressions`` of the centre range (the declared width / 5 where the
    centre range is the declared width), or the user's ``pick["step"]``."""
    declared, centre = float(pick["declared"]), width - 2 * float(buffer)
    if pick["step"] is not None:
        return float(pick["step"])
    return (centre if centre < declared - TOL else declared) / int(pick["progressions"])


def window_width(width: float, pick: dict, buffer: float = 0.0) -> float:
    """T0's window (m): ``2 x PICK_JITTER``, or one level's step where that is narrower (a kitchen whose centre range
    is 0.20 m or less), so the levels' windows never overlap and a narrow kitchen's levels tile its centre range.
    A kitchen with a wider step draws in the same 4 cm as before this rule (its T0 is unchanged)."""
    return min(2 * PICK_JITTER, level_step(width, pick, buffer))


def level_offset(width: float, pick: dict, nominal: float, where: str, buffer: float = 0.0) -> float:
    """Level ``pick["level"]``'s offset (m) of the window from T0's in a kitchen whose range is ``width`` wide, for
    an object RoboCasa keeps ``buffer`` (m) inside each end of it (``_sample_x``'s buffer).

    ``pick``: ``declared`` (the task's region, m), ``level``, ``top`` (the axis's last level), ``step`` (None: the
    task's own, 1/``progressions`` of the centre range ``width - 2 buffer``; else the user's, m), ``progressions``.
    ``nominal``: the plan's offset, used as is where the centre range is the declared width (the same numbers as
    before) or the step is the user's. Raises ``LevelUnavailable`` (one line) when the object's centre has no room
    or the top level's window (``window_width``) would leave the centre range (its footprint the range).
    """
    level, top = int(pick["level"]), int(pick["top"])
    declared, own, centre = float(pick["declared"]), pick["step"] is None, width - 2 * float(buffer)
    moved = centre < declared - TOL
    step, window = level_step(width, pick, buffer), window_width(width, pick, buffer)
    clips = " (RoboCasa clips it to the fixture)" if width < declared - TOL else ""
    region = (
        f"a {width:.3f} m range of its {declared:.2f} m pick region{clips}, {centre:.3f} m for the object's "
        f"centre (RoboCasa keeps {buffer:.3f} m of it inside each end)"
    )
    if centre <= TOL:
        raise LevelUnavailable(
            f"{where}: {region}, which leaves the object's centre no room, so this episode runs at no pick_x level "
            "(not retried)"
        )
    if top * step + window > centre + TOL:
        raise LevelUnavailable(
            f"{where}: {region}; level {top}'s window at {top * step:.3f}..{top * step + window:.3f} m leaves it "
            f"at {step:g} m a level, so this episode runs at no pick_x level (not retried)"
        )
    return float(nominal) if not (own and moved) else round(level * step, 9)


def _window_x(env, pick: dict):
    """``UniformRandomSampler._sample_x`` (robocasa/utils/placement_samplers.py) drawing in the window
    (``window_width`` of T0's range) at the low end of the range it would draw in: the same buffer
    (``ensure_object_boundary_in_range``), the same one ``rng.uniform``; the buffer is kept as
    ``env._indgen_pick_buffer``."""

    def sample_x(self, obj_size=None):
        minimum, maximum = (float(v) for v in self.x_range)
        buffer = 0.0
        if obj_size is not None and self.ensure_object_boundary_in_range:
            buffer = min(obj_size[0], obj_size[1]) / 2
        env._indgen_pick_buffer = float(buffer)
        t0 = getattr(env, "_indgen_pick_t0", None)  # a level's replay: the window is T0's
        width = float(t0[1]) - float(t0[0]) if t0 is not None else maximum - minimum
        span = window_width(width, pick, buffer)
        low, high = minimum + buffer, min(minimum + buffer + span, maximum - buffer)
        if low > high:
            from robocasa.utils.errors import PlacementError

            raise PlacementError(f"Invalid x range for placement initializer: ({low}, {maximum - buffer})")
        return self.rng.uniform(high=high, low=low)

    return sample_x


def narrow(env, sampler, cfg_list: list, pick: dict) -> None:
    """The pick object's sampler of ``sampler`` (RoboCasa's placement initializer of ``cfg_list``) draws its centre
    in the window at the low end of the centre range RoboCasa computed; that range is kept as
    ``env._indgen_pick_range``.

    Everything else is RoboCasa's: the counter region, its ``x_range`` (so at T0 the robot base RoboCasa places from
    it, CheesyBread's ``init_robot_here``), the y range, the rotation, the footprint rule, the collision checks. On
    a level's replay (``env._indgen_pick_t0``: T0's range) the range's high end stays T0's, so the footprint check
    keeps the object inside T0's range at every level; its low end is T0's moved by the level's offset edit.
    """
    cfg = next((c for c in cfg_list if c.get("name") == pick["cfg"] and c.get("type") == "object"), None)
    if cfg is None:
        return
    size = float(cfg["placement"]["size"][0])
    if abs(size - float(pick["declared"])) > TOL:  # the plan's step came from the declared width
        raise ValueError(
            f"RoboCasa declares {pick['cfg']}'s region {size} m wide, the plan assumed {pick['declared']} m "
            "(scenes/robocasa PICK_REGIONS): not the pinned RoboCasa 1.0.1; run 'indgen setup robocasa'"
        )
    sub = sampler.samplers[f"{pick['cfg']}_Sampler"]
    lo, hi = (float(v) for v in sub.x_range)
    env._indgen_pick_range = (lo, hi)
    t0 = getattr(env, "_indgen_pick_t0", None)
    if t0 is not None:
        sub.x_range = np.array([lo, float(t0[1])])
    sub._sample_x = types.MethodType(_window_x(env, pick), sub)


def record(t0_range: tuple[float, float], pick: dict, offset: float, buffer: float) -> dict:
    """The episode's window as the worker's ep_meta reports it (``PICK_KEY``): RoboCasa's range at T0 in its
    fixture's frame, the declared width, the object's buffer, the level's offset and the window of its centre."""
    lo, hi = t0_range
    start = lo + buffer + offset
    return {
        "cfg": pick["cfg"], "range": [lo, hi], "declared": float(pick["declared"]), "buffer": float(buffer),
        "offset": offset, "window": [start, start + window_width(hi - lo, pick, buffer)],
    }  # fmt: skip
