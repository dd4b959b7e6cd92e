"""
AgileRL's MADDPG on MPE2's ``simple_speaker_listener_v4``, trained for the same number of timesteps as this library's
runs and measured on the same episodes (experiments/speaker_listener.py): the peer comparison of docs/results.md.

Runs in a virtual environment of its own (AgileRL pins its own dependencies), e.g.

    python -m venv peer_venv && peer_venv/bin/pip install torch==2.13.0 agilerl
    taskset -c 1 peer_venv/bin/python experiments/peer_speaker_listener.py --seed 0 --timesteps 50000

AgileRL's own training loop (``train_multi_agent_off_policy``) with a population of one and neither mutation nor
selection, so this is plain MADDPG; every hyperparameter is AgileRL's default (batch 64, actor and critic learning rates
1e-3 and 1e-2, an update every 5 timesteps (``--learn-step``), γ 0.95, τ 0.01, Ornstein-Uhlenbeck noise 0.1, [64, 64] networks,
Gumbel-softmax actors for discrete actions), the replay buffer holds 100 000 transitions and learning starts after
1 000 timesteps, as in this library's entry. One JSON line: the seed, the wall time and the measures of
:func:`speaker_listener_episodes` for the trained agents acting deterministically.
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--timesteps", type=int, default=50_000)
    parser.add_argument("--continuous", action="store_true", help="Box actions (default: Discrete, MPE2's default)")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--eval-seed", type=int, default=1000)
    parser.add_argument("--learn-step", type=int, default=5, help="timesteps per update (AgileRL's default 5)")
    args = parser.parse_args()

    from agilerl.algorithms import MADDPG
    from agilerl.components.replay_buffer import ReplayBuffer
    from agilerl.training.train_multi_agent_off_policy import train_multi_agent_off_policy
    from mpe2 import simple_speaker_listener_v4

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from speaker_listener import speaker_listener_episodes

    torch.set_num_threads(1)
    torch.manual_seed(args.seed)
    np.random.seed(args.seed)
    env = simple_speaker_listener_v4.parallel_env(max_cycles=25, continuous_actions=args.continuous)
    env.reset(seed=args.seed)
    agents = env.possible_agents
    agent = MADDPG(
        observation_spaces=[env.observation_space(name) for name in agents],
        action_spaces=[env.action_space(name) for name in agents],
        agent_ids=agents,
        learn_step=args.learn_step,
    )
    start = time.time()
    trained, _ = train_multi_agent_off_policy(
        env, "simple_speaker_listener_v4", "MADDPG", [agent], ReplayBuffer(100_000), max_steps=args.timesteps,
        evo_steps=10_000, eval_loop=1, learning_delay=1_000, verbose=False,
    )  # fmt: skip
    seconds = time.time() - start
    trained = trained[0]
    trained.set_training_mode(False)

    def act(observations):
        actions, _ = trained.get_action({name: obs[None] for name, obs in observations.items()})
        return {name: action[0] for name, action in actions.items()}

    with torch.no_grad():
        result = speaker_listener_episodes(act, args.episodes, args.eval_seed, args.continuous)
    print(json.dumps(dict(library="agilerl", seed=args.seed, timesteps=args.timesteps, learn_step=args.learn_step,
                          seconds=round(seconds),
                          continuous_actions=args.continuous, episodes=args.episodes, **result)))  # fmt: skip


if __name__ == "__main__":
    main()
