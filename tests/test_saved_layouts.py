"""Files saved by earlier versions of the library still load and act the same (models here; buffers in test_device_buffer).

``tests/data/old_layout_maddpg.zip`` was saved by the code that stood before the multi-agent base class (commit
fb832a8: ``MADDPG(OffPolicyAlgorithm)`` with everything in ``maddpg/maddpg.py``): a 2-agent MlpPolicy model on
``TargetReachEnv`` after 30 timesteps; ``old_layout_maddpg_actions.npz`` holds 4 observation rows and the actions
that code predicted for them.
"""

from pathlib import Path

import numpy as np
import torch as th
from maddpg_test_envs import TargetReachEnv

from sb3_maddpg import MADDPG, make_multiagent_vec_env

DATA = Path(__file__).resolve().parent / "data"


def test_a_model_saved_before_the_base_class_loads_and_acts_as_it_did():
    model = MADDPG.load(DATA / "old_layout_maddpg.zip", device="cpu")
    saved = np.load(DATA / "old_layout_maddpg_actions.npz")
    actions, _ = model.predict(saved["observations"], deterministic=True)
    np.testing.assert_array_equal(actions, saved["actions"])
    assert model.n_agents == 2 and model.critic.n_critics == 1 and model.num_timesteps == 30


def test_a_model_saved_before_the_base_class_trains_on():
    venv = make_multiagent_vec_env(TargetReachEnv, n_envs=1, seed=0, env_kwargs=dict(n_agents=2))
    model = MADDPG.load(DATA / "old_layout_maddpg.zip", env=venv, device="cpu")
    before = [p.clone() for p in model.critic.parameters()]
    model.learn(20, reset_num_timesteps=False)
    assert model.num_timesteps == 50
    after = list(model.critic.parameters())
    assert any(not th.equal(a, b) for a, b in zip(before, after, strict=True))
