"""Per-episode seeds that depend only on the plan, never on worker count or scheduling order."""

from __future__ import annotations

import hashlib

import numpy as np


def episode_seed(base_seed: int, *key: object) -> int:
    """A 32-bit seed for one episode from the run seed and its identity (scene, task, axis, level, episode).

    Uses a cryptographic hash of the key so seeds are stable across processes and Python versions
    (``hash()`` is salted per process).
    """
    digest = hashlib.blake2b(repr((int(base_seed),) + tuple(key)).encode(), digest_size=8).digest()
    return int.from_bytes(digest, "little") % (2**32)


def episode_rng(base_seed: int, *key: object) -> np.random.Generator:
    """A numpy Generator seeded by ``episode_seed``."""
    return np.random.default_rng(episode_seed(base_seed, *key))
