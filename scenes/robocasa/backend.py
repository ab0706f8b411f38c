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
# the fixture each fixture_x task moves (its fixture_refs / attribute name in RoboCasa's task class)
MOVED_FIXTURE = {
    "CloseStandMixerHead": "stand_mixer", "OpenStandMixerHead": "stand_mixer", "TurnOnElectricKettle": "electric_kettle",
    "OpenElectricKettleLid": "electric_kettle", "CloseElectricKettleLid": "electric_kettle", "TurnOnBlender": "blender",
}  # fmt: skip
FIXTURE_KEY = (
    "indgen_fixture_offset"  # the ep_meta field fixture_x edits: {"fixture": name, "offset": [dx, 0, 0]}
)
# (task, layouts, styles, seed, t0 edits) -> T0: its ep_meta and the placements it sampled, reused across levels
_T0: dict[tuple, dict] = {}


def _load_beside(name: str):
    """``NAME.py`` beside this file, by path: the worker's sys.path has no ``scenes`` package."""
    import importlib.util

    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), f"{name}.py")
    spec = importlib.util.spec_from_file_location(f"indgen_robocasa_{name}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


_facts = _load_beside("worker_facts")
versions, failure_facts, check_kitchen = _facts.versions, _facts.failure_facts, _facts.check_kitchen
oracle_facts = _facts.oracle_facts
placement = _load_beside("placement_check")  # fixture_x / base_y moves checked after the settle
window = _load_beside("pick_window")  # pick_x's window on RoboCasa's range in the episode's kitchen
PICK_JITTER = window.PICK_JITTER
splits = _load_beside("splits")  # RoboCasa365's split and the object registries: the Kitchen's arguments
_patches = _load_beside("worker_patches")
unique_in_order = _patches.unique_in_order  # what counter.py's ``set`` becomes (tests read it here)


def _yaw(quat_wxyz) -> float:
    w, _, _, z = (float(q) for q in quat_wxyz)
    return 2.0 * np.arctan2(z, w)


def edit_ep_meta(
    meta: dict, edits: dict, fixture: str | None = None, cab: str | None = None, pick: str = "obj"
) -> dict:
    """T0's ep_meta with the level's one field moved (each edit touches exactly one ep_meta field).

    ``base_back`` moves ``init_robot_base_pos`` back along the base's heading; ``pick_x`` the pick object's
    config's (``pick``: ``"obj"``, CheesyBread's ``"cheese"``) ``placement.offset[0]``; ``fixture_x`` sets ``FIXTURE_KEY`` (the moved fixture and its offset in its own frame);
    ``clutter`` appends that many object configs placed in the cabinet ``cab`` (``object_cfgs``).
    """
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
        cfg = next(c for c in meta["object_cfgs"] if c.get("name") == pick)
        off = list(cfg["placement"].get("offset", (0.0, 0.0)))
        off[0] = float(off[0]) + dx
        cfg["placement"]["offset"] = off
    fx = float(edits.get("fixture_x", 0.0))
    if fx:
        meta[FIXTURE_KEY] = {"fixture": fixture, "offset": [fx, 0.0, 0.0]}
    n = int(edits.get("clutter", 0))
    if n:
        like = [c for c in meta["object_cfgs"] if c.get("placement", {}).get("fixture") == cab]
        if not like:
            raise ValueError(f"the clutter successor needs an object config placed in the cabinet {cab}")
        model = copy.deepcopy(next((c for c in like if c["name"] != "obj"), like[0]))
        for k in ("info", "reset_region"):
            model.pop(k, None)  # a new object: RoboCasa chooses its model and region
        model["placement"].update(size=(1.0, 0.20), pos=(0.0, 1.0), offset=(0.0, 0.0))  # the cabinet's back
        model.update(obj_groups="all", graspable=False)
        meta["object_cfgs"] = meta["object_cfgs"] + [{**copy.deepcopy(model), "name": f"clutter_{i + 1}"}
                                                     for i in range(n)]  # fmt: skip
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
    """One (task, level) of RoboCasa: built once, reset per episode from the episode's seed.

    Episode ``seed`` at level 0 is RoboCasa's own reset from ``seed`` in the run's split (T0; on ``pick_x`` with the
    pick object's centre x drawn in a 2 x ``PICK_JITTER`` window, or a level's step where narrower, at the low end
    of the range RoboCasa samples it in, in that kitchen, RoboCasa's footprint rule and robot base kept:
    ``pick_window``). Its ep_meta and the placements it
    drew are kept per worker; a level k > 0 (or a later reset of the same seed) replays that ep_meta with the level's one field edited,
    every fixture and object placement pinned to T0's except what the edit moves, and the post-load draws
    (``_setup_scene``) from the same stream, so T0 and level k differ in the one field only.
    """

    def __init__(self, config: dict):
        import robocasa  # noqa: F401  (registers the kitchen tasks with robosuite)
        import robosuite
        from robosuite.controllers import load_composite_controller_config

        _patches.install_patches(window)
        self.cfg = config
        self.cameras = tuple(config.get("cameras", ()))
        h, w = config.get("image_size", (256, 256))
        # a config without a split (a test's): "all", RoboCasa's Kitchen defaults
        self._split = (config.get("split", "all"), config.get("obj_registries", splits.DEFAULT_REGISTRIES))
        kitchen = splits.kitchen_kwargs(*self._split, config.get("layout_ids"), config.get("style_ids"))
        # a category with no model in the split: one line naming the choice
        with splits.one_line(*self._split):
            self.env = robosuite.make(
                config["task"],
                robots="PandaOmron",
                # as RoboCasa's create_env (robocasa/utils/env_utils.py): given a config, Kitchen.__init__ drives the
                # base with JOINT_VELOCITY_LEGACY, whose base_motion is in the base's current frame (robosuite's
                # default JOINT_VELOCITY turns it the other way once the base has turned)
                controller_configs=load_composite_controller_config(controller=None, robot="PandaOmron"),
                has_renderer=False,
                has_offscreen_renderer=bool(self.cameras),
                use_camera_obs=bool(self.cameras),
                camera_names=list(self.cameras) or "robot0_agentview_left",
                camera_heights=h,
                camera_widths=w,
                ignore_done=True,
                # the split's kitchens and object instances, or the run's one canonical kitchen, and the object
                # registries
                **kitchen,
                robot_spawn_deviation_pos_x=0.0,  # RoboCasa's 0.15 / 0.05 m jitter off: a documented choice
                robot_spawn_deviation_pos_y=0.0,  # (scenes/robocasa/departures.py SPAWN_JITTER, in the manifest)
                translucent_robot=False,
            )
        self.env._indgen_pins = self.env._indgen_made = self.env._indgen_seed = None
        self.env._indgen_task_fixture = None  # T0's task fixture on a replay (keep_task_fixture)
        self.env._indgen_pick = config.get("pick")  # pick_x: the window's config (pick_window.level_offset)
        self.env._indgen_pick_range = None  # RoboCasa's x range of the pick object at the last load
        self.env._indgen_pick_buffer = 0.0  # RoboCasa's _sample_x buffer of the pick object at the last load
        self.env._indgen_pick_t0 = None  # on a level's replay: T0's range, the high end every level keeps
        self.env._indgen_drawn = {}  # cfg name -> (object kwargs, info) RoboCasa drew at the last load
        self.meta: dict = {}
        self._seed = 0
        self._placed: dict = {}
        env = self.env
        load, settle = env._load_model, env._reset_internal

        def load_model(*args, **kwargs):  # what T0 drew, before _reset_internal moves sliding-fixture objects
            load(*args, **kwargs)
            self._placed = {
                n: (tuple(map(float, p)), tuple(map(float, q)))
                for n, (p, q, _) in env.object_placements.items()
            }
            keep_task_fixture(env, self.cfg["task"], getattr(env, "_indgen_task_fixture", None))
            shift = getattr(env, "_indgen_fixture_shift", None)
            if shift:  # fixture_x: the moved fixture, after the objects were placed clear of it at T0's pose
                name, d = shift
                for n in (name, *auxiliaries(env, name)):  # the blender's lid goes along (RoboCasa checks it)
                    fx = env.fixtures[n]
                    pos, quat, _ = env.fxtr_placements[n]
                    fx.set_pos(np.add(pos, d))
                    env.fxtr_placements[n] = (np.add(pos, d), quat, fx)

        def reset_internal():  # the post-load draws (door angles, mixer head) from one stream, fresh or replayed
            env.rng = np.random.default_rng([self._seed, 1])
            settle()

        env._load_model, env._reset_internal = load_model, reset_internal

    def mj_data(self):
        return self.env.sim.data._data if self.env.sim is not None else None

    def _reset(self, seed: int, meta: dict, pins: dict | None = None, made: dict | None = None, shift=None):
        """RoboCasa's reset from ``meta`` (T0: the layout and style only) with the stream of ``seed`` after the
        layout draw, so T0 and a replay draw the same fixture placements."""
        self._seed = self.env._indgen_seed = int(seed)
        self.env.unset_ep_meta()
        self.env.set_ep_meta(copy.deepcopy(meta))
        self.env._indgen_pins, self.env._indgen_made, self.env._indgen_fixture_shift = pins, made, shift
        self.env._indgen_pick_range, self.env._indgen_pick_buffer = None, 0.0
        self.env.rng = np.random.default_rng([self._seed, 0])
        try:
            with splits.one_line(*self._split):
                return self.env.reset()
        finally:
            self.env._indgen_pins = self.env._indgen_made = self.env._indgen_fixture_shift = None

    def _t0(self, seed: int) -> tuple[dict, dict | None]:
        """T0 of ``seed`` (cached per worker) and, when this reset made it, its observation."""
        key = (self.cfg["task"], str(self.cfg.get("layout_ids")), str(self.cfg.get("style_ids")), int(seed),
               bool(self.cfg.get("pick")), self.cfg.get("split"), str(self.cfg.get("obj_registries")))  # fmt: skip
        if key in _T0:
            return _T0[key], None
        # RoboCasa's own layout/style draw (kitchen.py _setup_model: rng.choice(layout_and_style_ids)), from seed
        layout, style = np.random.default_rng(int(seed)).choice(self.env.layout_and_style_ids)
        raw = self._reset(seed, {"layout_id": int(layout), "style_id": int(style)})
        moved = MOVED_FIXTURE.get(self.cfg["task"])
        t0 = {
            "meta": self.env.get_ep_meta(),
            "placed": dict(self._placed),
            "made": copy.deepcopy(self.env._indgen_drawn),
            "fixtures": {
                n: (tuple(map(float, p)), tuple(map(float, q)))
                for n, (p, q, _) in self.env.fxtr_placements.items()
            },
            "fixture": getattr(self.env, moved).name if moved and hasattr(self.env, moved) else None,
            "pick_range": self.env._indgen_pick_range,  # pick_x: RoboCasa's x range of the object in this kitchen
            "pick_buffer": self.env._indgen_pick_buffer,  # and how far inside each end it keeps the object's centre
        }
        _T0[key] = t0
        return t0, raw

    def _pins(self, t0: dict, meta: dict, edits: dict) -> tuple[dict, tuple | None]:
        """T0's object placements except what the edit moves; fixture_x's moved fixture (objects on it go along)."""
        pins = dict(t0["placed"])
        if edits.get("pick_x"):  # drawn by RoboCasa in the shifted window, clear of the pinned items
            pins.pop(self._pick_cfg(), None)
        shift = meta.get(FIXTURE_KEY)
        if not shift:
            return pins, None
        name = shift["fixture"]
        if name not in t0["fixtures"]:
            raise ValueError(
                f"fixture {name} is placed by the kitchen layout, not sampled: fixture_x cannot move it here"
            )
        pos, quat = t0["fixtures"][name]
        d = tuple(
            float(v)
            for v in fixture_shift(quat, float(meta["init_robot_base_ori"][2]), float(shift["offset"][0]))
        )
        for c in meta["object_cfgs"]:
            if c.get("placement", {}).get("fixture") == name and c["name"] in pins:
                pins[c["name"]] = (tuple(np.add(pins[c["name"]][0], d)), pins[c["name"]][1])
        return pins, (name, d)

    def _pick_cfg(self) -> str:
        return (self.cfg.get("pick") or {}).get("cfg", "obj")  # CheesyBread's is "cheese"

    def _pick_offset(self, t0: dict, seed: int) -> float:
        """pick_x: the level's offset in this kitchen (``pick_window.level_offset``; ``LevelUnavailable`` when the
        kitchen's range cannot hold the levels)."""
        if t0["pick_range"] is None:
            raise ValueError(
                f"pick_x: RoboCasa's {self.cfg['task']} placed no object config {self._pick_cfg()!r}"
            )
        lo, hi = t0["pick_range"]
        meta = t0["meta"]
        where = f"{self.cfg['task']} seed {seed} (layout {meta['layout_id']}, style {meta['style_id']})"
        nominal = self.cfg["edits"].get("pick_x", 0.0)
        return window.level_offset(hi - lo, self.cfg["pick"], nominal, where, t0["pick_buffer"])

    def reset(self, seed: int) -> dict:
        edits = {k: v for k, v in self.cfg.get("edits", {}).items() if v and k != "pick_x"}
        t0, raw = self._t0(seed)
        pick = self.cfg.get("pick")
        dx = self._pick_offset(t0, seed) if pick else 0.0
        if dx:
            edits["pick_x"] = dx
        if raw is None or edits:
            fixture_refs = t0["meta"].get("fixture_refs", {})
            meta = edit_ep_meta(t0["meta"], edits, fixture=t0["fixture"], cab=fixture_refs.get("cab"),
                                pick=self._pick_cfg())  # fmt: skip
            pins, shift = self._pins(t0, meta, edits)
            self.env._indgen_task_fixture, self.env._indgen_pick_t0 = t0["fixture"], t0["pick_range"]
            try:
                raw = self._reset(seed, meta, pins, t0["made"], shift)
            finally:
                self.env._indgen_task_fixture = self.env._indgen_pick_t0 = None
            self._check_moves(seed, edits, shift)
        self.meta = self.env.get_ep_meta()
        out = {**self._obs(raw), "facts": failure_facts(self.env)}
        if pick:
            self._check_window(t0, dx)
            self.meta[window.PICK_KEY] = window.record(t0["pick_range"], pick, dx, t0["pick_buffer"])
            if pick.get("report"):
                out["axis_param"] = dx  # the episode's own offset (m): episodes.parquet's param
        return out

    def _check_moves(self, seed: int, edits: dict, shift) -> None:
        """The placement check after the settle (``placement_check``): a fixture_x appliance clear of its neighbours
        and on its counter, a base_y base clear of what stands behind it; ``PlacementInfeasible`` otherwise."""
        meta = self.env.get_ep_meta()
        where = (
            f"{self.cfg['task']} seed {seed} (layout {meta.get('layout_id')}, style {meta.get('style_id')})"
        )
        if shift:
            name, d = shift
            placement.check_fixture_move(self.env, [name, *auxiliaries(self.env, name)], np.asarray(d), where)
        if edits.get("base_back"):
            placement.check_base_move(self.env, where)

    def _check_window(self, t0: dict, dx: float) -> None:
        """The level drew the object in T0's window moved by ``dx``: RoboCasa computed the same range, moved."""
        lo, got = t0["pick_range"][0], self.env._indgen_pick_range[0]
        if abs(got - lo - dx) > 1e-6:
            raise RuntimeError(
                f"pick_x: RoboCasa's range of the pick object moved {got - lo:.4f} m at this level, not the "
                f"{dx:.4f} m edited (the kitchen was drawn again?)"
            )

    def step(self, action) -> dict:
        raw, _, _, _ = self.env.step(_flat_action(self.env, action))
        obs = self._obs(raw)
        obs["success"] = bool(self.env._check_success())
        obs["facts"] = failure_facts(self.env, action)
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
        """What oracles, the success check and tests read (plain numbers; ``RoboCasaEnvironment.privileged_from`` makes the
        ``PrivilegedState``): the grip site, the gripper, the mobile base, the pick object with its extents, the
        target fixture's interior, the moved fixture and the stand mixer's state, and RoboCasa's own success."""
        env = self.env
        data = env.sim.data
        robot = env.robots[0]
        site = robot.eef_site_id["right"]
        bq = np.array(data.get_body_xquat("mobilebase0_base"))
        out: dict = {
            "eef_pos": np.array(data.site_xpos[site]),
            "eef_mat": np.array(data.site_xmat[site]).reshape(3, 3),
            "gripper_qpos": np.array([data.qpos[a] for a in robot._ref_gripper_joint_pos_indexes["right"]]),
            "base_pos": np.array(data.get_body_xpos("mobilebase0_base"), dtype=np.float64),
            "base_yaw": float(_yaw(bq)),
        }
        name = _facts.pick_name(env)  # "obj", CheesyBread's "cheese"
        if name in getattr(env, "objects", {}):
            obj, bid = env.objects[name], env.obj_body_id[name]
            pos = np.array(data.body_xpos[bid])
            out.update(
                obj_pos=pos, obj_quat=np.array(data.body_xquat[bid]),
                obj_linvel=np.array(data.get_body_xvelp(obj.root_body)),
                obj_bottom=float(pos[2] + obj.bottom_offset[2]), obj_top=float(pos[2] + obj.top_offset[2]),
                obj_half_width=float(obj.horizontal_radius),
                obj_touching=bool(env.check_contact(robot.gripper["right"], obj)),
            )  # fmt: skip
        cab = getattr(env, "cab", None)
        if cab is not None and hasattr(
            cab, "get_int_sites"
        ):  # the interior the object goes into (obj_inside_of)
            p0, px, py, pz = next(iter(cab.get_int_sites(relative=False).values()))
            out.update(goal_pos=np.array(cab.pos, dtype=np.float64), goal_floor=float(p0[2]),
                       goal_centre=np.array((px + py) / 2.0), goal_top=float(pz[2]),
                       goal_half=(float(np.linalg.norm(px - p0)) / 2, float(np.linalg.norm(py - p0)) / 2))  # fmt: skip
        moved = MOVED_FIXTURE.get(self.cfg["task"])
        if moved and hasattr(env, moved):  # fixture_x's fixture: its root body's world position
            out["fixture_pos"] = np.array(data.get_body_xpos(getattr(env, moved).naming_prefix + "main"))
        mixer = getattr(env, "stand_mixer", None)
        if mixer is not None:
            out["stand_mixer"] = {k: float(v) for k, v in mixer.get_state(env).items() if np.isscalar(v)}
            out["mixer_head_pos"] = np.array(data.get_body_xpos(mixer.naming_prefix + "head"))
        out.update(oracle_facts(env, self.cfg["task"]))
        out["success"] = bool(env._check_success())
        return out

    def ep_meta(self) -> dict:
        return copy.deepcopy(self.meta)

    def close(self) -> None:
        self.env.close()


def fixture_shift(quat_wxyz, base_yaw: float, dx: float) -> np.ndarray:
    """fixture_x's world displacement: ``dx`` along the fixture's own axis that runs across T0's robot heading (its
    x, or its y where RoboCasa turned the appliance a quarter on its counter), that axis's positive way.

    Along the counter, as RoboCasa's placement offsets run (the counter's x): the axis lying along the heading would
    push a turned appliance into the wall behind it and out of the pinned base's reach (CloseStandMixerHead
    levels 2-3 on its own x: the head 0.58-0.70 m out from the arm's shoulder, the grip site stalled 0.45 m out).
    """
    yaw = _yaw(quat_wxyz)
    across = np.array([-np.sin(base_yaw), np.cos(base_yaw)])  # the base's left: across its heading
    own_x, own_y = np.array([np.cos(yaw), np.sin(yaw)]), np.array([-np.sin(yaw), np.cos(yaw)])
    axis = own_x if abs(own_x @ across) >= abs(own_y @ across) else own_y
    return np.array([*(axis * dx), 0.0])


def auxiliaries(env, name: str) -> list[str]:
    """The auxiliary fixtures RoboCasa placed with fixture ``name`` (``<name>_auxiliary_<group>``: the blender's
    lid, at its ``anchor_site``): fixture_x moves them with it (a lid left behind is off the blender, and
    ``Blender.update_state`` then keeps it off)."""
    return [n for n in getattr(env, "fxtr_placements", {}) if n.startswith(f"{name}_auxiliary_")]


def keep_task_fixture(env, task: str, name: str | None) -> None:
    """On a replay, the task's fixture (``env.stand_mixer``, ...) is T0's: the task picks it with ``get_fixture``,
    which ep_meta's ``fixture_refs`` do not pin, so in a kitchen with two stand mixers a level could pick the other
    one, 1.8 m from the robot base pinned at T0's pose (CloseStandMixerHead fixture_x level 1 episode 6)."""
    attr = MOVED_FIXTURE.get(task)
    if name and attr and name in getattr(env, "fixtures", {}):
        setattr(env, attr, env.fixtures[name])


def build(config: dict) -> RoboCasaLevel:
    os.environ.setdefault("MUJOCO_GL", "egl")
    if config.get("assets"):
        os.environ["ROBOCASA_ASSETS_PATH"] = config["assets"]
    check_kitchen(config)
    return RoboCasaLevel(config)
