"""Where RoboCasa365 here departs from RoboCasa's own evaluation protocol (robocasa/robocasa be22d659, lerobot's
``lerobot/envs/robocasa.py``): recorded in every run's manifest (protocol facts ``deviations`` and the manifest's
``deviations``) and listed in docs/robocasa.md. Importing this is cheap."""

from __future__ import annotations

# RoboCasa's Kitchen defaults robot_spawn_deviation_pos_x=0.15, _pos_y=0.05 (robocasa/environments/kitchen/kitchen.py)
SPAWN_JITTER = {"pos_x": 0.0, "pos_y": 0.0, "robocasa_default": {"pos_x": 0.15, "pos_y": 0.05}}

# what T0 is on pick_x, in the protocol facts' initial_states (the fingerprint): rule 2 (the window inside RoboCasa's
# buffer, its footprint rule and robot base kept) replaced rule 1 (the window at the range's own end, no footprint
# rule, the sampler's range narrowed to it): the runs of the two are not pooled and one does not resume the other
PICK_T0 = (
    "pick_x (window rule 2): T0 draws the pick object's centre x in a 4 cm window at the low end of the range "
    "RoboCasa draws it in (its range less the object's buffer), RoboCasa's footprint rule and robot base kept; a "
    "level moves the window 1/5 of that range"
)

DEVIATIONS: tuple[str, ...] = (
    "robot spawn jitter 0 (RoboCasa's default: uniform +-0.15 m along and +-0.05 m across the anchor): T0's robot "
    "base is RoboCasa's anchor pose itself, so a base_y step (0.125 m) is not drowned in T0's own spread of the "
    "base and every level replays one base pose; the oracle's certificates were made so",
    "T0's kitchen, style and objects are RoboCasa's own draws from streams seeded per episode (layout/style from "
    "the seed, placements per object from (seed, name)), not the stream RoboCasa's gym reset(seed) would use: "
    "the same seed gives a RoboCasa task instance, not the one lerobot's env gives for that seed",
    "levels replay T0's ep_meta with one field moved, skipping RoboCasa's robot-placement collision retry; the "
    "placement check after the settle stands in for it (a fixture_x / base_y move into an obstacle or off its "
    "counter is an infeasible cell, recorded as EpisodeUnavailableError, never a policy failure)",
    "pick_x: T0 draws the pick object's centre x in a 4 cm window (one level's step where that is narrower) at the "
    "low end of the range RoboCasa draws it in (its range less the object's buffer at each end), not across that "
    "whole range; RoboCasa's buffer, "
    "footprint rule (rotations whose footprint leaves its range are redrawn, so fewer fit at the window's low "
    "end) and robot base (CheesyBread's, from the cheese's range) are its own",
    "RoboCasa365 split and object registries are the user's choice (--split, --obj-registries, else "
    "INDGEN_ROBOCASA_SPLIT, INDGEN_ROBOCASA_OBJ_REGISTRIES; the protocol facts' split names this run's), by default "
    "pretrain with "
    "objaverse and lightwheel, where RoboCasa365's multi-task and lifelong-learning benchmarks and its openpi client "
    "evaluate; RoboCasa365 evaluates its foundation-model checkpoints in target, lerobot split='all' with lightwheel "
    "only",
    "RoboCasa's counter-region order is made first-seen (RoboCasa iterates a set of XML elements, in memory order), "
    "so one seed is one kitchen in every process",
)
