"""pick_x's window, placed on the range RoboCasa samples the pick object's x in, in the episode's own kitchen.

RoboCasa 1.0.1 clips a task's declared region to the fixture it lies on (``utils/env_utils.py``
``_get_placement_initializer``: ``inner_size = min(outer_size - margin, size)``, then centres it by ``pos``), so in
a narrow kitchen the object is drawn from less than the declared width (CounterToBlender seed 6: 0.20 of 0.50 m).
Appendix B divides "the valid sampling region" by the number of progressions; the region is the one RoboCasa
samples from in that kitchen. T0's window is ``2 x PICK_JITTER`` at its low-x end and level k moves it k steps:
the task's own step is 1/5 of that range (the declared width / 5 where the kitchen does not clip it), a --step is
the user's metres. A kitchen whose range cannot hold the levels 0..top (``level_offset``) hosts none of them.

Runs in RoboCasa's venv, loaded by ``backend.py`` by path; imports only the standard library and numpy, so our own
venv's tests import it as ``scenes.robocasa.pick_window``.
"""

from __future__ import annotations

import numpy as np

PICK_JITTER = 0.02  # T0's window: 2 x 2 cm of x at the low-x end of RoboCasa's range (levels shift it)
PICK_KEY = "indgen_pick_window"  # what the worker's ep_meta reports of the episode's window (not an edit)
TOL = 1e-9


class LevelUnavailable(Exception):
    """This episode's kitchen cannot hold the pick_x levels: its seed decides it, so the worker replies
    ``unavailable`` and the engine records the episode once as an error at every level, never retried."""

    unavailable = True


def level_offset(width: float, pick: dict, nominal: float, where: str) -> float:
    """Level ``pick["level"]``'s offset (m) of the window from T0's in a kitchen whose range is ``width`` wide.

    ``pick``: ``declared`` (the task's region, m), ``level``, ``top`` (the axis's last level), ``step`` (None: the
    task's own, 1/``progressions`` of the range; else the user's, m), ``progressions``. ``nominal``: the plan's
    offset, used as is where the kitchen does not clip the region (the same numbers as before) or the step is the
    user's. Raises ``LevelUnavailable`` (one line) when the levels' windows would overlap (a fifth no wider than
    the window) or the top level's window would leave the range.
    """
    window, level, top = 2 * PICK_JITTER, int(pick["level"]), int(pick["top"])
    declared, own = float(pick["declared"]), pick["step"] is None
    clipped = width < declared - TOL
    step = (width if clipped else declared) / int(pick["progressions"]) if own else float(pick["step"])
    region = f"a {width:.3f} m range of its {declared:.2f} m pick region (RoboCasa clips it to the fixture)"
    if own and step <= window + TOL:
        raise LevelUnavailable(
            f"{where}: {region}, whose 1/{pick['progressions']} ({step:.3f} m) is no wider than pick_x's "
            f"{window:.2f} m window: the levels would overlap, so this episode runs at no pick_x level (not retried)"
        )
    if top * step + window > width + TOL:
        raise LevelUnavailable(
            f"{where}: {region}; level {top}'s window at {top * step:.3f}..{top * step + window:.3f} m leaves it "
            f"at {step:g} m a level, so this episode runs at no pick_x level (not retried)"
        )
    return float(nominal) if not (own and clipped) else round(level * step, 9)


def narrow(env, sampler, cfg_list: list, pick: dict) -> None:
    """The pick object's sampler of ``sampler`` (RoboCasa's placement initializer of ``cfg_list``) draws its x in
    the window at the low-x end of the range RoboCasa computed; that range is kept as ``env._indgen_pick_range``.

    Everything else is RoboCasa's: the counter region it chose, the y range, the rotation, the collision checks;
    the window bounds the object's centre (``ensure_object_boundary_in_range`` off: RoboCasa would shrink a 4 cm
    range by the object's radius). A replay's range is T0's moved by the level's offset edit.
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
    sub.x_range = np.array([lo, lo + 2 * PICK_JITTER])
    sub.ensure_object_boundary_in_range = False


def record(t0_range: tuple[float, float], pick: dict, offset: float) -> dict:
    """The episode's window as the worker's ep_meta reports it (``PICK_KEY``): RoboCasa's range at T0 in its
    fixture's frame, the declared width, the level's offset and the window it drew the object's x in."""
    lo, hi = t0_range
    return {
        "cfg": pick["cfg"], "range": [lo, hi], "declared": float(pick["declared"]), "offset": offset,
        "window": [lo + offset, lo + offset + 2 * PICK_JITTER],
    }  # fmt: skip
