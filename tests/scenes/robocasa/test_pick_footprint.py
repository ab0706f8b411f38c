"""pick_x's T0 is RoboCasa's own draw but for the 4 cm window: its buffer and footprint rule, its robot base.

Upstream: robocasa/robocasa be22d659, ``robocasa/utils/placement_samplers.py`` (``UniformRandomSampler._sample_x``:
``buffer = min(obj_size[0], obj_size[1]) / 2`` inside each end when ``ensure_object_boundary_in_range``; ``sample``:
``obj_in_region`` rejects a footprint outside ``x_range``), ``robocasa/utils/env_utils.py``
(``compute_robot_base_placement_pose``: an ``init_robot_here`` object's base offset is ``np.mean(sampler.x_range)``),
``robocasa/environments/kitchen/atomic/kitchen_pick_place.py`` (``CheesyBread``: the cheese has
``init_robot_here=True``).
"""

from __future__ import annotations

import json
import os
import subprocess
from types import SimpleNamespace

import numpy as np
import pytest

from scenes.robocasa.pick_window import PICK_JITTER, narrow
from tests.scenes.robocasa.test_robocasa import needs_venv

CHEESE = {"cfg": "cheese", "declared": 1.0, "level": 0, "top": 4, "step": None, "progressions": 5}


def _sampler(x_range, ensure=True, seed=7):
    sub = SimpleNamespace(x_range=np.array(x_range), ensure_object_boundary_in_range=ensure,
                          rng=np.random.default_rng(seed))  # fmt: skip
    cfg = [{"name": "cheese", "type": "object", "placement": {"size": (1.0, 0.3)}}]
    return SimpleNamespace(samplers={"cheese_Sampler": sub}), sub, cfg


def test_t0_keeps_robocasas_range_and_draws_in_the_window_inside_its_buffer():
    """At T0 the sampler's ``x_range`` stays RoboCasa's (the base of an ``init_robot_here`` object is placed from
    it); the centre is drawn with RoboCasa's one ``rng.uniform`` in [lo + buffer, lo + buffer + 4 cm], the buffer
    half the footprint's smaller side, as ``_sample_x`` computes it; no buffer without the footprint rule."""
    env = SimpleNamespace(_indgen_pick_t0=None)
    sampler, sub, cfg = _sampler([-1.0, -0.5])
    narrow(env, sampler, cfg, CHEESE)
    assert env._indgen_pick_range == (-1.0, -0.5) and list(sub.x_range) == [-1.0, -0.5]
    x = sub._sample_x((0.08, 0.05, 0.03))
    assert x == np.random.default_rng(7).uniform(high=-1.0 + 0.025 + 2 * PICK_JITTER, low=-1.0 + 0.025)
    assert env._indgen_pick_buffer == 0.025
    sampler, sub, cfg = _sampler([-1.0, -0.5], ensure=False)
    narrow(env, sampler, cfg, CHEESE)
    assert -1.0 <= sub._sample_x((0.08, 0.05, 0.03)) <= -0.96 and env._indgen_pick_buffer == 0.0


def test_a_levels_range_ends_where_t0s_does():
    """A level's replay moves the range's low end by the offset edit (RoboCasa recomputes it) and keeps T0's high
    end, so ``obj_in_region`` keeps the footprint inside T0's range at every level."""
    env = SimpleNamespace(_indgen_pick_t0=(-1.0, -0.5))
    sampler, sub, cfg = _sampler([-0.6, -0.1])  # T0's range moved 0.4 m by the level's offset
    narrow(env, sampler, cfg, CHEESE)
    assert env._indgen_pick_range == (-0.6, -0.1) and list(sub.x_range) == [-0.6, -0.5]
    assert -0.575 <= sub._sample_x((0.08, 0.05, 0.03)) <= -0.535


def test_a_narrow_kitchens_window_is_a_fifth_of_t0s_centre_range_at_every_level():
    """PickPlaceSinkToCounter's 0.25 m range and a 6 cm object: 0.19 m for the centre, a level 0.038 m, and so the
    window (not 4 cm): T0 draws in [lo + 0.03, lo + 0.068], level 1's replay (range moved 0.038 m, T0's high end
    kept) in the next 0.038 m, from T0's range rather than the replay's."""
    sink = {**CHEESE, "cfg": "obj", "declared": 0.25}
    env = SimpleNamespace(_indgen_pick_t0=None)
    sampler, sub, cfg = _sampler([0.0, 0.25])
    cfg[0].update(name="obj", placement={"size": (0.25, 0.3)})
    sampler.samplers = {"obj_Sampler": sub}
    narrow(env, sampler, cfg, sink)
    assert sub._sample_x((0.06, 0.06, 0.03)) == np.random.default_rng(7).uniform(high=0.03 + 0.038, low=0.03)
    env, (sampler, sub, _) = SimpleNamespace(_indgen_pick_t0=(0.0, 0.25)), _sampler([0.038, 0.288])
    sampler.samplers = {"obj_Sampler": sub}
    narrow(env, sampler, cfg, sink)
    assert list(sub.x_range) == [0.038, 0.25]
    x = sub._sample_x((0.06, 0.06, 0.03))
    assert x == np.random.default_rng(7).uniform(high=0.068 + 0.038, low=0.068) and x >= 0.068


@needs_venv
def test_the_buffer_and_the_base_offset_are_robocasas_own():
    """The installed RoboCasa computes the buffer and the base offset as ``pick_window`` relies on."""
    from scenes.robocasa.environment import venv_dir

    site = next(venv_dir().glob("lib/python*/site-packages/robocasa"))
    samplers = (site / "utils/placement_samplers.py").read_text()
    body = samplers.split("def _sample_x(self, obj_size=None):")[1].split("def _sample_y")[0]
    assert "buffer = min(obj_size[0], obj_size[1]) / 2" in body and "minimum += buffer" in body
    assert "if self.ensure_object_boundary_in_range and not obj_in_region(" in samplers
    env_utils = (site / "utils/env_utils.py").read_text()
    assert "fixture_to_robot_offset[0] += np.mean(sampler.x_range)" in env_utils
    pick_place = (site / "environments/kitchen/atomic/kitchen_pick_place.py").read_text()
    cheesy = pick_place.split("class CheesyBread(")[1].split("\nclass ")[0]
    assert 'name="cheese"' in cheesy and "init_robot_here=True" in cheesy


_BASES = """
import importlib.util, json, sys
spec = importlib.util.spec_from_file_location("backend", sys.argv[1])
backend = importlib.util.module_from_spec(spec)
spec.loader.exec_module(backend)
seed, out = int(sys.argv[3]), {}
for level in (None, 0, 2):  # None: RoboCasa's own CheesyBread, no pick window, under the same seed streams
    pick = None if level is None else dict(json.loads(sys.argv[4]), level=level)
    cfg = {"task": "CheesyBread", "layout_ids": None, "style_ids": None, "cameras": [], "image_size": (64, 64),
           "edits": {"pick_x": 0.2 * (level or 0)}, "assets": sys.argv[2], "pick": pick}
    built = backend.build(cfg)
    built.reset(seed)
    meta = built.ep_meta()
    out[str(level)] = {"base": meta["init_robot_base_pos"], "ori": meta["init_robot_base_ori"],
                       "window": meta.get("indgen_pick_window")}
    built.close()
print(json.dumps(out))
"""


@needs_venv
@pytest.mark.slow  # ~15 s of CPU: three CheesyBread kitchens built; the tests above cover the rule by default
def test_cheesy_breads_base_is_robocasas_own_at_every_level(placeholders):
    """CheesyBread seed 3: the base our worker places at pick_x levels 0 and 2 is the base RoboCasa's own
    CheesyBread (no pick window) places for the seed, from the mean of the cheese's un-narrowed x range. When the
    window narrowed that range the base stood 0.070 m off RoboCasa's here (seed 6: 0.274 m)."""
    from scenes.robocasa import backend
    from scenes.robocasa.environment import find_python

    out = subprocess.run(
        [str(find_python()), "-c", _BASES, backend.__file__, str(placeholders), "3", json.dumps(CHEESE)],
        capture_output=True, text=True, timeout=600, cwd="/",
        env={"PATH": os.environ["PATH"], "MUJOCO_GL": "egl", "PYTHONNOUSERSITE": "1"},
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    got = json.loads(out.stdout.strip().splitlines()[-1])
    own, l0, l2 = got["None"], got["0"], got["2"]
    assert own["window"] is None and l0["window"]["offset"] == 0.0 and l2["window"]["offset"] > 0.1
    for level in (l0, l2):
        assert level["base"] == own["base"] and level["ori"] == own["ori"]  # bit for bit
    lo, hi = l0["window"]["range"]
    assert l0["window"]["window"][0] == pytest.approx(lo + l0["window"]["buffer"]) and hi - lo <= 1.0 + 1e-9


def test_the_fingerprint_names_the_window_rule_and_the_manifest_its_one_deviation(placeholders):
    """A pick_x run under window rule 1 (no footprint rule, the sampler's range narrowed, CheesyBread's base moved)
    has another ``initial_states`` in its fingerprint, so it is neither pooled with nor resumed as one under rule 2;
    the deviations name the window and nothing of CheesyBread's base."""
    from scenes.family import get_scene
    from scenes.robocasa.departures import DEVIATIONS, PICK_T0

    facts = get_scene("robocasa").environment.protocol_facts()
    assert facts["initial_states"].endswith(PICK_T0) and "window rule 2" in PICK_T0
    assert facts["deviations"] == list(DEVIATIONS)
    pick = [d for d in DEVIATIONS if "pick_x" in d or "CheesyBread" in d]
    assert len(pick) == 1 and "4 cm window" in pick[0] and "robot base" in pick[0]


_SINK_LEVELS = """
import importlib.util, json, sys
spec = importlib.util.spec_from_file_location("backend", sys.argv[1])
backend = importlib.util.module_from_spec(spec)
spec.loader.exec_module(backend)
seed, out = int(sys.argv[3]), {}
for level in range(5):  # one process: T0 drawn once (the worker's cache), each level replayed from it
    pick = {"cfg": "obj", "declared": 0.25, "level": level, "top": 4, "step": None, "progressions": 5,
            "report": True}
    cfg = {"task": "PickPlaceSinkToCounter", "layout_ids": None, "style_ids": None, "cameras": [],
           "image_size": (64, 64), "edits": {"pick_x": 0.05 * level}, "assets": sys.argv[2], "pick": pick}
    built = backend.build(cfg)
    obs = built.reset(seed)
    out[level] = {"window": built.ep_meta()["indgen_pick_window"], "param": obs.get("axis_param"),
                  "x": built.privileged()["obj_pos"].tolist()}
    built.close()
print(json.dumps(out))
"""


@needs_venv
@pytest.mark.slow  # ~25 s CPU, 60 s wall: five levels; test_a_narrow_kitchens_window_... keeps the rule by default
def test_pick_place_sink_to_counter_runs_every_pick_x_level_on_the_placeholder_tree(placeholders):
    """Under the 4 cm window every PickPlaceSinkToCounter episode on the placeholder tree was unavailable (its 0.25 m
    region less a 2.7-3.6 cm buffer at each end: a fifth under 4 cm). Now seed 0 resets at levels 0..4, each window
    a fifth of the centre range wide, the five tiling it from lo + buffer to hi - buffer, each level's offset its
    param, and the object one step further along at each level."""
    from scenes.robocasa import backend
    from scenes.robocasa.environment import find_python

    out = subprocess.run(
        [str(find_python()), "-c", _SINK_LEVELS, backend.__file__, str(placeholders), "0"],
        capture_output=True, text=True, timeout=600, cwd="/",
        env={"PATH": os.environ["PATH"], "MUJOCO_GL": "egl", "PYTHONNOUSERSITE": "1"},
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    got = {int(k): v for k, v in json.loads(out.stdout.strip().splitlines()[-1]).items()}
    (lo, hi), b = got[0]["window"]["range"], got[0]["window"]["buffer"]
    step = (hi - lo - 2 * b) / 5
    assert hi - lo == pytest.approx(0.25) and 0.02 < b and step < 2 * PICK_JITTER
    for k, level in got.items():
        w = level["window"]
        assert w["range"] == [lo, hi] and w["offset"] == level["param"] == pytest.approx(k * step)
        assert w["window"] == pytest.approx([lo + b + k * step, lo + b + (k + 1) * step])
    assert got[4]["window"]["window"][1] == pytest.approx(hi - b)
    x = [level["x"] for level in got.values()]  # RoboCasa's same draw in each window: one step apart
    assert [np.linalg.norm(np.subtract(x[k + 1], x[k])[:2]) for k in range(4)] == pytest.approx(
        [step] * 4, abs=1e-3
    )
