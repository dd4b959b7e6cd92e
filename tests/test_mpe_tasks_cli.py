"""Every MPE2 task trains from the command line in both action modes, with its shipped YAML entry, and acts."""

import os
from pathlib import Path

import numpy as np
import pytest

from sb3_maddpg import MADDPG
from sb3_maddpg.__main__ import main
from sb3_maddpg.zoo.registry import MPE2_TASKS, make_multiagent_env

pytest.importorskip("mpe2")
ENV_IDS = [
    env_id for task in ("simple_spread_v3", *MPE2_TASKS) for env_id in (task, "{}_discrete_{}".format(*task.rsplit("_", 1)))
]


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_task_trains_from_the_command_line(env_id: str, tmp_path: Path) -> None:
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        args = ["train", "--algo", "maddpg", "--env", env_id, "-n", "30", "--seed", "0", "--eval-freq", "-1"]
        small = ["-params", "learning_starts:10", "batch_size:8", "buffer_size:100", "--env-kwargs", "max_cycles:5"]
        assert main([*args, *small]) == 0
    finally:
        os.chdir(cwd)
    model = MADDPG.load(tmp_path / "logs" / "maddpg" / f"{env_id}_1" / f"{env_id}.zip", device="cpu")
    assert model.num_timesteps == 30
    # each agent gets an action of its own space from a PettingZoo observation dict
    env = make_multiagent_env(env_id, max_cycles=5)
    observations, _ = env.reset(seed=0)
    actions, _ = model.predict(observations, deterministic=True)
    assert actions.keys() == observations.keys()
    for agent, action in actions.items():
        assert env.action_space(agent).contains(np.asarray(action, dtype=env.action_space(agent).dtype)), agent
    env.close()
