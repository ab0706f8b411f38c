"""What ``make test`` exports, as defaults for a bare ``pytest``: MuJoCo renders through EGL, the Hub stays offline."""

import os

for _name, _value in {"MUJOCO_GL": "egl", "HF_HUB_OFFLINE": "1", "TOKENIZERS_PARALLELISM": "false"}.items():
    os.environ.setdefault(_name, _value)
