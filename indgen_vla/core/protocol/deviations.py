"""Where a run departs from its scene family's own protocol, in words for the manifest and the report: a family
that registers each task's horizon (RoboCasa365: ``get_task_horizon``) and a ``--max-steps`` that replaces it, plus
the family's own standing deviations (its protocol facts' ``deviations``)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any


def protocol_deviations(max_steps: int | None, protocol: Mapping[str, Any]) -> list[str]:
    """The deviations of a run from ``protocol`` (the scene's ``protocol_facts``) under ``--max-steps``."""
    out = [str(d) for d in protocol.get("deviations", ())]
    own = protocol.get("max_steps")
    if max_steps is not None and isinstance(own, Mapping):
        source = protocol.get("horizon_source", "the family's per-task horizons")
        lo, hi = min(own.values()), max(own.values())
        out.append(
            f"--max-steps {int(max_steps)} replaces {source} for every task (registered: {lo}..{hi} steps per "
            "task): success rates are not comparable with the family's own evaluations"
        )
    return out
