"""Environment copies in worker processes (``vec_env_cls="subproc"``) behave exactly as the copies in one process."""

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg.common.env_util import find_multiagent_vec_env
from sb3_maddpg.common.subproc_vec_env import SubprocMultiAgentVecEnv
from sb3_maddpg.common.vec_env import MultiAgentVecEnv
from sb3_maddpg_envs import uav_coverage_v0

# Short episodes, so that automatic resets (terminal observations, reset infos, episode statistics) are compared too
ENV_KWARGS = {"obs_size": 16, "max_cycles": 5, "n_uavs": 2, "start": "random"}
N_COPIES = 3


@pytest.fixture
def env_pair() -> Any:
    """The same 3 copies with seed 11, in this process and in 2 worker processes (2 copies + 1)."""
    local = make_multiagent_vec_env(uav_coverage_v0.parallel_env, n_envs=N_COPIES, seed=11, env_kwargs=ENV_KWARGS)
    remote = make_multiagent_vec_env(
        uav_coverage_v0.parallel_env, n_envs=N_COPIES, seed=11, env_kwargs=ENV_KWARGS, vec_env_cls="subproc", n_processes=2
    )
    yield local, remote
    local.close()
    remote.close()


def _assert_same_infos(expected: list[dict], actual: list[dict]) -> None:
    assert len(expected) == len(actual)
    for info_a, info_b in zip(expected, actual, strict=True):
        assert info_a.keys() == info_b.keys()
        for key, value in info_a.items():
            if key == "terminal_observation":
                np.testing.assert_array_equal(value, info_b[key])
            elif key == "episode":
                # "t" is wall-clock time since the VecEnv was created
                assert {k: v for k, v in value.items() if k != "t"} == {k: v for k, v in info_b[key].items() if k != "t"}
            else:
                assert value == info_b[key], key


def _run_both(local: Any, remote: Any, n_steps: int, seed: int = 0) -> None:
    np.testing.assert_array_equal(local.reset(), remote.reset())
    _assert_same_infos(local.reset_infos, remote.reset_infos)
    rng = np.random.default_rng(seed)
    episode_ends = 0
    for _ in range(n_steps):
        actions = rng.random((local.num_envs, 2)).astype(np.float32)
        obs_a, rewards_a, dones_a, infos_a = local.step(actions)
        obs_b, rewards_b, dones_b, infos_b = remote.step(actions)
        np.testing.assert_array_equal(obs_a, obs_b)
        np.testing.assert_array_equal(rewards_a, rewards_b)
        np.testing.assert_array_equal(dones_a, dones_b)
        _assert_same_infos(infos_a, infos_b)
        _assert_same_infos(local.reset_infos, remote.reset_infos)
        episode_ends += int(dones_a.any())
    # every copy's episode lasts max_cycles steps
    assert episode_ends == n_steps // ENV_KWARGS["max_cycles"]


def test_worker_processes_give_the_same_steps_as_one_process(env_pair: Any) -> None:
    local, remote = env_pair
    assert isinstance(remote, SubprocMultiAgentVecEnv) and remote.n_processes == 2
    assert (remote.num_envs, remote.n_agents, remote.n_copies) == (local.num_envs, local.n_agents, local.n_copies)
    assert remote.observation_space == local.observation_space and remote.action_space == local.action_space
    assert remote.possible_agents == local.possible_agents
    _run_both(local, remote, n_steps=12)
    # Copies reseeded with a new base seed, then reset again
    assert local.seed(5) == remote.seed(5)
    _run_both(local, remote, n_steps=6, seed=1)


def test_copies_have_distinct_seeds_in_worker_processes(env_pair: Any) -> None:
    _, remote = env_pair
    obs = np.asarray(remote.reset()).reshape(N_COPIES, 2, *remote.observation_space.shape)
    # start="random": every copy starts elsewhere (SuperSuit's processes would have repeated seeds)
    assert len({obs[copy].tobytes() for copy in range(N_COPIES)}) == N_COPIES
    assert [state["seed"] for state in remote.reset_states()] == [11, 12, 13]


def test_reset_states_replay_across_processes(env_pair: Any) -> None:
    local, remote = env_pair
    _run_both(local, remote, n_steps=7)
    states = local.reset_states()
    assert remote.reset_states() == states
    fresh = make_multiagent_vec_env(
        uav_coverage_v0.parallel_env, n_envs=N_COPIES, env_kwargs=ENV_KWARGS, vec_env_cls="subproc", n_processes=3
    )
    try:
        assert fresh.restore_reset_states(states) and local.restore_reset_states(states)
        np.testing.assert_array_equal(local.reset(), fresh.reset())
        assert not fresh.restore_reset_states(states[:2])
    finally:
        fresh.close()


def test_attributes_and_methods_reach_the_copy_of_each_row(env_pair: Any) -> None:
    local, remote = env_pair
    rows = [5, 0, 3]
    assert remote.get_attr("max_cycles", rows) == local.get_attr("max_cycles", rows) == [5, 5, 5]
    remote.set_attr("max_cycles", 9, indices=[4])
    assert remote.get_attr("max_cycles") == [5, 5, 5, 5, 9, 9]
    assert remote.env_method("observation_space", "uav_1", indices=rows) == local.env_method(
        "observation_space", "uav_1", indices=rows
    )
    assert find_multiagent_vec_env(remote) is remote and isinstance(find_multiagent_vec_env(local), MultiAgentVecEnv)


def test_errors_of_the_env_are_raised_in_the_parent(env_pair: Any) -> None:
    _, remote = env_pair
    remote.reset()
    with pytest.raises(ValueError, match="finite"):
        remote.step(np.full((remote.num_envs, 2), np.nan, dtype=np.float32))
    # the pipes are still in step
    obs, *_ = remote.step(np.full((remote.num_envs, 2), 0.5, dtype=np.float32))
    assert obs.shape[0] == remote.num_envs


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"vec_env_cls": "threads"}, "vec_env_cls must be"),
        ({"vec_env_cls": "subproc", "n_processes": 0}, "n_processes must be"),
        ({"n_processes": 2}, "needs vec_env_cls='subproc'"),
    ],
)
def test_bad_process_settings(kwargs: dict[str, Any], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        make_multiagent_vec_env(uav_coverage_v0.parallel_env, n_envs=2, env_kwargs=ENV_KWARGS, **kwargs)


def test_maddpg_learns_the_same_with_copies_in_processes() -> None:
    kwargs = {"obs_size": 16, "max_cycles": 10, "n_uavs": 2}
    parameters = []
    for vec_env_cls in (None, "subproc"):
        env = make_multiagent_vec_env(uav_coverage_v0.parallel_env, n_envs=2, env_kwargs=kwargs, vec_env_cls=vec_env_cls)
        model = MADDPG("CnnPolicy", env, buffer_size=500, learning_starts=20, batch_size=16, seed=3, device="cpu")
        model.learn(40)
        parameters.append(np.concatenate([p.detach().numpy().ravel() for p in model.policy.parameters()]))
        env.close()
    np.testing.assert_array_equal(parameters[0], parameters[1])


def test_train_command_runs_copies_in_processes(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from sb3_maddpg.__main__ import main

    config = str(Path(__file__).resolve().parent.parent / "zoo_configs" / "maddpg.yml")
    monkeypatch.chdir(tmp_path)
    created = []
    original = SubprocMultiAgentVecEnv.__init__

    def record(self: SubprocMultiAgentVecEnv, *args: Any, **kwargs: Any) -> None:
        original(self, *args, **kwargs)
        created.append(self.n_copies)

    monkeypatch.setattr(SubprocMultiAgentVecEnv, "__init__", record)
    argv = ["train", "--env", "uav_coverage_fast_v0", "-conf", config, "--env-kwargs", "obs_size:16", "max_cycles:10"]
    argv += ["n_uavs:2", "-params", "n_envs:2", "learning_starts:20", "-n", "40", "--vec-env", "subproc", "--eval-freq", "-1"]
    assert main(argv) == 0
    assert created and created[0] == 2
    assert (tmp_path / "logs" / "maddpg" / "uav_coverage_fast_v0_1" / "uav_coverage_fast_v0.zip").is_file()


def test_agents_with_spaces_of_their_own_in_worker_processes() -> None:
    """Padding and each agent's spaces survive the move into worker processes: the same steps and the same spaces."""
    simple_speaker_listener_v4 = pytest.importorskip("mpe2.simple_speaker_listener_v4")
    env_kwargs = dict(continuous_actions=False, max_cycles=5)
    local = make_multiagent_vec_env(simple_speaker_listener_v4.parallel_env, n_envs=2, seed=3, env_kwargs=env_kwargs)
    remote = make_multiagent_vec_env(
        simple_speaker_listener_v4.parallel_env, n_envs=2, seed=3, env_kwargs=env_kwargs, vec_env_cls="subproc", n_processes=2
    )
    try:
        assert remote.agent_spaces == local.agent_spaces and local.agent_spaces is not None
        np.testing.assert_array_equal(local.reset(), remote.reset())
        # rows: speaker (3 actions), listener (5 actions) of copy 0, then of copy 1
        actions = np.array([2, 4, 0, 3])
        for _ in range(6):  # past the end of the 5-step episodes
            for a, b in zip(local.step(actions)[:3], remote.step(actions)[:3], strict=True):
                np.testing.assert_array_equal(a, b)
    finally:
        local.close()
        remote.close()
