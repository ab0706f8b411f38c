"""LeRobot processor steps that indgen's own checkpoints save in their ``policy_preprocessor.json``.

lerobot's ACT and Diffusion refuse a state-only input (they want an image or an environment state).
``ProprioAsEnvStateStep`` lets a state-only policy exist without any privileged input: it copies the
robot's own proprioception (``observation.state``) into ``observation.environment_state`` inside the
preprocessor, so the model's second input is the same 8 numbers, never simulator state. The step is saved
by class path, so lerobot imports this module by itself when it loads the preprocessor.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from lerobot.configs import PipelineFeatureType, PolicyFeature
from lerobot.configs.types import FeatureType
from lerobot.processor.pipeline import ObservationProcessorStep
from lerobot.utils.constants import OBS_ENV_STATE, OBS_STATE


@dataclass
class ProprioAsEnvStateStep(ObservationProcessorStep):
    """Copy ``observation.state`` (proprioception) to ``observation.environment_state``."""

    def observation(self, observation):
        if OBS_STATE in observation:
            observation[OBS_ENV_STATE] = observation[OBS_STATE]
        return observation

    def get_config(self) -> dict[str, Any]:
        return {}

    def transform_features(
        self, features: dict[PipelineFeatureType, dict[str, PolicyFeature]]
    ) -> dict[PipelineFeatureType, dict[str, PolicyFeature]]:
        obs = features.get(PipelineFeatureType.OBSERVATION, {})
        if OBS_STATE in obs:
            obs[OBS_ENV_STATE] = PolicyFeature(FeatureType.ENV, tuple(obs[OBS_STATE].shape))
        return features


@dataclass
class ObjectPosesStep(ObservationProcessorStep):
    """Declares that ``observation.environment_state`` is indgen's object observation (pick and target poses,
    ``indgen_vla.core.protocol.interface.OBJECT_NAMES``), so the wrapper hands the policy ``Observation.objects`` there.

    It changes nothing: the wrapper fills the input; the step only marks the checkpoint as a low-dim policy
    trained on those poses (any other environment state is refused).
    """

    def observation(self, observation):
        return observation

    def get_config(self) -> dict[str, Any]:
        return {}

    def transform_features(
        self, features: dict[PipelineFeatureType, dict[str, PolicyFeature]]
    ) -> dict[PipelineFeatureType, dict[str, PolicyFeature]]:
        return features
