"""Per-episode seeds that depend only on the plan, never on worker count or scheduling order."""

from __future__ import annotations

import hashlib
from collections.abc import Collection, Iterable

# the evaluation seeds training data never takes (``held_out_seeds``): ``evaluate --seed 0..9`` (and the recorder's
# own seed), episodes 0..999 of every (scene, task), i.e. every level and axis of those runs
HELD_OUT_RUN_SEEDS = 10
HELD_OUT_EPISODES = 1000


def episode_seed(base_seed: int, *key: object) -> int:
    """A 32-bit seed for one episode from the run seed and its identity (scene, task, axis, level, episode).

    Uses a cryptographic hash of the key so seeds are stable across processes and Python versions
    (``hash()`` is salted per process).
    """
    digest = hashlib.blake2b(repr((int(base_seed),) + tuple(key)).encode(), digest_size=8).digest()
    return int.from_bytes(digest, "little") % (2**32)


def evaluation_seed(run_seed: int, scene: str, task: str, episode: int) -> int:
    """The seed ``evaluate`` gives episode ``episode`` of (scene, task): the same at every level and axis."""
    return episode_seed(run_seed, scene, task, episode)


def held_out_seeds(scene: str, task: str, also: Iterable[int] = ()) -> frozenset[int]:
    """Evaluation seeds of (scene, task) that demonstrations and generated data must not start from.

    Evaluation episode i starts from ``evaluation_seed(run_seed, ...)`` at every level, so training data that
    avoids these never shares an initial state with ``evaluate --seed S`` for S in 0..9 or ``also``, episodes
    0..999 (outside that, only a 32-bit hash collision could).
    """
    run_seeds = set(range(HELD_OUT_RUN_SEEDS)) | {int(s) for s in also}
    return frozenset(
        evaluation_seed(r, scene, task, ep) for r in sorted(run_seeds) for ep in range(HELD_OUT_EPISODES)
    )


def fresh_seed(base_seed: int, *key: object, avoid: Collection[int]) -> int:
    """``episode_seed(base_seed, *key)``, or when that is in ``avoid`` the first of ``key + (1,)``, ``key + (2,)``,
    ... that is not (the plain seed whenever it is free, so seeds stay what they were without ``avoid``)."""
    seed, bump = episode_seed(base_seed, *key), 0
    while seed in avoid:
        bump += 1
        seed = episode_seed(base_seed, *key, bump)
    return seed
