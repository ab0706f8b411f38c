"""``indgen real``: the paper's real-robot protocol (§5.3) with an operator in the loop.

The robot and the policy run in the user's own stack (DROID's eval loop, an openpi client, ``lerobot-record``);
this package runs everything around them: what to set up at each level in physical units (``setup``), the
episode order and manifest of a normal run directory (``plan``), a crash-safe journal of the operator's verdicts
from which ``episodes.parquet`` is rebuilt (``store``), and the keyboard session that takes them (``session``).
"""
