"""Importing lerobot for a policy, with the package-map scan it triggers done once instead of twice.

lerobot's policy modules import transformers and diffusers, and each of them calls
``importlib.metadata.packages_distributions()`` at import time: a walk over every installed package's RECORD
(0.5-1.4 s on a 2-core machine with torch's and NVIDIA's large ones). Inside ``one_package_scan()`` the second
call gets a copy of the first's answer; nothing is installed or removed in between, so both see the same map.
"""

from __future__ import annotations

import contextlib
import importlib.metadata
from collections.abc import Iterator


@contextlib.contextmanager
def one_package_scan() -> Iterator[None]:
    """Within this block ``importlib.metadata.packages_distributions()`` scans the installed packages once."""
    real = importlib.metadata.packages_distributions
    cache: list[dict[str, list[str]]] = []

    def packages_distributions() -> dict[str, list[str]]:
        if not cache:
            cache.append(real())
        return {name: list(dists) for name, dists in cache[0].items()}

    importlib.metadata.packages_distributions = packages_distributions
    try:
        yield
    finally:
        importlib.metadata.packages_distributions = real
