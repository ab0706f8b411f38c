"""CPU stand-ins: deterministic given the episode seed."""

from __future__ import annotations

import numpy as np
import pytest

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.interface import PolicySpec, declared_reads
from policy_wrappers.specs import load_policy


def test_noop_is_still_and_open(obs_factory):
    policy = load_policy("standin:noop")
    policy.reset("x", seed=1)
    chunk = policy.act([obs_factory(0), obs_factory(1)])
    assert chunk.shape == (2, 8, 7) and chunk.dtype == np.float32
    assert np.all(chunk[..., :6] == 0) and np.all(chunk[..., 6] == -1)
    assert policy.spec.batched


def test_random_is_reproducible_from_the_seed(obs_factory):
    policy = load_policy("standin:random?chunk=5")
    obs = [obs_factory(0)]
    policy.reset("x", seed=7)
    a = np.concatenate([policy.act(obs), policy.act(obs)], axis=1)
    policy.reset("x", seed=7)
    b = np.concatenate([policy.act(obs), policy.act(obs)], axis=1)
    policy.reset("x", seed=8)
    c = policy.act(obs)
    assert a.shape == (1, 10, 7) and np.array_equal(a, b) and not np.array_equal(a[:, :5], c)
    assert np.all(np.abs(a[..., :6]) <= 0.5) and set(np.unique(a[..., 6])) <= {-1.0, 1.0}
    assert not policy.spec.batched  # per-episode RNG state


def test_stand_ins_that_ignore_observations_declare_it():
    """random and noop read no observation (report then says it cannot answer); a spec reads them by default."""
    assert not load_policy("standin:random").spec.reads_observations
    assert not load_policy("standin:noop").spec.reads_observations
    assert PolicySpec("lerobot", "lerobot:x").reads_observations
    with pytest.raises(ConfigError, match="reads_observations must be true or false, got 'no'"):
        PolicySpec("standin", "standin:x", reads_observations="no")
    # several runs as one (a merge's shards, a group of seeds): any blind run makes the group blind
    assert declared_reads([True, False]) is False and declared_reads([True, True]) is True
    assert declared_reads([True, None]) is None and declared_reads([]) is None
