"""BlockEnv: the paper's toy inductive benchmark (appendix A), its oracle, learners and Table 1."""
