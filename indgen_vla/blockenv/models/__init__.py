"""BlockEnv learners: the paper's baselines (appendix A.1), Ind, and a local translation-equivariant policy."""

from indgen_vla.blockenv.models.base import METHODS, build_model

__all__ = ["METHODS", "build_model"]
