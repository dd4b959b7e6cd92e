"""The per-agent reference update of benchmarks/per_agent_reference.py (the baseline of benchmarks/update_speed.py) runs."""

import importlib.util
import math
from pathlib import Path

import torch as th

_PATH = Path(__file__).resolve().parents[1] / "benchmarks" / "per_agent_reference.py"


def _load_reference():
    spec = importlib.util.spec_from_file_location("per_agent_reference", _PATH)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_one_reference_update_trains_every_network():
    reference = _load_reference()
    th.manual_seed(0)
    n_agents, batch_size, n_quantiles, image_size = 2, 4, 5, 16
    agents = reference.make_agents(n_agents, n_quantiles, image_size, "cpu")
    batch = reference.random_batch(n_agents, batch_size, image_size, "cpu")
    names = ("actor", "critic", "actor_target", "critic_target")
    before = {
        (i, name): [p.detach().clone() for p in getattr(agent, name).parameters()]
        for i, agent in enumerate(agents)
        for name in names
    }
    # critic i owns one encoder per agent: N^2 critic encoders in all
    assert all(len(agent.critic.encoders) == n_agents for agent in agents)

    losses = reference.update(agents, batch)

    assert set(losses) == {"critic_loss", "actor_loss"}
    for values in losses.values():
        assert len(values) == n_agents
        assert all(math.isfinite(value) for value in values)
    for (i, name), old in before.items():
        new = list(getattr(agents[i], name).parameters())
        changed = [not th.equal(a, b) for a, b in zip(old, new, strict=True)]
        assert all(changed), f"agent {i}'s {name}: {changed.count(False)} of {len(changed)} parameter tensors unchanged"


def test_ms_per_update_is_positive():
    reference = _load_reference()
    ms = reference.ms_per_update(2, 4, 5, 16, "cpu", n_updates=1, warmup=0)
    assert ms > 0.0


def test_reference_loss_is_the_library_quantile_huber_loss():
    from sb3_maddpg.common.distributional import quantile_huber_loss

    reference = _load_reference()
    generator = th.Generator().manual_seed(0)
    current, target = th.randn(8, 5, generator=generator) * 2, th.randn(8, 5, generator=generator) * 2
    expected = quantile_huber_loss(current, target).mean()
    assert th.allclose(reference.quantile_huber_loss(current, target), expected, atol=1e-6)
