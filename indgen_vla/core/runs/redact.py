"""A policy spec's secrets (``?api_key=``, ``?api_token=``) never reach a run directory, a policy's name or a report.

Run directories are shared (papers' artifacts, clusters' shared disks), and the spec is recorded in many places: the
manifest's policy, plan, config and command, every row's ``policy`` and episode errors that name the policy. The
policy still gets the key (the parsed options keep it); everything written or printed gets ``api_key=***``.
"""

from __future__ import annotations

import re
from typing import Any

SECRET_OPTIONS = (
    "api_key",
    "api_token",
)  # openpi / UniVLA / RynnVLA's Api-Key header, GR00T's api_token field
MASK = "***"
_SECRET = re.compile(r"(?<=[?&])(" + "|".join(SECRET_OPTIONS) + r")=[^&\s'\"]*")


def redact(text: str) -> str:
    """``text`` with the value of every secret spec option masked (``...?api_key=***&replan=5``)."""
    if "api_" not in text:  # every episode row passes here: one substring test in the common case
        return text
    return _SECRET.sub(lambda m: f"{m.group(1)}={MASK}", text)


def redact_tree(value: Any) -> Any:
    """``redact`` over every string of a JSON-like value (the manifest)."""
    if isinstance(value, str):
        return redact(value)
    if isinstance(value, dict):
        return {k: redact_tree(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(redact_tree(v) for v in value)
    return value
