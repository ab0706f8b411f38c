"""RoboCasa365's episode length per task, as RoboCasa's own evaluators take it (lerobot, RoboCasa365's openpi client).

RoboCasa registers each task's limit in ``robocasa/utils/dataset_registry.py`` (``ATOMIC_TASK_DATASETS`` /
``COMPOSITE_TASK_DATASETS``, field ``horizon``) and reads it with ``get_task_horizon(task)``
(``robocasa/utils/dataset_registry_utils.py``). The constants below are that registry's values for the 17 tasks of
appendix B in the pinned release (rlinf-robocasa365 1.0.1 = upstream be22d659); tests compare them with the pinned
install's own ``get_task_horizon``. Importing this is cheap.
"""

from __future__ import annotations

from indgen_vla.core.errors import ConfigError

REGISTRY = "RoboCasa's get_task_horizon (robocasa/utils/dataset_registry.py, field horizon)"
# steps at 20 Hz; the task names are RoboCasa's own registry keys
TASK_HORIZONS: dict[str, int] = {
    "CheesyBread": 750,
    "CloseElectricKettleLid": 300,
    "CloseStandMixerHead": 450,
    "CloseToasterOvenDoor": 450,
    "CoffeeSetupMug": 600,
    "OpenElectricKettleLid": 300,
    "OpenStandMixerHead": 450,
    "PickPlaceCabinetToCounter": 450,
    "PickPlaceCounterToBlender": 750,
    "PickPlaceCounterToCabinet": 750,
    "PickPlaceCounterToDrawer": 750,
    "PickPlaceCounterToSink": 600,
    "PickPlaceCounterToStandMixer": 600,
    "PickPlaceFridgeDrawerToShelf": 600,
    "PickPlaceSinkToCounter": 900,
    "TurnOnBlender": 300,
    "TurnOnElectricKettle": 450,
}


def task_horizon(task: str) -> int:
    """``task``'s registered limit (``Task@L-S``: the task's own; a canonical kitchen does not change it)."""
    name = task.partition("@")[0]
    if name not in TASK_HORIZONS:
        raise ConfigError(
            f"scene robocasa: task {name} has no horizon in {REGISTRY}; pick one of {', '.join(TASK_HORIZONS)} "
            "or pass --max-steps"
        )
    return TASK_HORIZONS[name]
