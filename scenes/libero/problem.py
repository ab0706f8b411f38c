"""LIBERO's problem classes for a level: the pick object's XML scaled, distractors loaded as visual-only fixtures."""

from __future__ import annotations

import contextlib


def scale_xml(obj, s: float) -> None:
    """Scale a robosuite ``MujocoXMLObject`` uniformly about its origin: geoms, sites, bodies and meshes."""

    def mul(el, attr: str) -> None:
        if el.get(attr) is not None:
            el.set(attr, " ".join(f"{float(v) * s:.6g}" for v in el.get(attr).split()))

    for root in (obj.get_obj(), obj.worldbody):
        for el in root.iter():
            if el.tag in ("geom", "site", "body") and el is not obj.get_obj():
                mul(el, "pos")
            if el.tag == "site" or (el.tag == "geom" and el.get("type") != "mesh"):
                mul(el, "size")
    for mesh in obj.asset.iter("mesh"):
        mesh.set("scale", mesh.get("scale", "1 1 1"))
        mul(mesh, "scale")


def level_problem(base_cls, pick: str, scale: float, distractors: tuple[tuple[str, str, tuple], ...]):
    """A subclass of LIBERO's problem class (same name, so its BDDL problem check passes) that scales the pick
    object's XML and loads ``distractors`` (instance, category, (x, y)) as visual-only, joint-less fixtures."""
    from libero.libero.envs.objects import get_object_fn
    from libero.libero.envs.regions import REGION_SAMPLERS
    from robosuite.models.objects import MujocoXMLObject

    names = {d[0] for d in distractors}

    class Level(base_cls):
        def _load_objects_in_arena(self, mujoco_arena):
            super()._load_objects_in_arena(mujoco_arena)
            if scale != 1.0:
                scale_xml(self.objects_dict[pick], scale)

        def _load_fixtures_in_arena(self, mujoco_arena):
            fixtures = self.parsed_problem["fixtures"]
            self.parsed_problem["fixtures"] = {
                c: [i for i in v if i not in names] for c, v in fixtures.items()
            }
            try:
                super()._load_fixtures_in_arena(mujoco_arena)
            finally:
                self.parsed_problem["fixtures"] = fixtures
            for inst, cat, (x, y) in distractors:
                proto = get_object_fn(cat)(name=inst)  # LIBERO's object: its XML file and resting rotation
                obj = MujocoXMLObject(
                    proto.file, name=inst, joints=None, obj_type="visual", duplicate_collision_geoms=False
                )
                # the problem's one workspace sampler: "floor" (LIBERO-Object) or "table" (LIBERO-Spatial)
                (workspace_sampler,) = REGION_SAMPLERS[self.parsed_problem["problem_name"]].values()
                sampler = workspace_sampler(
                    inst,
                    proto,
                    x_ranges=[[x, x]],
                    y_ranges=[[y, y]],
                    rotation=proto.rotation,
                    rotation_axis=proto.rotation_axis,
                    ensure_object_boundary_in_range=False,
                    ensure_valid_placement=False,
                    reference_pos=self.workspace_offset,
                )
                pos, quat, _ = sampler.sample()[inst]
                obj.get_obj().set("pos", " ".join(f"{v:.6f}" for v in pos))
                obj.get_obj().set("quat", " ".join(f"{v:.6f}" for v in quat))
                obj.category_name = cat
                obj.object_properties = {"vis_site_names": {}}
                self.fixtures_dict[inst] = obj

    Level.__name__ = Level.__qualname__ = base_cls.__name__
    return Level


@contextlib.contextmanager
def problem_class(problem_name: str, cls):
    """Let LIBERO's ``ControlEnv`` construct ``cls`` for ``problem_name`` (restored afterwards)."""
    from libero.libero.envs.bddl_base_domain import TASK_MAPPING

    old = TASK_MAPPING[problem_name]
    TASK_MAPPING[problem_name] = cls
    try:
        yield
    finally:
        TASK_MAPPING[problem_name] = old
