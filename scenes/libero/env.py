"""``LiberoSceneEnv``: one level of one LIBERO task, built from hf-libero's env classes, behind SceneEnv's interface.

Level 0 builds LIBERO's own ``OffScreenRenderEnv`` (``ControlEnv`` when no camera is rendered) from the task's
BDDL file with lerobot's settings (Panda, OSC_POSE, 20 Hz, hard resets, agentview + eye-in-hand cameras in
robosuite's raw orientation), restores fixed initial state ``episode % 50`` and settles 10 no-op steps. Other
levels build the same problem class from an edited BDDL (moved init regions, distractor fixtures) with the
pick object's XML scaled, and start from the same initial state with the moved object translated alike.
"""

from __future__ import annotations

import contextlib
import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np

import scenes.libero.placement_check as placement
import scenes.mujoco_geom as geom
from indgen_vla.core.errors import SceneError
from indgen_vla.core.protocol.interface import Observation
from indgen_vla.core.protocol.progression import check_strictly_harder
from scenes.axes import Successor, axis_param, shifts, spec_at_level
from scenes.base_env import BaseSceneEnv
from scenes.libero.assets import HOPE_OBJECTS, config_dir, find_assets, import_libero
from scenes.libero.bddl import LiberoTask, add_fixtures, shift_region
from scenes.libero.grasp_clearance import OPEN_HALF, RIM_DOWN, grasp_offset, rim_offset, wall_middles
from scenes.libero.problem import level_problem, problem_class
from scenes.privileged import GoalState, PickState, PrivilegedState, Targets
from scenes.sim import CAMERA_NAMES, fast_step

NUM_STEPS_WAIT = 10  # lerobot's LiberoEnv settles the scene with this many no-op steps after each reset
DUMMY_ACTION = [0, 0, 0, 0, 0, 0, -1]  # lerobot's get_libero_dummy_action
DISTRACTOR_PREFIX = "indgen_distractor_"
BUILD_TRIES = 20  # seeded tries of LIBERO's build-time placement (a moved region can make one fail)


@dataclass(frozen=True)
class Support:
    """Where T0 puts the moved objects: min/max of their x, y over LIBERO's fixed initial states."""

    pick_y: tuple[float, float]
    goal_y: tuple[float, float]


class Suite(Protocol):
    """What the env reads from the ``scenes.libero.LiberoSuite`` that builds it (that module imports this one)."""

    name: str
    max_steps: int
    success_predicate: object
    distractor_slots: tuple[tuple[float, float], ...]

    def task_info(self, task: str) -> LiberoTask: ...

    def base(self, task: str): ...


class LiberoSceneEnv(BaseSceneEnv):
    """One level of one LIBERO task; ``reset(seed=, options={"episode": i})`` starts from fixed init state i."""

    fast_physics = True  # scenes.sim.fast_step: stock robosuite states bit for bit (False: LIBERO's own step)

    def _load(self, scene: Suite, task: str, successor: Successor) -> None:
        self.info = scene.task_info(task)
        self.instruction = self.info.language
        self.base = scene.base(task)
        self.spec = spec_at_level(self.base, successor, self.level)
        self.axis_param = axis_param(self.spec, successor, self.level)
        self.success_predicate = scene.success_predicate  # LIBERO's own BDDL goal at every level
        self._slots = scene.distractor_slots
        self._successor = successor
        self.assets = find_assets()
        import_libero(self.assets)
        self.bddl_file = self._level_bddl()
        self._sim_env = self._build()
        self.init_index: int | None = None
        self._setup_indices()
        self.support = self._support()
        self._check_progression()

    # ---- building ------------------------------------------------------------------------------
    @property
    def shift(self) -> tuple[float, float]:
        """(pick dy, basket dy) of this level relative to LIBERO's own layout."""
        return (round(self.spec.pick.y - self.base.pick.y, 9), round(self.spec.goal.y - self.base.goal.y, 9))

    @property
    def distractors(self) -> tuple[tuple[str, str, tuple[float, float]], ...]:
        present = {c for _, c in self.info.objects}

        pool = [c for c in HOPE_OBJECTS if c not in present]
        if self.spec.distractors > len(pool):
            raise SceneError(f"{self.scene}/{self.task}: only {len(pool)} distractor objects are available")
        return tuple(
            (f"{DISTRACTOR_PREFIX}{i + 1}", pool[i], self._slots[i]) for i in range(self.spec.distractors)
        )

    def _level_bddl(self) -> Path:
        """LIBERO's BDDL file at level 0; otherwise an edited copy (cached by content)."""
        dpick, dgoal = self.shift
        if not (dpick or dgoal or self.spec.distractors):
            return self.info.bddl_path
        text = self.info.bddl_path.read_text()
        if dpick and not self.info.pick_on_table:
            raise SceneError(f"{self.scene}/{self.task}: pick_y needs a pick object placed on a table region")
        if dpick:
            text = shift_region(text, self.info.pick_region, 0.0, dpick)
        if dgoal:
            text = shift_region(text, self.info.goal_region, 0.0, dgoal)
        text = add_fixtures(text, [(i, c) for i, c, _ in self.distractors])
        digest = hashlib.sha1(text.encode()).hexdigest()[:12]
        path = config_dir() / "bddl" / self.info.suite / f"{self.info.file}__{digest}.bddl"
        if not path.is_file():
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_suffix(".tmp")
            tmp.write_text(text)
            tmp.replace(path)
        return path

    def _build(self):
        from libero.libero.envs import OffScreenRenderEnv
        from libero.libero.envs.bddl_base_domain import TASK_MAPPING
        from libero.libero.envs.bddl_utils import get_problem_info
        from libero.libero.envs.env_wrapper import ControlEnv

        h, w = self.image_size
        kwargs = dict(
            bddl_file_name=str(self.bddl_file),
            camera_heights=h,
            camera_widths=w,
            control_freq=20,
            hard_reset=True,
        )
        if self.cameras:
            kwargs["camera_names"] = [CAMERA_NAMES[c] for c in self.cameras]
            cls = OffScreenRenderEnv
        else:
            kwargs.update(
                use_camera_obs=False,
                has_offscreen_renderer=False,
                camera_names=[],
                camera_heights=[],
                camera_widths=[],
            )
            cls = ControlEnv
        from robosuite.utils.errors import RandomizationError

        problem = get_problem_info(str(self.bddl_file))["problem_name"]

        def construct():
            if self.spec.pick.scale == 1.0 and not self.spec.distractors:
                return cls(**kwargs)
            sub = level_problem(TASK_MAPPING[problem], self.info.pick, self.spec.pick.scale, self.distractors)
            with problem_class(problem, sub):
                return cls(**kwargs)

        try:
            # the build's own placement (LIBERO's sampler, numpy's global generator) is overwritten by the fixed
            # initial state at every reset; a moved region can make it fail at random: retry it, seeded
            for attempt in range(BUILD_TRIES):
                np.random.seed(attempt)
                try:
                    return construct()
                except RandomizationError:
                    continue
            raise SceneError(
                f"{self.scene}/{self.task} level {self.level}: LIBERO could not place the objects in the moved "
                f"regions ({BUILD_TRIES} tries); use a smaller level"
            )
        except SceneError:
            raise
        except Exception as e:  # robosuite/LIBERO raise bare assertions, mujoco errors, missing files
            msg = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
            raise SceneError(
                f"LIBERO scene {self.scene}/{self.task} level {self.level} failed to build: {msg}"
            ) from e

    def _setup_indices(self) -> None:
        import torch

        sim = self._env.sim
        self._states = np.asarray(torch.load(str(self.info.init_path), weights_only=False))
        n = 1 + sim.model.nq + sim.model.nv
        if self._states.ndim != 2 or self._states.shape[1] != n:
            raise SceneError(
                f"LIBERO init states {self.info.init_path} have shape {self._states.shape}, the model "
                f"needs (N, {n}); the asset tree at {self.assets} does not match this task"
            )
        objs = self._env.env.objects_dict
        self._qpos = {
            k: sim.model.get_joint_qpos_addr(objs[k].joints[-1])[0] for k in (self.info.pick, self.info.goal)
        }
        m = sim.model._model

        def geoms(inst: str, table: dict = objs) -> np.ndarray:
            return geom.body_geoms(m, sim.model.body_name2id(table[inst].root_body))

        self._pick_body = sim.model.body_name2id(objs[self.info.pick].root_body)
        self._goal_body = sim.model.body_name2id(objs[self.info.goal].root_body)
        self._pick_geoms, self._goal_geoms = geoms(self.info.pick), geoms(self.info.goal)
        # everything the carried object must clear on its way: other objects and the fixtures (cabinet, stove)
        fixtures = self._env.env.fixtures_dict
        self._other_geoms = [geoms(i) for i in objs if i not in (self.info.pick, self.info.goal)]
        self._other_geoms += [geoms(i, fixtures) for i in fixtures]
        # what the open gripper may land on when it comes down to grasp: every other object, the basket too
        self._neighbour_geoms = [geoms(i) for i in objs if i != self.info.pick]
        # the placement check's view of the two objects a level moves (or scales), each against every other object
        self._placed = [placement.body(k, objs, lambda i: sim.model.body_name2id(objs[i].root_body), geoms)
                        for k in (self.info.pick, self.info.goal)]  # fmt: skip
        hand = sim.model.body_name2id(self._env.robots[0].gripper.root_body)

        def under_hand(b: int) -> bool:
            while b > 0 and b != hand:
                b = int(m.body_parentid[b])
            return b == hand

        self._gripper_geoms = [
            g
            for g in range(m.ngeom)
            if under_hand(int(m.geom_bodyid[g])) and (m.geom_contype[g] or m.geom_conaffinity[g])
        ]
        self._finger_mask = geom.geom_mask(m, geom.named_geoms(m, self._env.robots[0].gripper.contact_geoms))
        self._pick_mask = geom.geom_mask(m, self._pick_geoms)
        site = f"{self.info.goal}_contain_region"
        self._contain_site = sim.model.site_name2id(site) if site in sim.model.site_names else None

    def _support(self) -> Support:
        p, g = 1 + self._qpos[self.info.pick] + 1, 1 + self._qpos[self.info.goal] + 1
        dp, dg = self.shift
        return Support(
            (float(self._states[:, p].min() + dp), float(self._states[:, p].max() + dp)),
            (float(self._states[:, g].min() + dg), float(self._states[:, g].max() + dg)),
        )

    def _check_progression(self) -> None:
        """Condition 2 against T0's actual support (LIBERO's fixed states), for pick_y and goal_y components."""
        for part in shifts(self._successor):  # a held axis's held pick_y/goal_y too
            name = part.axis.name
            if name not in ("pick_y", "goal_y"):
                continue
            lo, hi = self._states_support(self.info.pick if name == "pick_y" else self.info.goal)
            step = part.axis.step
            supports = {k: (lo + k * step, hi + k * step) for k in part.axis.default_levels()}
            check_strictly_harder(supports, name)

    def _states_support(self, inst: str) -> tuple[float, float]:
        col = self._states[:, 1 + self._qpos[inst] + 1]
        return (float(col.min()), float(col.max()))

    # ---- gymnasium API -------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[Observation, dict]:
        super().reset(seed=seed)
        if seed is None:
            seed = int(self.np_random.integers(0, 2**31 - 1))
        episode = (options or {}).get("episode")
        self.episode_seed = int(seed)
        self.init_index = int(episode if episode is not None else seed) % len(self._states)
        self._renderers.clear()  # hard resets rebuild the MuJoCo model
        self._render_here()  # the hard reset frees the old render context's GL objects in the current GL context
        self._reset_sim(self.episode_seed)
        self._render_here()
        state = self._level_state(self.init_index)
        raw = self._env.set_init_state(state)
        if self.spec.pick.scale != 1.0:
            raw = self._env.set_init_state(self._rest_scaled_pick(self._level_state(self.init_index)))
        data = self._env.sim.data._data
        # the placement check, where the level moved or scaled an object (level 0 is LIBERO's own layout: unchecked)
        checked = any(self.shift) or self.spec.pick.scale != 1.0
        overlaps = [placement.overlap(data, b) for b in self._placed] if checked else []
        for i in range(NUM_STEPS_WAIT):
            # only the last settle step's frames are read: the earlier ones stay held, and a lazy step that ended
            # the previous episode (``step(observe=False)``) must not leave the reset's frames held (stale)
            self._observing = i == NUM_STEPS_WAIT - 1
            raw = self._sim_step(DUMMY_ACTION)
        if checked:
            where = f"{self.scene}/{self.task} level {self.level}, LIBERO initial state {self.init_index}"
            placement.check(self._placed, self._qpos, data, state, overlaps, where)
        for robot in self._env.robots:
            robot.controller.use_delta = True
        self._raw, self._t, self._done = raw, 0, False
        self._grasp_plan: tuple[np.ndarray, float | None] | None = None  # (offset, rim z), at the first state
        return self._observation(), {
            "success": False,
            "step": 0,
            "seed": self.episode_seed,
            "init_state": self.init_index,
        }

    def close(self) -> None:
        self._render_here()  # robosuite frees the render context's GL objects in the current context
        super().close()

    def _reset_sim(self, seed: int, tries: int = 20) -> None:
        from robosuite.utils.errors import RandomizationError

        self._env.seed(seed)
        for _ in range(tries):
            try:
                self._env.env.reset()
                return
            except RandomizationError:
                continue
        raise SceneError(
            f"{self.scene}/{self.task} level {self.level}: LIBERO could not place the objects in "
            f"the moved regions ({tries} tries); use a smaller level"
        )

    def _level_state(self, i: int) -> np.ndarray:
        """LIBERO's fixed initial state ``i`` with the pick object and basket translated like their regions."""
        state = np.array(self._states[i], dtype=np.float64)
        dpick, dgoal = self.shift
        state[1 + self._qpos[self.info.pick] + 1] += dpick
        state[1 + self._qpos[self.info.goal] + 1] += dgoal
        return state

    def _rest_scaled_pick(self, state: np.ndarray) -> np.ndarray:
        """Raise/lower the scaled pick object so its lowest point is where the unscaled object's was."""
        s = self.spec.pick.scale
        z = float(self._env.sim.data.body_xpos[self._pick_body][2])
        d = self._lowest(self._pick_geoms) - z
        state[1 + self._qpos[self.info.pick] + 2] += -d * (1.0 - 1.0 / s)
        return state

    def _lowest(self, geoms: np.ndarray) -> float:
        return float(self._extent(geoms)[0][2])

    def _clear_grasp(
        self, pick_pos: np.ndarray, lo: np.ndarray, hi: np.ndarray
    ) -> tuple[np.ndarray, float | None]:
        """The episode's grasp offset from the object's centre (``scenes.libero.grasp_clearance``: a clear point, or
        an open-topped object's rim) and, for a rim grasp, its height, from the scene at the first privileged state
        (the object at rest, the gripper open above it); None: the height follows the object as v2's did."""
        if getattr(self, "_grasp_plan", None) is None:
            m, d = self._env.sim.model._model, self._env.sim.data._data
            eef = geom.grip_site(d, self._env.robots[0])[0]
            boxes = [geom.world_aabb(m, d, [g]) for g in self._gripper_geoms]
            grip_lo = np.array([b[0] for b in boxes]) - eef
            grip_hi = np.array([b[1] for b in boxes]) - eef
            obs = [self._extent(g) for g in self._neighbour_geoms if len(g)]
            obs_lo = np.array([b[0] for b in obs]).reshape(-1, 3)
            obs_hi = np.array([b[1] for b in obs]).reshape(-1, 3)
            half = (hi[:2] - lo[:2]) / 2
            c = (lo + hi) / 2
            rim_z = float(hi[2]) - RIM_DOWN
            walls = wall_middles(m, d, self._pick_body, c, float(hi[2]), rim_z) if half[1] > OPEN_HALF else []
            rim = rim_offset(grip_lo, grip_hi, obs_lo, obs_hi, np.array([c[0], c[1], rim_z]), walls)
            if rim is not None:  # from the body's origin, as the other offsets
                self._grasp_plan = (rim + c[:2] - pick_pos[:2], rim_z)
            else:
                z = geom.grasp_height(float(lo[2]), float(hi[2]), 0.5)
                centre = np.array([pick_pos[0], pick_pos[1], z])
                self._grasp_plan = (grasp_offset(grip_lo, grip_hi, obs_lo, obs_hi, centre, half), None)
        return self._grasp_plan

    def _corridor_top(self, start: np.ndarray, end: np.ndarray, margin: float) -> float:
        """Highest top of the other objects and fixtures whose footprint (+ margin) meets the segment start→end."""
        pts = start[None] + np.linspace(0.0, 1.0, 21)[:, None] * (np.asarray(end) - start)[None]
        top = -np.inf
        for g in self._other_geoms:
            if len(g):
                lo, hi = self._extent(g)
                if np.any(np.all((pts >= lo[:2] - margin) & (pts <= hi[:2] + margin), axis=1)):
                    top = max(top, float(hi[2]))
        return top

    def _extent(self, geoms: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World AABB (min, max corners) of ``geoms``."""
        return geom.world_aabb(self._env.sim.model._model, self._env.sim.data._data, geoms)

    # ---- the hf-libero backend --------------------------------------------------------------------
    @property
    def _env(self):
        """LIBERO's ``OffScreenRenderEnv``/``ControlEnv`` (None once closed)."""
        return self._sim_env

    def _sim_step(self, action) -> dict:
        """One LIBERO control step, its raw observation: ``scenes.sim.fast_step`` (bit for bit) or LIBERO's."""
        with self._cameras_held(not self._observing):
            if self._observing:
                self._render_here()
            if not self.fast_physics:
                return self._env.step(action)[0]

            # LIBERO's own step adds only a 4-d (OSC_POSITION) conversion
            return fast_step(self._env.env, action)[0]

    def _render_here(self) -> None:
        """Make this env's GL context current before robosuite renders its cameras or frees its render context
        (``MjRenderContext.render`` and ``__del__`` act on whatever context is current): another env in this process
        (a pipelined lane's) or a video frame's ``mujoco.Renderer`` may have made its own current since, and
        rendering there gives another scene's pixels, freeing there deletes that env's textures and buffers."""
        sim = getattr(self._env, "sim", None) if self._env is not None and self.cameras else None
        ctx = getattr(sim, "_render_context_offscreen", None)
        if ctx is not None:
            ctx.gl_ctx.make_current()

    @contextlib.contextmanager
    def _cameras_held(self, hold: bool):
        """While ``hold``, the camera observables re-emit their last image instead of rendering.

        robosuite samples each camera at a fixed substep of a control step on its own timer; the timers run on
        unchanged, so the frames a policy reads are rendered at the same substep from the same state as when
        every step renders: only frames nobody reads are skipped.
        """
        held = [self._env.env._observables[f"{CAMERA_NAMES[c]}_image"] for c in self.cameras] if hold else []
        sensors = [o._sensor for o in held]
        for o, sensor in zip(held, sensors, strict=True):
            o._sensor = _last_value(o, sensor.__modality__)
        try:
            yield
        finally:
            for o, sensor in zip(held, sensors, strict=True):
                o._sensor = sensor

    def _advance(self, action: np.ndarray) -> bool:
        self._raw = self._sim_step(action)
        return bool(self._env.check_success())

    def _failure_signals(self) -> tuple[bool, float]:
        return self._pick_touching(), self._lowest(self._pick_geoms)

    def _over_goal(self) -> bool:
        """The pick object's body position is inside the xy box of the goal's contain region, as LIBERO's own
        ``In`` test measures it (libero/envs/objects/site_object.py ``in_box``: |R·size| around the site; here
        without its z bound), or inside the goal object's xy AABB when the goal has no such region."""
        d = self._env.sim.data
        xy = np.asarray(d.body_xpos[self._pick_body][:2])
        if self._contain_site is not None:
            half = np.abs(
                d.site_xmat[self._contain_site].reshape(3, 3)
                @ self._env.sim.model.site_size[self._contain_site]
            )
            return bool(np.all(np.abs(xy - d.site_xpos[self._contain_site][:2]) < half[:2]))
        lo, hi = self._extent(self._goal_geoms)
        return bool(np.all(xy > lo[:2]) and np.all(xy < hi[:2]))

    # ---- observations and privileged state -------------------------------------------------------
    def _observation(self, with_images: bool = True) -> Observation:
        from robosuite.utils.transform_utils import quat2axisangle

        raw = self._raw
        cameras = self.cameras if with_images else ()
        images = {c: np.ascontiguousarray(raw[f"{CAMERA_NAMES[c]}_image"], dtype=np.uint8) for c in cameras}
        state = np.concatenate(
            [
                raw["robot0_eef_pos"],
                quat2axisangle(np.array(raw["robot0_eef_quat"])),
                raw["robot0_gripper_qpos"],
            ]
        ).astype(np.float32)
        return Observation(
            images=images,
            state=state,
            instruction=self.instruction,
            extras={"step": self._t, "init_state": self.init_index},
        )

    def _observation_without_images(self) -> Observation:
        return self._observation(with_images=False)

    def _pick_touching(self) -> bool:
        return geom.touching(self._env.sim.data._data, self._finger_mask, self._pick_mask)

    def privileged_state(self) -> PrivilegedState:
        """Poses, extents and contacts for the oracle (never shown to learned policies)."""
        sim = self._env.sim
        d = sim.data
        lo, hi = self._extent(self._pick_geoms)
        glo, ghi = self._extent(self._goal_geoms)
        pick_pos = np.array(d.body_xpos[self._pick_body])
        goal_pos = np.array(d.body_xpos[self._goal_body])
        qv = sim.model.get_joint_qvel_addr(self._env.env.objects_dict[self.info.pick].joints[-1])[0]
        if self._contain_site is not None:
            c = np.array(d.site_xpos[self._contain_site])
            floor = float(c[2] - sim.model.site_size[self._contain_site][2])
            place_xy = c[:2]
        else:
            floor, place_xy = float(ghi[2]), goal_pos[:2]
        bottom, top = float(lo[2]), float(hi[2])
        clear = max(
            float(ghi[2]), self._corridor_top(pick_pos[:2], place_xy, float(max(hi[:2] - lo[:2]) / 2) + 0.02)
        )
        eef_pos, eef_mat, gripper_qpos = geom.grip_site(d, self._env.robots[0])
        grasp_dxy, rim_z = self._clear_grasp(pick_pos, lo, hi)
        return PrivilegedState(
            eef_pos=eef_pos,
            eef_mat=eef_mat,
            gripper_qpos=gripper_qpos,
            pick=PickState(
                pos=pick_pos,
                quat_wxyz=np.array(d.body_xquat[self._pick_body]),
                linvel=np.array(d.qvel[qv : qv + 3]),
                bottom=bottom,
                top=top,
                half_width=float(max(hi[:2] - lo[:2]) / 2),
                touching_gripper=self._pick_touching(),
            ),
            goal=GoalState(
                pos=goal_pos, quat_wxyz=np.array(d.body_xquat[self._goal_body]), top=float(ghi[2])
            ),
            target=Targets(
                place_xy=np.array(place_xy),
                place_bottom=floor + 0.012,
                clear_z=clear,
                grasp_z=geom.grasp_height(bottom, top, 0.5) if rim_z is None else rim_z,
                floor_z=floor,
                grasp_xy=pick_pos[:2] + grasp_dxy,
            ),
            bddl_success=bool(self._env.check_success()),
        )


def _last_value(observable, modality: str):
    """A robosuite sensor that re-emits ``observable``'s last value (robosuite reads its ``__modality__``)."""

    def sensor(_cache):
        return observable._current_observed_value

    sensor.__modality__ = modality
    return sensor
