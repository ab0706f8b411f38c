"""BlockEnv learners: the paper's baselines (appendix A.1), Ind, and a local translation-equivariant policy.

``base`` holds what every learner shares (encoders, heads; the method table and its options are ``blockenv.methods``); the learners
import it, and this package builds one by method key.
"""

from torch import nn

from indgen_vla.app.blockenv.methods import METHODS, check_options
from indgen_vla.app.blockenv.models.per_step import LocalConvPolicy, StepMLPPolicy
from indgen_vla.app.blockenv.models.recursive import TRMPolicy
from indgen_vla.app.blockenv.models.sequence import IndPolicy, RNNPolicy, TransformerPolicy
from indgen_vla.core.registry import lookup

__all__ = ["METHODS", "build_model"]


def build_model(method: str, grid: int, hidden: int = 128, extra: dict | None = None) -> nn.Module:
    """Instantiate a learner by method key; ``extra`` holds its OPTIONS (defaults when absent)."""
    o = check_options(method, extra or {}) if method in METHODS else {}
    table = {
        "rnn": lambda: RNNPolicy(grid, hidden),
        "transformer": lambda: TransformerPolicy(grid, hidden, rope=False),
        "transformer_rope": lambda: TransformerPolicy(grid, hidden, rope=True),
        "transformer_goal_act": lambda: TransformerPolicy(grid, hidden, rope=True, goal_act=True),
        "ind": lambda: IndPolicy(
            grid, hidden, gate_scale=o["gate_scale"], mask=o["mask"], legal_head=o["legal_head"]
        ),
        "trm": lambda: TRMPolicy(grid, hidden, patch=o["patch"]),
        "maml": lambda: StepMLPPolicy(grid, hidden * 2, joint=o["head"] == "joint"),
        "local_equivariant": lambda: LocalConvPolicy(),
    }
    return lookup("BlockEnv method", method, table)()
