"""The placement check after a level's move (issue 41): a ``fixture_x`` appliance that lands in a neighbour, in an
object or off its counter, or a ``base_y`` robot base that lands in what stands behind it, makes the level
infeasible for that episode (``PlacementInfeasible``: the worker replies ``unavailable``, the engine records the
episode once as an error naming the check, never retried, and certify counts it as an unavailable seed).

RoboCasa's own T0 path retries its robot placement until the base is clear; a level replays T0's ep_meta with one
field moved, which skips that retry, so the worker checks after RoboCasa's settle:

- ``fixture_x``: MuJoCo's signed distance (``mj_geomDistance``) of each collision geom of the moved appliance (and
  its auxiliaries, the blender's lid) to every other fixture's and object's geom; static fixtures never make
  MuJoCo contacts with each other, so contacts alone would miss an appliance pushed into a wall. A pair counts
  when it penetrates by more than ``TOL`` at the level and did not at T0's pose (the same model, the appliance
  moved back), so an overlap RoboCasa's own kitchen already has is not blamed on the level. Support: each corner
  of the appliance's footprint that had a surface within ``SUPPORT_GAP`` below it at T0's pose must have one at the
  level (a ray straight down).
- ``base_y``: every collision geom of the robot against every fixture's and object's geom, penetrating by more than
  ``TOL`` after the settle (RoboCasa's T0 placement keeps the base clear, so any is the move's).

Runs in RoboCasa's venv, loaded by ``backend.py`` by path; imports only the standard library and numpy at module
level (MuJoCo inside the functions), so our own venv's tests import it as ``scenes.robocasa.placement_check``.
"""

from __future__ import annotations

import numpy as np

TOL = 0.005  # m of penetration a check tolerates (resting contacts sit well under 1 mm)
SUPPORT_GAP = 0.02  # m: a footprint corner is supported when a surface lies this close below it
REACH = 0.01  # m: mj_geomDistance's distmax (pairs farther apart than this are clear)


class PlacementInfeasible(Exception):
    """The level's move put the moved body into an obstacle or off its support in this episode's kitchen: its seed
    decides it, so the worker replies ``unavailable`` (an infeasible cell, recorded once, never retried)."""

    unavailable = True


def _body_root(model, body: int) -> int:
    while model.body_parentid[body] != 0:
        body = int(model.body_parentid[body])
    return body


def _collides(model, g: int) -> bool:
    return bool(model.geom_contype[g] or model.geom_conaffinity[g])


def geoms_named(model, prefixes: tuple[str, ...]) -> list[int]:
    """Collision geoms of the bodies whose names start with one of ``prefixes``."""
    import mujoco

    out = []
    for g in range(model.ngeom):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(model.geom_bodyid[g])) or ""
        if _collides(model, g) and name.startswith(prefixes):
            out.append(g)
    return out


def penetrations(
    model, data, moved: list[int], others: list[int], tol: float = TOL
) -> dict[tuple[int, int], float]:
    """{(moved geom, other geom): depth} of the pairs that penetrate deeper than ``tol`` (broad phase by the geoms'
    bounding spheres, then MuJoCo's signed distance)."""
    import mujoco

    out = {}
    fromto = np.zeros(6)
    for a in moved:
        for b in others:
            gap = (
                np.linalg.norm(data.geom_xpos[a] - data.geom_xpos[b])
                - model.geom_rbound[a]
                - model.geom_rbound[b]
            )
            if gap > REACH:
                continue
            d = mujoco.mj_geomDistance(model, data, a, b, REACH, fromto)
            if d < -tol:
                out[(a, b)] = float(-d)
    return out


def _name(model, g: int) -> str:
    import mujoco

    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or mujoco.mj_id2name(
        model, mujoco.mjtObj.mjOBJ_BODY, int(model.geom_bodyid[g])
    )


def _worst(model, pairs: dict) -> str:
    (a, b), depth = max(pairs.items(), key=lambda kv: kv[1])
    return f"{_name(model, a)} {depth * 100:.1f} cm into {_name(model, b)}"


def supported_corners(model, data, corners: np.ndarray, exclude: set[int]) -> list[bool]:
    """For each footprint corner (world, at the appliance's bottom): a surface other than ``exclude``'s bodies lies
    within ``SUPPORT_GAP`` below it (rays from 1 mm below the bottom, so the appliance's own feet are not hit)."""
    import mujoco

    out = []
    geomid = np.zeros(1, dtype=np.int32)
    for c in corners:
        start = np.array([c[0], c[1], c[2] - 0.001])
        hit, dist = -1, np.inf
        origin = start.copy()
        for _ in range(8):  # step past this appliance's own geoms (mj_ray excludes one body at most)
            d = mujoco.mj_ray(model, data, origin, np.array([0.0, 0.0, -1.0]), None, 1, -1, geomid)
            if d < 0:
                break
            if _body_root(model, int(model.geom_bodyid[geomid[0]])) in exclude:
                origin = origin - np.array([0.0, 0.0, d + 1e-4])
                continue
            hit, dist = int(geomid[0]), float(start[2] - (origin[2] - d))
            break
        out.append(hit >= 0 and dist <= SUPPORT_GAP)
    return out


def _footprint(fixture) -> np.ndarray:
    """The four bottom corners of ``fixture``'s exterior box (RoboCasa's ``get_ext_sites``: p0, px, py, pz)."""
    p0, px, py, _ = (np.asarray(p, dtype=float) for p in fixture.get_ext_sites(relative=False))
    return np.array([p0, px, py, px + py - p0])


def check_fixture_move(env, names: list[str], shift: np.ndarray, where: str) -> None:
    """``fixture_x``: the appliance ``names[0]`` (with its auxiliaries ``names[1:]``) moved by ``shift`` (world, m)
    neither overlaps another fixture or an object more than at T0's pose nor lost a footprint corner's support."""
    import mujoco

    model, data = env.sim.model._model, env.sim.data._data
    prefixes = tuple(env.fixtures[n].naming_prefix for n in names)
    moved = geoms_named(model, prefixes)
    if not moved:
        return
    roots = {_body_root(model, int(model.geom_bodyid[g])) for g in moved}
    others = [g for g in range(model.ngeom) if _collides(model, g) and int(model.geom_bodyid[g]) != 0
              and _body_root(model, int(model.geom_bodyid[g])) not in roots
              and not _is_robot(model, g)]  # fmt: skip
    corners = _footprint(env.fixtures[names[0]])
    now = penetrations(model, data, moved, others)
    held = supported_corners(model, data, corners, roots)
    saved = model.body_pos[list(roots)].copy()
    try:  # T0's pose, in the same model: what RoboCasa's own kitchen already overlaps is not the level's
        model.body_pos[list(roots)] -= shift
        mujoco.mj_kinematics(model, data)
        before = penetrations(model, data, moved, others)
        held0 = supported_corners(model, data, corners - shift, roots)
    finally:
        model.body_pos[list(roots)] = saved
        mujoco.mj_kinematics(model, data)
    new = {k: v for k, v in now.items() if v > before.get(k, 0.0) + TOL}
    if new:
        raise PlacementInfeasible(
            f"{where}: fixture_x moved {names[0]} {_worst(model, new)} (placement check)"
        )
    lost = [i for i, (a, b) in enumerate(zip(held0, held, strict=True)) if a and not b]
    if lost:
        raise PlacementInfeasible(
            f"{where}: fixture_x moved {names[0]} off its support: {len(lost)} of its footprint's corners have no "
            f"surface within {SUPPORT_GAP * 100:.0f} cm below (placement check)"
        )


def _is_robot(model, g: int) -> bool:
    import mujoco

    name = (
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, _body_root(model, int(model.geom_bodyid[g]))) or ""
    )
    return name.startswith(("robot0_", "mobilebase0_", "gripper0_"))


def check_base_move(env, where: str) -> None:
    """``base_y``: no collision geom of the robot penetrates a fixture or an object more than ``TOL`` after the
    settle."""
    model, data = env.sim.model._model, env.sim.data._data
    robot = [g for g in range(model.ngeom) if _collides(model, g) and _is_robot(model, g)]
    others = [g for g in range(model.ngeom) if _collides(model, g) and int(model.geom_bodyid[g]) != 0
              and not _is_robot(model, g)]  # fmt: skip
    hits = penetrations(model, data, robot, others)
    if hits:
        raise PlacementInfeasible(
            f"{where}: base_y moved the robot base {_worst(model, hits)} (placement check)"
        )
