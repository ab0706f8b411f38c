"""Loading one LeRobot policy imports only its lerobot subpackage; the rest of ``lerobot.policies`` still works."""

from __future__ import annotations

import importlib.metadata
import os
import subprocess
import sys
from pathlib import Path

import pytest

from policy_wrappers.lerobot_import import one_package_scan

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = ROOT / "checkpoints" / "act_pick_place_human"

CHILD = """
import sys
from policy_wrappers.registry import load_policy
policy = load_policy("lerobot:" + sys.argv[1], scene="pick_place")
OTHERS = ("lerobot.policies.eo1.modeling_eo1", "lerobot.policies.fastwam.modeling_fastwam",
          "lerobot.policies.groot.processor_groot", "lerobot.policies.smolvla.modeling_smolvla", "datasets")
print("others:", sorted(m for m in OTHERS if m in sys.modules))
from lerobot.policies import SmolVLAConfig, get_policy_class  # the package's own __init__ runs now
import lerobot.policies
from lerobot.policies.groot import GrootPolicy  # and a subpackage's on its first name
print("after:", SmolVLAConfig.__name__, get_policy_class("act").__name__, "ACTConfig" in lerobot.policies.__all__,
      GrootPolicy.__name__, "lerobot.policies.groot.processor_groot" in sys.modules)
"""


@pytest.mark.slow  # a fresh interpreter importing lerobot (~10 s); tests/policy_wrappers/test_lerobot.py loads
def test_act_loads_without_the_other_policies_and_the_package_still_works():  # through the same path by default
    pytest.importorskip("lerobot")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "HF_HUB_OFFLINE": "1"}
    out = subprocess.run([sys.executable, "-c", CHILD, str(SHIPPED)], env=env, capture_output=True, text=True,
                         cwd=ROOT, timeout=300)  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    assert "others: []" in out.stdout
    assert "after: SmolVLAConfig ACTPolicy True GrootPolicy True" in out.stdout


def test_one_package_scan_scans_once_and_restores(monkeypatch):
    calls = []

    def scan():
        calls.append(1)
        return {"numpy": ["numpy"]}

    monkeypatch.setattr(importlib.metadata, "packages_distributions", scan)
    with one_package_scan():
        first = importlib.metadata.packages_distributions()
        first["numpy"].append("changed by a caller")
        assert importlib.metadata.packages_distributions() == {"numpy": ["numpy"]}  # a copy each time
    assert len(calls) == 1
    assert importlib.metadata.packages_distributions is scan
