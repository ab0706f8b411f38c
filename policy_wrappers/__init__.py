"""Policy wrappers: one adapter per family behind the tiny ``Policy`` protocol (``indgen_vla.core.protocol.interface``).

``load_policy("openpi:ws://HOST:PORT")`` is the entry point; family modules (and torch/lerobot) load lazily.
"""

from __future__ import annotations


def load_policy(spec: str, **kwargs):
    """Load the policy a spec string names; see ``policy_wrappers.specs.load_policy``."""
    from policy_wrappers.specs import load_policy as _load

    return _load(spec, **kwargs)


__all__ = ["load_policy"]
