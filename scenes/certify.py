"""``indgen certify`` and the certificates, in one import: the rule and the oracle runs (``scenes.certify_run``),
where certificates live, how ``evaluate`` finds them and the CLI (``scenes.certify_io``, which builds on the
former). Those two modules import each other never; this one imports both."""

from __future__ import annotations

from scenes.certify_io import (
    cert_path,
    certification_root,
    certify_all,
    certify_main,
    find_certification,
    print_table,
    write_summary,
)
from scenes.certify_run import (
    Rule,
    certified_levels,
    certify,
    certify_level,
    episodes_needed,
    infeasible_levels,
    level_status,
    load_certification,
    lower_bound,
    run_oracle_episode,
    write_json_atomic,
)

__all__ = [
    "Rule", "lower_bound", "episodes_needed", "certify", "certify_level", "load_certification", "level_status",
    "infeasible_levels", "certified_levels", "write_json_atomic", "run_oracle_episode",
    "certification_root", "certify_all", "certify_main", "cert_path", "find_certification", "print_table",
    "write_summary",
]  # fmt: skip
