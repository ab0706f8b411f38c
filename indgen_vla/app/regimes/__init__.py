"""Data regimes: T0 demonstrations as LeRobotDatasets, MimicGen-style augmentation, tiny stand-ins."""

import os
import warnings


def quiet_datasets() -> None:
    """Silence `datasets` progress bars, which lerobot re-enables after every saved episode.

    Only the environment variable (read when `datasets` is imported) wins over lerobot, so CLI handlers
    call this before importing lerobot's dataset module.
    """
    os.environ.setdefault("HF_DATASETS_DISABLE_PROGRESS_BARS", "1")
    warnings.filterwarnings("ignore", message="Cannot enable progress bars")
