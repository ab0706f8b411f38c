"""Per-episode seeds that depend only on the plan, never on worker count or scheduling order."""

from __future__ import annotations

import hashlib


def episode_seed(base_seed: int, *key: object) -> int:
    """A 32-bit seed for one episode from the run seed and its identity (scene, task, axis, level, episode).

    Uses a cryptographic hash of the key so seeds are stable across processes and Python versions
    (``hash()`` is salted per process).
    """
    digest = hashlib.blake2b(repr((int(base_seed),) + tuple(key)).encode(), digest_size=8).digest()
    return int.from_bytes(digest, "little") % (2**32)
