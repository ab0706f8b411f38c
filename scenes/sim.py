"""The one robosuite environment every scene builds into: a Panda at a table plus a ``Layout`` of objects.

Importing this module imports robosuite and MuJoCo; ``scenes`` and ``scenes.tabletop`` never do.
Placement is seeded from the episode seed alone (numpy Generator), the robot starts without
initialisation noise, and the model is built once per env (``hard_reset=False``), so the same
(scene, task, axis, level, seed) gives the same initial state bit for bit in any process.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

import scenes.mujoco_geom as geom
from indgen_vla.core.errors import SceneError
from scenes.privileged import NO_FACTS, GoalState, PickState, PrivilegedState, SceneFacts, Targets

os.environ.setdefault("MUJOCO_GL", "egl")  # robosuite's macro-file warning: dropped by ``scenes`` (__init__)

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
    targets: Callable[[PickState, GoalState | None], Targets]  # where the oracle grasps and places, per state
    static: list[tuple[object, tuple[float, float, float]]] = field(default_factory=list)
    pick: str = "pick"
    goal: str | None = None
    robot_back: float = 0.0
    jitter: float = 0.0
    facts: SceneFacts = NO_FACTS  # constant geometry the scene's success predicate reads


def _yaw_quat_wxyz(yaw: float) -> np.ndarray:
    return np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])


def fast_path_refusal(env) -> str | None:
    """Why ``FastControl`` cannot reproduce ``env.step`` bit for bit (None when it can)."""
    import mujoco
    from robosuite.controllers.base_controller import Controller
    from robosuite.models.grippers.panda_gripper import PandaGripper

    m = env.sim.model._model
    if len(env.robots) != 1 or not hasattr(env.robots[0], "controller"):
        return "only single-arm robosuite envs are supported"
    robot = env.robots[0]
    if type(robot.controller).update is not Controller.update:
        return f"controller {type(robot.controller).__name__} overrides update()"
    if not isinstance(robot.gripper, PandaGripper):
        return f"gripper {type(robot.gripper).__name__} is not robosuite's PandaGripper"
    if m.opt.solver == mujoco.mjtSolver.mjSOL_PGS:
        return "the PGS solver warm-starts from efc_force, which every mj_forward rewrites"
    if m.ntendon or m.nflex or m.opt.enableflags & mujoco.mjtEnableBit.mjENBL_SLEEP:
        return "tendons, flexes or sleeping need more of mj_forward than the light pass computes"
    if viewer := getattr(env, "viewer", None):
        return f"a viewer ({type(viewer).__name__}) is attached"
    return None


class FastControl:
    """robosuite 1.4's ``step`` for one OSC arm without its redundant work: the same states, bit for bit.

    Stock robosuite runs two full ``mj_forward`` per 2 ms substep (one in ``step``, one in the controller's
    ``update``), updates every observable and pushes proprioception buffers nobody here reads. ``mj_forward``
    only writes derived quantities (the Newton/CG warm start ``qacc_warmstart`` is written by ``mj_step``
    alone), so a light pass computing exactly what the controller reads (kinematics, com frames, inertia,
    com velocities, bias forces; the same MuJoCo functions on the same inputs) followed by robosuite's own
    ``set_goal``/``run_controller`` arithmetic and ``mj_step`` gives the stock trajectory. Unless ``observe``,
    observables are not updated: callers read ``sim.data`` (``robot_state``, ``privileged_state``) instead.
    """

    def __init__(self, env, observe: bool = False):
        import mujoco

        self.env, self.mujoco, self.observe = env, mujoco, observe
        self.m, self.d = env.sim.model._model, env.sim.data._data
        robot = env.robots[0]
        self.robot, self.controller, self.gripper = robot, robot.controller, robot.gripper
        c = self.controller
        self.site = env.sim.model.site_name2id(c.eef_name)
        self.control_dim = c.control_dim
        self.arm_actuators = np.asarray(robot._ref_joint_actuator_indexes)
        self.torque_low, self.torque_high = robot.torque_limits
        self.grip_actuators = [env.sim.model.actuator_name2id(a) for a in self.gripper.actuators]
        ctrl_range = env.sim.model.actuator_ctrlrange[self.grip_actuators]
        self.grip_actuators = np.asarray(self.grip_actuators)
        self.grip_bias = 0.5 * (ctrl_range[:, 1] + ctrl_range[:, 0])
        self.grip_weight = 0.5 * (ctrl_range[:, 1] - ctrl_range[:, 0])
        self.qpos_index, self.qvel_index = np.asarray(c.qpos_index), np.asarray(c.qvel_index)
        nv = self.m.nv
        self.jacp, self.jacr, self.full_m = np.zeros((3, nv)), np.zeros((3, nv)), np.zeros((nv, nv))
        self.substeps = int(env.control_timestep / env.model_timestep)
        from robosuite.controllers.osc import OperationalSpaceController
        from robosuite.models.grippers.panda_gripper import PandaGripper
        from robosuite.utils import control_utils

        self.plain_osc = (
            type(c) is OperationalSpaceController
            and c.impedance_mode == "fixed"
            and c.uncoupling
            and c.interpolator_pos is None
            and c.interpolator_ori is None
        )
        self.panda_grip = type(self.gripper).format_action is PandaGripper.format_action
        self.orientation_error = control_utils.orientation_error
        self.opspace_matrices = control_utils.opspace_matrices
        self.nullspace_torques = control_utils.nullspace_torques
        self.action_dim = env.action_dim

    def _controller_inputs(self) -> None:
        """What ``step``'s ``sim.forward()`` and ``Controller.update`` give the controller, from a light pass."""
        mj, m, d, c = self.mujoco, self.m, self.d, self.controller
        mj.mj_kinematics(m, d)
        mj.mj_comPos(m, d)
        mj.mj_makeM(m, d)
        mj.mj_comVel(m, d)
        mj.mj_rne(m, d, 0, d.qfrc_bias)
        if not c.new_update:  # like update(): a freshly built controller keeps the values it was built with
            return
        jacp, jacr, full_m = self.jacp, self.jacr, self.full_m  # both MuJoCo calls overwrite every entry
        mj.mj_jacSite(m, d, jacp, jacr, self.site)
        c.ee_pos = np.array(d.site_xpos[self.site])
        c.ee_ori_mat = np.array(d.site_xmat[self.site].reshape([3, 3]))
        c.ee_pos_vel = np.dot(jacp, d.qvel)
        c.ee_ori_vel = np.dot(jacr, d.qvel)
        c.joint_pos = d.qpos[self.qpos_index]
        c.joint_vel = d.qvel[self.qvel_index]
        c.J_pos = jacp[:, self.qvel_index]
        c.J_ori = jacr[:, self.qvel_index]
        c.J_full = np.concatenate([c.J_pos, c.J_ori])  # = np.vstack of 2-d arrays, layout included
        mj.mj_fullM(m, full_m, d.qM)
        # F-ordered like robosuite's slice: numba compiles per layout and a C-ordered copy changes the last bits
        c.mass_matrix = full_m[self.qvel_index, :][:, self.qvel_index]
        c.new_update = False  # the controller's own update() (and its mj_forward) is skipped

    def _torques(self) -> np.ndarray:
        """``OperationalSpaceController.run_controller`` for its default setup (fixed impedance, no
        interpolators, decoupled), the same NumPy/numba operations on the same array layouts, minus copies."""
        c = self.controller
        if not self.plain_osc:
            return c.run_controller()
        ori_error = self.orientation_error(np.array(c.goal_ori), c.ee_ori_mat)
        force = (np.array(c.goal_pos) - c.ee_pos) * c.kp[0:3] + (-c.ee_pos_vel) * c.kd[0:3]
        torque = ori_error * c.kp[3:6] + (-c.ee_ori_vel) * c.kd[3:6]
        _, lambda_pos, lambda_ori, nullspace = self.opspace_matrices(
            c.mass_matrix, c.J_full, c.J_pos, c.J_ori
        )
        wrench = np.concatenate([np.dot(lambda_pos, force), np.dot(lambda_ori, torque)])
        torques = np.dot(c.J_full.T, wrench) + self.d.qfrc_bias[self.qvel_index]
        torques += self.nullspace_torques(c.mass_matrix, nullspace, c.initial_joint, c.joint_pos, c.joint_vel)
        c.torques = torques
        c.new_update = True
        return torques

    def _grip(self, grip: np.ndarray, delta: np.ndarray | None) -> np.ndarray:
        """``PandaGripper.format_action``: the gripper command integrates by ``speed`` every substep."""
        g = self.gripper
        if delta is None:
            return g.format_action(grip)
        g.current_action = np.minimum(np.maximum(g.current_action + delta, -1.0), 1.0)
        return g.current_action

    def step(self, action) -> tuple[dict, float, bool, dict]:
        env, d, c = self.env, self.d, self.controller
        if env.done:
            raise ValueError("executing action in terminated episode")
        if len(action) != self.action_dim:
            raise ValueError(f"expected a {self.action_dim}-d action, got {len(action)}-d")
        env.timestep += 1
        arm, grip = action[: self.control_dim], action[self.control_dim :]
        grip_delta = np.array([-1.0, 1.0]) * self.gripper.speed * np.sign(grip) if self.panda_grip else None
        for i in range(self.substeps):
            self._controller_inputs()
            if i == 0:
                c.set_goal(arm)
            torques = np.minimum(np.maximum(self._torques(), self.torque_low), self.torque_high)  # = np.clip
            self.robot.torques = torques
            d.ctrl[self.grip_actuators] = self.grip_bias + self.grip_weight * self._grip(grip, grip_delta)
            d.ctrl[self.arm_actuators] = torques
            self.mujoco.mj_step(self.m, d)
            if self.observe:
                env._update_observables()
        env.cur_time += env.control_timestep
        reward, done, info = env._post_action(action)
        return (env._get_observations() if self.observe else {}), reward, done, info

    def fresh(self) -> bool:
        """Still bound to ``env``'s current simulator and controller (resets may rebuild either)."""
        return self.d is self.env.sim.data._data and self.controller is self.env.robots[0].controller


def fast_step(env, action, observe: bool = True) -> tuple[dict, float, bool, dict]:
    """``env.step(action)`` of any robosuite single-arm env through ``FastControl``, bit for bit.

    With ``observe`` the observables update every substep and the observation dict comes back, as stock.
    """
    fast = getattr(env, "_indgen_fast", None)
    if fast is None or not fast.fresh() or fast.observe != observe:
        refusal = fast_path_refusal(env)
        if refusal is not None:
            raise SceneError(f"fast_physics is unavailable here: {refusal}; pass fast_physics=False")
        fast = env._indgen_fast = FastControl(env, observe=observe)
    return fast.step(action)


class IndgenRobosuiteEnv(SingleArmEnv):
    """A robosuite single-arm env whose objects come from a ``Layout`` (rendering is done by the wrapper).

    ``fast_physics`` (default) steps through ``FastControl`` (stock states bit for bit, observables not
    updated, ``step`` returns an empty observation dict); False runs robosuite's own ``step``.
    """

    def __init__(self, layout: Layout, control_freq: int = 20, fast_physics: bool = True):
        self.layout = layout
        self._seed = 0
        self.fast_physics = bool(fast_physics)
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

    def step(self, action):
        if not self.fast_physics:
            return super().step(action)
        return fast_step(self, action, observe=False)

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
        self.obj_qvel = {f.name: m.get_joint_qvel_addr(f.model.joints[0]) for f in self.layout.free}
        self.eef_body = m.body_name2id(self.robots[0].robot_model.eef_name)
        raw = m._model
        fingers = geom.named_geoms(raw, self.robots[0].gripper.contact_geoms)
        self._finger_mask = geom.geom_mask(raw, fingers)
        pick = next(f for f in self.layout.free if f.name == self.layout.pick)
        self._pick_mask = geom.geom_mask(raw, geom.named_geoms(raw, pick.model.contact_geoms))
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
        for f in self.layout.free:
            b = self.obj_body[f.name]
            pts = geom.geom_corners(m, d, geom.body_geoms(m, b)) - d.xpos[b]
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

    def object_pose(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        b = self.obj_body[name]
        return self.sim.data.body_xpos[b].copy(), self.sim.data.body_xquat[b].copy()  # quat wxyz

    def privileged_state(self) -> PrivilegedState:
        """Poses, velocities and contacts the oracle and the success predicate read."""
        d = self.sim.data
        lay = self.layout
        pick_pos, pick_quat = self.object_pose(lay.pick)
        ext = self.extent[lay.pick]
        lo, _ = self.obj_qvel[lay.pick]
        pick = PickState(
            pos=pick_pos,
            quat_wxyz=pick_quat,
            linvel=np.array(d.qvel[lo : lo + 3]),
            bottom=float(pick_pos[2] + ext[0]),
            top=float(pick_pos[2] + ext[1]),
            half_width=float(ext[2]),
            touching_gripper=geom.touching(d._data, self._finger_mask, self._pick_mask),
        )
        goal = None
        if lay.goal is not None:
            gp, gq = self.object_pose(lay.goal)
            goal = GoalState(pos=gp, quat_wxyz=gq, top=float(gp[2] + self.extent[lay.goal][1]))
        eef_pos, eef_mat, gripper_qpos = geom.grip_site(d, self.robots[0])
        return PrivilegedState(
            eef_pos=eef_pos,
            eef_mat=eef_mat,
            gripper_qpos=gripper_qpos,
            pick=pick,
            goal=goal,
            target=lay.targets(pick, goal),
            table_top=TABLE_TOP,
            facts=lay.facts,
        )

    def robot_state(self) -> np.ndarray:
        """The LIBERO 8-d state: eef pos, eef axis-angle, gripper qpos (2)."""
        robot = self.robots[0]
        d = self.sim.data
        pos = np.array(d.site_xpos[robot.eef_site_id])
        quat_xyzw = np.array(d.body_xquat[self.eef_body])[[1, 2, 3, 0]]
        grip = np.array(d.qpos[robot._ref_gripper_joint_pos_indexes])
        return np.concatenate([pos, quat2axisangle(quat_xyzw), grip]).astype(np.float32)
