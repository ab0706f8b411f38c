"""RoboCasa365 inside its own venv: the backend ``scenes/external_worker.py`` loads (robosuite 1.5, mujoco 3.3.1).

Imports only the standard library, numpy and RoboCasa. A level is T0's episode with one field of RoboCasa's episode
metadata edited (``edit_ep_meta``): episode ``seed`` first resets T0 (layout, style, objects and their poses drawn
from ``seed``), then, for a level k > 0, resets again from T0's ``ep_meta`` with the axis's one field moved.

Observation and action follow RoboCasa's own gym wrapper (``robocasa/wrappers/gym_wrapper.py``) and lerobot's
``lerobot/envs/robocasa.py``: state = base-to-eef pos (3) + base-to-eef quat (4) + base pos (3) + base quat (4) +
gripper qpos (2); action = eef pos (3) + eef rot (3) + gripper (1) + base motion (4) + control mode (1), RoboCasa's
``convert_action`` order, composed into robosuite's flat action by the composite controller's split indexes; camera
images upright (the wrapper flips robosuite's raw frames).
"""

from __future__ import annotations

import copy
import os

import numpy as np

CAMERAS = ("robot0_agentview_left", "robot0_agentview_right", "robot0_eye_in_hand")
_T0_META: dict[
    tuple, dict
] = {}  # (task, layouts, styles, seed) -> T0 ep_meta: a worker reuses it across levels


def versions() -> dict:
    import mujoco
    import robocasa
    import robosuite

    try:
        from importlib.metadata import version

        dist = version("rlinf-robocasa365")
    except Exception:
        dist = "?"
    return {
        "robocasa": getattr(robocasa, "__version__", "?"),
        "robocasa_dist": f"rlinf-robocasa365 {dist}",
        "robosuite": robosuite.__version__,
        "mujoco": mujoco.__version__,
        "numpy": np.__version__,
    }


def edit_ep_meta(meta: dict, edits: dict) -> dict:
    """T0's ep_meta with the level's one field moved (each edit touches exactly one ep_meta field)."""
    meta = copy.deepcopy(meta)
    back = float(edits.get("base_back", 0.0))
    if back:
        # the base faces +x of its own frame (yaw = ori[2]): moving it back lengthens the reach
        yaw = float(meta["init_robot_base_ori"][2])
        pos = list(meta["init_robot_base_pos"])
        pos[0] -= back * np.cos(yaw)
        pos[1] -= back * np.sin(yaw)
        meta["init_robot_base_pos"] = pos
    dx = float(edits.get("pick_x", 0.0))
    if dx:
        cfg = next(c for c in meta["object_cfgs"] if c.get("name") == "obj")
        off = list(cfg["placement"].get("offset", (0.0, 0.0)))
        off[0] = float(off[0]) + dx
        cfg["placement"]["offset"] = off
    return meta


def _flat_action(env, action: np.ndarray) -> np.ndarray:
    """RoboCasa's flat 12-d action -> robosuite's composite-controller action (RoboCasaGymEnv.step's composition)."""
    from robocasa.utils.env_utils import convert_action
    from robocasa.wrappers.gym_wrapper import PandaOmronKeyConverter
    from robosuite.controllers.composite.composite_controller import HybridMobileBase

    parts = PandaOmronKeyConverter.unmap_action(convert_action(np.asarray(action, dtype=np.float64)))
    robot = env.robots[0]
    cc = robot.composite_controller
    pf = robot.robot_model.naming_prefix
    out = np.zeros(cc.action_limits[0].shape)
    for name in cc.part_controllers:
        lo, hi = cc._action_split_indexes[name]
        out[lo:hi] = parts.pop(f"{pf}{name}")
    if isinstance(cc, HybridMobileBase):
        out[-1] = parts.pop(f"{pf}base_mode")
    return out


class RoboCasaLevel:
    """One (task, level) of RoboCasa: built once, reset per episode from the episode's seed."""

    def __init__(self, config: dict):
        import robocasa  # noqa: F401  (registers the kitchen tasks with robosuite)
        import robosuite

        self.cfg = config
        self.cameras = tuple(config.get("cameras", ()))
        h, w = config.get("image_size", (256, 256))
        self.env = robosuite.make(
            config["task"],
            robots="PandaOmron",
            has_renderer=False,
            has_offscreen_renderer=bool(self.cameras),
            use_camera_obs=bool(self.cameras),
            camera_names=list(self.cameras) or "robot0_agentview_left",
            camera_heights=h,
            camera_widths=w,
            ignore_done=True,
            layout_ids=config.get("layout_ids"),
            style_ids=config.get("style_ids"),
            obj_registries=tuple(config.get("obj_registries", ("objaverse", "lightwheel"))),
            robot_spawn_deviation_pos_x=0.0,
            robot_spawn_deviation_pos_y=0.0,
            translucent_robot=False,
        )
        self.meta: dict = {}

    def mj_data(self):
        return self.env.sim.data._data if self.env.sim is not None else None

    def _reset_from(self, seed: int, meta: dict | None):
        self.env.unset_ep_meta()
        if meta is not None:
            self.env.set_ep_meta(copy.deepcopy(meta))
        self.env.rng = np.random.default_rng(seed)
        return self.env.reset()

    def reset(self, seed: int) -> dict:
        edits = {k: v for k, v in self.cfg.get("edits", {}).items() if v}
        key = (self.cfg["task"], str(self.cfg.get("layout_ids")), str(self.cfg.get("style_ids")), int(seed))
        t0 = _T0_META.get(key)
        if t0 is None:
            self._reset_from(seed, None)
            t0 = _T0_META[key] = self.env.get_ep_meta()
        # every level, level 0 included, replays T0's metadata with the same rng stream: a replay draws nothing
        # for the layout/style/objects, so object poses agree across levels only if level 0 is replayed too
        meta = edit_ep_meta(t0, edits)
        raw = self._reset_from(seed, meta)
        self.meta = self.env.get_ep_meta()
        return self._obs(raw)

    def step(self, action) -> dict:
        raw, _, _, _ = self.env.step(_flat_action(self.env, action))
        obs = self._obs(raw)
        obs["success"] = bool(self.env._check_success())
        return obs

    def _obs(self, raw: dict) -> dict:
        state = np.concatenate(
            [
                raw["robot0_base_to_eef_pos"], raw["robot0_base_to_eef_quat"], raw["robot0_base_pos"],
                raw["robot0_base_quat"], raw["robot0_gripper_qpos"],
            ]
        ).astype(np.float32)  # fmt: skip
        images = {
            c: np.ascontiguousarray(raw[f"{c}_image"][::-1]) for c in self.cameras if f"{c}_image" in raw
        }
        return {"state": state, "images": images, "instruction": self.env.get_ep_meta().get("lang", "")}

    def privileged(self) -> dict:
        """What oracles and tests read: the pick object's pose, the robot base, and RoboCasa's fixture states."""
        env = self.env
        out: dict = {"base_pos": np.array(env.sim.data.get_body_xpos("mobilebase0_base"), dtype=np.float64)}
        if "obj" in getattr(env, "objects", {}):
            bid = env.obj_body_id["obj"]
            out["obj_pos"] = np.array(env.sim.data.body_xpos[bid])
            out["obj_quat"] = np.array(env.sim.data.body_xquat[bid])
        mixer = getattr(env, "stand_mixer", None)
        if mixer is not None:
            out["stand_mixer"] = {k: float(v) for k, v in mixer.get_state(env).items() if np.isscalar(v)}
        out["success"] = bool(env._check_success())
        return out

    def ep_meta(self) -> dict:
        return copy.deepcopy(self.meta)

    def close(self) -> None:
        self.env.close()


def build(config: dict) -> RoboCasaLevel:
    os.environ.setdefault("MUJOCO_GL", "egl")
    if config.get("assets"):
        os.environ["ROBOCASA_ASSETS_PATH"] = config["assets"]
    return RoboCasaLevel(config)
