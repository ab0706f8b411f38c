"""indgen-vla: measure inductive generalization of robot manipulation policies.

Importing this package is cheap: torch, robosuite and lerobot load only inside the modules that need them.
"""

__version__ = "0.1.0"
