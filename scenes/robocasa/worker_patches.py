"""The RoboCasa worker's patches of RoboCasa (``install_patches``): counter tops deduplicated in first-seen order,
objects in a drawer moved out with it on a replay too, placement samplers that honour a level's pinned placements and pick_x's window, the exact objects T0 drew, and
RoboCasa's style YAML parsed once. Runs in RoboCasa's venv, loaded by ``backend.py`` by path; imports only the
standard library and numpy at module level (RoboCasa inside the functions)."""

from __future__ import annotations

import copy
import os
import zlib

import numpy as np


def _pinned_sample(pins: dict):
    """SequentialCompositeSampler.sample (robocasa/utils/placement_samplers.py) that places each pinned item at
    T0's pose instead of drawing it, so every draw left is for what the level edited."""
    from copy import copy as shallow

    def sample(self, placed_objects=None, reference=None, on_top=True):
        placed = {} if placed_objects is None else shallow(placed_objects)
        for sampler, s_args in zip(self.samplers.values(), self.sample_args.values(), strict=True):
            objs = list(sampler.mujoco_objects)
            if objs and all(o.name in pins for o in objs):
                placed.update(
                    {o.name: (np.array(pins[o.name][0]), np.array(pins[o.name][1]), o) for o in objs}
                )
                continue
            s_args = dict(s_args or {})
            s_args.setdefault("reference", reference)
            s_args.setdefault("on_top", on_top)
            placed.update(sampler.sample(placed_objects=placed, **s_args))
        names = {o.name for s in self.samplers.values() for o in s.mujoco_objects}
        return {k: v for k, v in placed.items() if k in names}

    return sample


def unique_in_order(items=()) -> list:
    """``list(set(items))`` in first-seen order: a set of XML elements iterates in id() (memory address) order."""
    return list(dict.fromkeys(items))


def _dedupe_counter_geoms_in_order() -> None:
    """RoboCasa's ``Counter.get_reset_regions`` (robocasa/models/fixtures/counter.py) dedupes the counter tops beside
    a reference fixture with ``list(set(valid_geoms))``, its module's only ``set``: the regions' order, so the one
    ``rng.choice`` takes, followed memory addresses, and one seed put the stand mixer (and the robot base placed at
    it) on either side of the island sink, 1.775 m apart, depending on the process. Shadow that ``set``."""
    import robocasa.models.fixtures.counter as counter

    counter.set = unique_in_order


def _slide_replayed_objects() -> None:
    """RoboCasa's ``Kitchen._update_sliding_fxtr_obj_placement`` (robocasa/environments/kitchen/kitchen.py) moves an
    object placed in a drawer (a fridge's too) out with the drawer ``_setup_scene`` opened, but finds that drawer
    with ``fixture_is_type`` on the config's placement fixture: on a reset from ep_meta that is the fixture's name,
    so a replayed level left the object where the closed drawer held it (PickPlaceFridgeDrawerToShelf's base_y
    levels: behind the opened drawer, on the freezer's top). The names stand for the env's fixtures during it."""
    from robocasa.environments.kitchen.kitchen import Kitchen

    original = Kitchen._update_sliding_fxtr_obj_placement

    def update(self):
        placements = [c.get("placement", {}) for c in self.object_cfgs]
        named = [p for p in placements if isinstance(p.get("fixture"), str) and p["fixture"] in self.fixtures]
        for placement in named:
            placement["fixture"] = self.fixtures[placement["fixture"]]
        try:
            original(self)
        finally:
            for placement in named:
                placement["fixture"] = placement["fixture"].name

    Kitchen._update_sliding_fxtr_obj_placement = update


def install_patches(window) -> None:
    """Worker-wide: counter regions in first-seen order; placement samplers honour ``env._indgen_pins`` and
    pick_x's window (``env._indgen_pick``: ``window.narrow``, ``window`` the worker's ``pick_window``); RoboCasa's
    fixture style YAML (re-parsed ~100 times per reset with the pure-Python loader, ~70 % of a reset) is parsed once
    with libyaml and copied."""
    import types

    import robocasa.models.scenes.scene_utils as scene_utils
    import robocasa.utils.env_utils as env_utils
    import yaml

    if getattr(env_utils, "_indgen_patched", False):
        return
    _dedupe_counter_geoms_in_order()
    _slide_replayed_objects()
    original = env_utils._get_placement_initializer

    def placement_initializer(env, cfg_list, z_offset=0.01):
        sampler = original(env, cfg_list, z_offset)
        seed = getattr(env, "_indgen_seed", None)
        if seed is not None and all(c.get("type") == "object" for c in cfg_list):
            # each object draws from its own stream of (seed, name): a level that pins or adds other objects
            # draws the same numbers for the one it moves, so pick_x's levels are shifts of T0's pose
            for name, sub in sampler.samplers.items():
                sub.rng = np.random.default_rng([seed, 2, zlib.crc32(name.encode())])
        pick = getattr(env, "_indgen_pick", None)
        if pick and all(c.get("type") == "object" for c in cfg_list):
            window.narrow(env, sampler, cfg_list, pick)
        pins = getattr(env, "_indgen_pins", None)
        if pins:
            sampler.sample = types.MethodType(_pinned_sample(pins), sampler)
        return sampler

    env_utils._get_placement_initializer = placement_initializer
    create = env_utils.create_obj

    def create_obj(env, cfg):
        """T0's exact object (model and scale): a replay by ``info.mjcf_path`` looks the category up again and can
        pick another category's scale for a model folder two categories share."""
        made = getattr(env, "_indgen_made", None)
        if made and cfg["name"] in made:
            kwargs, info = copy.deepcopy(made[cfg["name"]])
            return env_utils.MJCFObject(name=cfg["name"], **kwargs), info
        drawn: list = []
        sample = env.sample_object
        env.sample_object = lambda *a, **k: drawn.append(sample(*a, **k)) or drawn[-1]
        try:
            obj, info = create(env, cfg)
        finally:
            del env.sample_object
        env._indgen_drawn[cfg["name"]] = copy.deepcopy(drawn[-1])
        return obj, info

    env_utils.create_obj = create_obj
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    cache: dict = {}

    class CachedYaml(types.ModuleType):
        def __getattr__(self, name):
            return getattr(yaml, name)

        @staticmethod
        def safe_load(stream):
            name = getattr(stream, "name", None)
            if not isinstance(name, str) or not os.path.isfile(name):
                return yaml.load(stream, Loader=loader)
            key = (name, os.stat(name).st_mtime_ns)
            if key not in cache:
                cache[key] = yaml.load(stream, Loader=loader)
            return copy.deepcopy(cache[key])

    scene_utils.yaml = CachedYaml("yaml")
    env_utils._indgen_patched = True
