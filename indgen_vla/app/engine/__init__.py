"""The rollout engine: plan episodes, drive scenes with a policy, record every episode.

The application composes scenes and policies, so the scene-side stand-ins are registered here, in one place
(``policy_wrappers`` never refers to ``scenes``): ``standin:oracle`` is the scenes' privileged controller.
"""

from policy_wrappers.specs import register_standin

register_standin(
    "oracle", "scenes.oracles:oracle_for", "privileged scripted oracle of the scenes (certifies every level)"
)
