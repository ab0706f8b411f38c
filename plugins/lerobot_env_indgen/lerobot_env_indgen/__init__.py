"""LeRobot plugin: importing it registers ``--env.type=indgen`` (``indgen_vla.app.lerobot_bridge.env_config``)."""

from indgen_vla.app.lerobot_bridge.env_config import IndgenEnv

__all__ = ["IndgenEnv"]
