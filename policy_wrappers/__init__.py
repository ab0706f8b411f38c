"""Policy wrappers: one adapter per family behind the tiny ``Policy`` protocol (``indgen_vla.core.protocol.interface``).

``load_policy("openpi:ws://HOST:PORT")`` is the entry point; family modules (and torch/lerobot) load lazily.
"""

from __future__ import annotations

from policy_wrappers.specs import load_policy

__all__ = ["load_policy"]
