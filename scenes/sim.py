"""The one robosuite environment every scene builds into: a Panda at a table plus a ``Layout`` of objects.

Importing this module imports robosuite and MuJoCo; ``scenes`` and ``scenes.catalog`` never do.
Placement is seeded from the episode seed alone (numpy Generator), the robot starts without
initialisation noise, and the model is built once per env (``hard_reset=False``), so the same
(scene, task, axis, level, seed) gives the same initial state bit for bit in any process.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")


class _DropMacroWarning(logging.Filter):
    """robosuite warns about a missing private macro file on every import; it is irrelevant here."""

    def filter(self, record: logging.LogRecord) -> bool:
        return "macro" not in record.getMessage()


logging.getLogger("robosuite_logs").addFilter(_DropMacroWarning())

import robosuite  # noqa: E402
from robosuite.environments.manipulation.single_arm_env import SingleArmEnv  # noqa: E402
from robosuite.models.arenas import TableArena  # noqa: E402
from robosuite.models.tasks import ManipulationTask  # noqa: E402
from robosuite.utils.transform_utils import quat2axisangle  # noqa: E402

TABLE_SIZE = (0.8, 1.2, 0.05)
TABLE_TOP = 0.8
AGENTVIEW_POS = (0.748, 0.0, 1.597)
AGENTVIEW_QUAT = (0.653, 0.271, 0.271, 0.653)
CAMERA_NAMES = {"agentview": "agentview", "wrist": "robot0_eye_in_hand"}


@dataclass
class FreeObject:
    """A free-joint object placed at reset: nominal xy on a surface, optionally sharing a jitter group."""

    name: str
    model: object  # a robosuite MujocoObject
    x: float
    y: float
    surface_z: float
    yaw: float = 0.0
    jitter: str | None = None  # "pick" or "goal": shares that group's seeded xy jitter


@dataclass
class Layout:
    """What a scene builder hands the simulator: objects, fixed bodies, roles and scene-specific facts."""

    free: list[FreeObject]
    static: list[tuple[object, tuple[float, float, float]]] = field(default_factory=list)
    pick: str = "pick"
    goal: str | None = None
    robot_back: float = 0.0
    jitter: float = 0.0
    facts: dict[str, object] = field(default_factory=dict)
    privileged: Callable[[dict], dict] | None = None  # adds scene-specific keys to privileged_state


def _yaw_quat_wxyz(yaw: float) -> np.ndarray:
    return np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])


class IndgenRobosuiteEnv(SingleArmEnv):
    """A robosuite single-arm env whose objects come from a ``Layout`` (rendering is done by the wrapper)."""

    def __init__(self, layout: Layout, control_freq: int = 20):
        self.layout = layout
        self._seed = 0
        controller = robosuite.load_controller_config(default_controller="OSC_POSE")
        super().__init__(
            robots="Panda",
            controller_configs=controller,
            gripper_types="default",
            initialization_noise=None,
            use_camera_obs=False,
            has_renderer=False,
            has_offscreen_renderer=False,
            control_freq=control_freq,
            horizon=10**9,
            ignore_done=True,
            hard_reset=False,
            camera_names=[],
            camera_heights=[],
            camera_widths=[],
            camera_depths=[],
        )

    # ---- model -------------------------------------------------------------------------------
    def _load_model(self) -> None:
        super()._load_model()
        robot = self.robots[0].robot_model
        xpos = np.array(robot.base_xpos_offset["table"](TABLE_SIZE[0]), dtype=float)
        xpos[0] -= self.layout.robot_back
        robot.set_base_xpos(xpos)
        arena = TableArena(
            table_full_size=TABLE_SIZE, table_friction=(1.0, 5e-3, 1e-4), table_offset=(0, 0, TABLE_TOP)
        )
        arena.set_origin([0, 0, 0])
        # robosuite's agentview, pulled back 0.35 m along its own view axis so the whole workspace is in frame
        arena.set_camera("agentview", pos=AGENTVIEW_POS, quat=AGENTVIEW_QUAT)
        for obj, pos in self.layout.static:
            obj.get_obj().set("pos", " ".join(f"{v:.6f}" for v in pos))
        objects = [f.model for f in self.layout.free] + [obj for obj, _ in self.layout.static]
        self.model = ManipulationTask(mujoco_arena=arena, mujoco_robots=[robot], mujoco_objects=objects)

    def _setup_references(self) -> None:
        super()._setup_references()
        m = self.sim.model
        self.obj_body = {f.name: m.body_name2id(f.model.root_body) for f in self.layout.free}
        self.obj_joint = {f.name: f.model.joints[0] for f in self.layout.free}
        self.obj_geoms = {
            f.name: np.array([m.geom_name2id(g) for g in f.model.contact_geoms], dtype=int)
            for f in self.layout.free
        }
        self._masks: dict[bytes, np.ndarray] = {}
        self.obj_qvel = {f.name: m.get_joint_qvel_addr(f.model.joints[0]) for f in self.layout.free}
        self.eef_body = m.body_name2id(self.robots[0].robot_model.eef_name)
        gripper = self.robots[0].gripper
        self.finger_geoms = np.array([m.geom_name2id(g) for g in gripper.contact_geoms], dtype=int)
        if not hasattr(self, "extent"):
            self.extent = self._measure_extents()

    def _measure_extents(self) -> dict[str, np.ndarray]:
        """Per free object: (min z, max z, horizontal half extent) of its geoms in its body frame."""
        m, d = self.sim.model._model, self.sim.data._data
        import mujoco

        saved = d.qpos.copy()
        for i, f in enumerate(self.layout.free):
            self.sim.data.set_joint_qpos(self.obj_joint[f.name], np.array([0, 0, 5.0 + 2 * i, 1, 0, 0, 0]))
        mujoco.mj_forward(m, d)
        out = {}
        root = m.body_rootid
        for f in self.layout.free:
            b = self.obj_body[f.name]
            geoms = [
                g
                for g in range(m.ngeom)
                if root[m.geom_bodyid[g]] == b and m.geom_contype[g] | m.geom_conaffinity[g]
            ]
            corners = []
            for g in geoms:
                c, h = m.geom_aabb[g][:3], m.geom_aabb[g][3:]
                signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
                pts = d.geom_xpos[g] + (d.geom_xmat[g].reshape(3, 3) @ (c + signs * h).T).T
                corners.append(pts - d.xpos[b])
            pts = np.concatenate(corners)
            out[f.name] = np.array([pts[:, 2].min(), pts[:, 2].max(), np.abs(pts[:, :2]).max(axis=0).max()])
        d.qpos[:] = saved
        mujoco.mj_forward(m, d)
        return out

    # ---- reset / placement -------------------------------------------------------------------
    def seed_placement(self, seed: int) -> None:
        self._seed = int(seed)

    def _reset_internal(self) -> None:
        super()._reset_internal()
        # robosuite keeps the Panda gripper's integrated command across soft resets; clear it so that an
        # episode never depends on the one before (bit-for-bit reproducible episodes)
        gripper = self.robots[0].gripper
        gripper.current_action = np.zeros(gripper.dof)
        rng = np.random.default_rng(self._seed)
        j = self.layout.jitter
        offsets = {"pick": rng.uniform(-j, j, size=2), "goal": rng.uniform(-j, j, size=2)}
        self.jitter_offsets = offsets
        for f in self.layout.free:
            dx, dy = offsets[f.jitter] if f.jitter else (0.0, 0.0)
            z = f.surface_z - self.extent[f.name][0] + 0.001
            pose = np.concatenate([[f.x + dx, f.y + dy, z], _yaw_quat_wxyz(f.yaw)])
            self.sim.data.set_joint_qpos(self.obj_joint[f.name], pose)
            self.sim.data.set_joint_qvel(self.obj_joint[f.name], np.zeros(6))

    # ---- success / state ---------------------------------------------------------------------
    def reward(self, action=None) -> float:
        return 0.0

    def _check_success(self) -> bool:
        return False  # the wrapper evaluates the scene's success predicate on privileged_state()

    def _mask(self, geoms: np.ndarray) -> np.ndarray:
        key = geoms.tobytes()
        mask = self._masks.get(key)
        if mask is None:
            mask = np.zeros(self.sim.model.ngeom, dtype=bool)
            mask[geoms] = True
            self._masks[key] = mask
        return mask

    def contact_between(self, geoms_a: np.ndarray, geoms_b: np.ndarray) -> bool:
        """Is any geom of ``geoms_a`` touching any geom of ``geoms_b`` (boolean masks: ~2 us per call)?"""
        d = self.sim.data._data
        n = d.ncon
        if n == 0:
            return False
        g = d.contact.geom[:n]
        a, b = self._mask(geoms_a), self._mask(geoms_b)
        return bool(np.any((a[g[:, 0]] & b[g[:, 1]]) | (a[g[:, 1]] & b[g[:, 0]])))

    def object_pose(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        b = self.obj_body[name]
        return self.sim.data.body_xpos[b].copy(), self.sim.data.body_xquat[b].copy()  # quat wxyz

    def privileged_state(self) -> dict:
        """Poses, velocities and contacts the oracle and the success predicate read."""
        d = self.sim.data
        robot = self.robots[0]
        eef_pos = np.array(d.site_xpos[robot.eef_site_id])
        lay = self.layout
        pick_pos, pick_quat = self.object_pose(lay.pick)
        ext = self.extent[lay.pick]
        lo, _ = self.obj_qvel[lay.pick]
        vel = d.qvel[lo : lo + 3]
        state: dict = {
            "eef_pos": eef_pos,
            "eef_mat": np.array(d.site_xmat[robot.eef_site_id]).reshape(3, 3),
            "gripper_qpos": np.array(d.qpos[robot._ref_gripper_joint_pos_indexes]),
            "pick_pos": pick_pos,
            "pick_quat_wxyz": pick_quat,
            "pick_linvel": np.array(vel[:3]),
            "pick_bottom": float(pick_pos[2] + ext[0]),
            "pick_top": float(pick_pos[2] + ext[1]),
            "pick_half_width": float(ext[2]),
            "pick_touching_gripper": self.contact_between(self.finger_geoms, self.obj_geoms[lay.pick]),
            "table_top": TABLE_TOP,
        }
        if lay.goal is not None:
            gp, gq = self.object_pose(lay.goal)
            state["goal_pos"], state["goal_quat_wxyz"] = gp, gq
            state["goal_top"] = float(gp[2] + self.extent[lay.goal][1])
        state.update(lay.facts)
        if lay.privileged is not None:
            state.update(lay.privileged(state))
        return state

    def robot_state(self) -> np.ndarray:
        """The LIBERO 8-d state: eef pos, eef axis-angle, gripper qpos (2)."""
        robot = self.robots[0]
        d = self.sim.data
        pos = np.array(d.site_xpos[robot.eef_site_id])
        quat_xyzw = np.array(d.body_xquat[self.eef_body])[[1, 2, 3, 0]]
        grip = np.array(d.qpos[robot._ref_gripper_joint_pos_indexes])
        return np.concatenate([pos, quat2axisangle(quat_xyzw), grip]).astype(np.float32)
