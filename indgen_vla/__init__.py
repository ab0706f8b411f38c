"""indgen-vla: measure inductive generalization of robot manipulation policies.

The public Python API is ``evaluate``, ``report``, ``compare`` and ``certify`` (docs/api.md), the types a policy of
your own implements (``Policy``, ``PolicySpec``, ``Observation``) and those a scene family of your own subclasses
(``Scene`` and its parts ``SceneEnvironment``, ``SceneCertificates``; ``TabletopScene``, ``SceneSpec``, ``Item``,
``register_scene``: docs/extending.md). Importing this package is cheap: each name loads its module on first use, and
torch, robosuite and lerobot load only inside what needs them.
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

# public name -> "module:attribute", imported on first access (PEP 562)
_LAZY = {
    "evaluate": "indgen_vla.app.api:evaluate",
    "report": "indgen_vla.app.api:report",
    "compare": "indgen_vla.app.api:compare",
    "certify": "indgen_vla.app.api:certify",
    "import_lerobot_eval": "indgen_vla.app.api:import_lerobot_eval",
    # the other commands, each taking its config (docs/api.md)
    "demos": "indgen_vla.app.api:demos",
    "mimicgen": "indgen_vla.app.api:mimicgen",
    "train": "indgen_vla.app.api:train",
    "budget": "indgen_vla.app.api:budget",
    "series": "indgen_vla.app.api:series",
    "real_plan": "indgen_vla.app.api:real_plan",
    "DemosConfig": "indgen_vla.app.regimes.demos:DemosConfig",
    "MimicGenConfig": "indgen_vla.app.regimes.mimicgen:MimicGenConfig",
    "TrainConfig": "indgen_vla.app.regimes.train:TrainConfig",
    "BudgetConfig": "indgen_vla.app.studies.config:BudgetConfig",
    "SeriesConfig": "indgen_vla.app.studies.config:SeriesConfig",
    "RealPlanConfig": "indgen_vla.app.real.design:RealPlanConfig",
    "Run": "indgen_vla.core.runs.result:Run",
    "KStar": "indgen_vla.core.runs.result:KStar",
    "EvalConfig": "indgen_vla.app.engine.config:EvalConfig",
    "PlanConfig": "indgen_vla.app.engine.config:PlanConfig",
    "PolicyConfig": "indgen_vla.app.engine.config:PolicyConfig",
    "RunConfig": "indgen_vla.app.engine.config:RunConfig",
    "AdaptiveConfig": "indgen_vla.app.engine.config:AdaptiveConfig",
    "CertifyConfig": "indgen_vla.app.certify.certify_config:CertifyConfig",
    # the extension point of a policy of your own (docs/extending.md): what it sees, declares and returns
    "Policy": "indgen_vla.core.protocol.interface:Policy",
    "PolicySpec": "indgen_vla.core.protocol.interface:PolicySpec",
    "Observation": "indgen_vla.core.protocol.interface:Observation",
    "Action": "indgen_vla.core.protocol.interface:Action",
    "ACTION_DIM": "indgen_vla.core.protocol.interface:ACTION_DIM",
    "EnvSpec": "indgen_vla.core.protocol.interface:EnvSpec",
    # the extension point of a scene family of your own (docs/extending.md): the base (a catalogue with its
    # environment and certificate parts), the tabletop backend's base, a level's frozen spec and its items, the
    # registration, the family lookup by name, the tabletop predicates
    "Scene": "scenes.family:Scene",
    "SceneEnvironment": "scenes.family:SceneEnvironment",
    "SceneCertificates": "scenes.family:SceneCertificates",
    "TabletopScene": "scenes.tabletop:TabletopScene",
    "SceneSpec": "scenes.spec:SceneSpec",
    "Item": "scenes.spec:Item",
    "register_scene": "scenes.family:register_scene",
    "get_scene": "scenes.family:get_scene",
    "InReceptacle": "scenes.predicates:InReceptacle",
    "IndgenError": "indgen_vla.core.errors:IndgenError",
    "ConfigError": "indgen_vla.core.errors:ConfigError",
    "EpisodeErrorsWarning": "indgen_vla.core.errors:EpisodeErrorsWarning",
}
__all__ = ["__version__", *_LAZY]


def __getattr__(name: str) -> Any:
    if name not in _LAZY:
        raise AttributeError(f"module 'indgen_vla' has no attribute {name!r}")
    module, _, attr = _LAZY[name].partition(":")
    value = getattr(importlib.import_module(module), attr)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)
