"""Loading one LeRobot policy imports only its lerobot subpackage; the rest of ``lerobot.policies`` still works."""

from __future__ import annotations

import importlib.metadata
import os
import subprocess
import sys
from pathlib import Path

import pytest

from policy_wrappers.lerobot_import import Deferred, one_package_scan

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = ROOT / "checkpoints" / "act_pick_place_human"

CHILD = """
import sys
from policy_wrappers.specs import load_policy
policy = load_policy("lerobot:" + sys.argv[1], scene="pick_place")
OTHERS = ("lerobot.policies.eo1.modeling_eo1", "lerobot.policies.fastwam.modeling_fastwam",
          "lerobot.policies.groot.processor_groot", "lerobot.policies.smolvla.modeling_smolvla", "datasets")
print("others:", sorted(m for m in OTHERS if m in sys.modules))
print("optional:", sorted(m for m in ("transformers", "diffusers", "scipy.optimize") if m in sys.modules))
import lerobot.optim.schedulers as schedulers, lerobot.processor.tokenizer_processor as tokenizing
tokenizer_class = tokenizing.AutoTokenizer.resolve()  # what TokenizerProcessorStep calls from_pretrained on
import transformers, diffusers.optimization
print("resolved:", tokenizer_class is transformers.AutoTokenizer is tokenizing.AutoTokenizer,
      schedulers.get_scheduler.resolve() is diffusers.optimization.get_scheduler is schedulers.get_scheduler,
      tokenizing._transformers_available, schedulers._diffusers_available)
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
    assert (
        "optional: []" in out.stdout
    )  # ACT needs neither transformers nor diffusers (lerobot_import.DEFERRED)
    assert "resolved: True True True True" in out.stdout
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


def test_a_deferred_name_imports_its_source_on_first_use_and_takes_its_place(monkeypatch):
    """``Deferred`` (lerobot_import.DEFERRED): a call or an attribute imports the real object, which then replaces
    the stand-in in its owner module, so later lookups are the real object itself."""
    import json
    import types

    owner = types.ModuleType("owner_for_test")
    monkeypatch.setitem(sys.modules, owner.__name__, owner)
    owner.dumps = Deferred(owner.__name__, "dumps", "json")
    owner.JSONDecoder = Deferred(owner.__name__, "JSONDecoder", "json")
    assert "deferred json.dumps" in repr(owner.dumps)
    assert owner.dumps([1]) == "[1]" and owner.dumps is json.dumps
    assert owner.JSONDecoder.decode is json.JSONDecoder.decode and owner.JSONDecoder is json.JSONDecoder
    assert not hasattr(Deferred(owner.__name__, "x", "json"), "__wrapped__")  # dunders never import
