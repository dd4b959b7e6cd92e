"""The README's library example runs as written (with a smaller training budget), and the usage page's resume claim holds."""

import re
from pathlib import Path

import numpy as np
import pytest

README = Path(__file__).resolve().parent.parent / "README.md"
USAGE = README.parent / "docs" / "usage.md"


def test_readme_library_example_runs(tmp_path, monkeypatch) -> None:
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    example = next(block for block in blocks if "MADDPG(" in block and "model.learn" in block)
    # The example trains for 50 000 timesteps; the test keeps every line but the budget, and a buffer that fits CI
    assert "total_timesteps=50_000" in example
    example = example.replace("total_timesteps=50_000", "total_timesteps=120")
    example = example.replace('tensorboard_log="runs",', 'tensorboard_log="runs", buffer_size=500, learning_starts=60,')
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    exec(compile(example, str(README), "exec"), namespace)

    actions = namespace["actions"]
    venv = namespace["venv"]
    assert actions.shape == (venv.num_envs, 2)
    assert np.all((actions >= 0) & (actions <= 1))
    assert set(namespace["agent_actions"]) == set(namespace["env"].possible_agents)
    assert (tmp_path / "maddpg_uav.zip").is_file()
    assert list((tmp_path / "runs").rglob("events.out.tfevents.*"))


def test_the_usage_page_says_where_a_resume_continues_exactly() -> None:
    from sb3_maddpg.common.vec_env import env_generator
    from sb3_maddpg.zoo.registry import make_multiagent_env

    text = " ".join(USAGE.read_text().split())
    claim = text[text.index("continues exactly") :][:400]
    assert "the UAV envs" in claim and "not on MPE2's tasks" in claim
    # what the claim rests on: the UAV env's generator is read (and saved with the model), MPE2's is not
    uav = make_multiagent_env("uav_coverage_fast_v0")
    uav.reset(seed=0)
    assert env_generator(uav) is not None
    simple_spread = pytest.importorskip("mpe2.simple_spread_v3").parallel_env()
    simple_spread.reset(seed=0)
    assert env_generator(simple_spread) is None
