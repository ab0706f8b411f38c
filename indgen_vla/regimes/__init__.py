"""Data regimes: T0 demonstrations as LeRobotDatasets, MimicGen-style augmentation, tiny stand-ins."""
