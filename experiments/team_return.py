"""
Mean team return of saved models (and of uniformly random actions) on a registered multi-agent env: the measure of
the MPE comparisons in docs/results.md. One JSON line per model. Box or Discrete actions (random actions: uniform in
the box, or uniform integers).

    python experiments/team_return.py --env simple_spread_v3 --episodes 20 --seed 1000 \
        runs/matd3/logs/*/simple_spread_v3_*/simple_spread_v3.zip

The team return of an episode is the sum over agents and steps of the agents' rewards (what SB3 logs as
``rollout/ep_rew_mean`` for this library's algorithms); actions are deterministic; episode e of every method is
reset with seed ``--seed + e``.
"""

import argparse
import json

import numpy as np
from gymnasium import spaces

from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg.common.callbacks import team_returns as team_return_split
from sb3_maddpg.zoo import registry  # noqa: F401  (registers the env ids)
from sb3_maddpg.zoo.registry import make_multiagent_env


def team_returns(env_id: str, env_kwargs: dict, act, episodes: int, seed: int) -> tuple[list[float], dict[str, list[float]]]:
    """
    Team return of ``episodes`` episodes, episode e reset with seed ``seed + e``; and, where the agents' names make
    several competing teams (MPE2's adversaries and good agents), each team's returns.
    """
    returns, by_team = [], {}
    for episode in range(episodes):
        venv = make_multiagent_vec_env(lambda: make_multiagent_env(env_id, **env_kwargs), n_envs=1, seed=seed + episode)
        obs, total, done = venv.reset(), 0.0, False
        while not done:
            obs, rewards, dones, infos = venv.step(act(obs))
            total += float(np.sum(rewards))
            done = bool(np.any(dones))
        returns.append(total)
        teams = team_return_split(infos[0]["episode"]["agent_r"])
        if len(teams) > 1:
            for team, value in teams.items():
                by_team.setdefault(team, []).append(value)
    return returns, by_team


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument("models", nargs="*", help="saved models (.zip)")
    parser.add_argument("--env", default="simple_spread_v3")
    parser.add_argument("--env-kwargs", default='{"continuous_actions": true, "max_cycles": 25}', help="JSON")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=1000)
    args = parser.parse_args()
    env_kwargs = json.loads(args.env_kwargs)
    rng = np.random.default_rng(args.seed)
    probe = make_multiagent_vec_env(lambda: make_multiagent_env(args.env, **env_kwargs), n_envs=1, seed=0)
    space = probe.action_space
    if isinstance(space, spaces.Discrete):  # uniform integers, one per agent row, each among its agent's own actions
        widths = space.n if probe.agent_spaces is None else probe.agent_spaces.action_widths
        controllers = {"random": lambda obs: space.start + rng.integers(widths, size=len(obs))}
    else:
        low, high = space.low, space.high
        controllers = {"random": lambda obs: rng.uniform(low, high, (len(obs), *low.shape)).astype(np.float32)}
    for path in args.models:
        model = MADDPG.load(path, device="cpu")  # a MATD3 model loads as well: the same networks act
        controllers[path] = lambda obs, model=model: model.predict(obs, deterministic=True)[0]
    for name, act in controllers.items():
        returns, by_team = team_returns(args.env, env_kwargs, act, args.episodes, args.seed)
        teams = {f"mean_{team}": float(np.mean(values)) for team, values in by_team.items()}
        print(json.dumps(dict(model=name, env=args.env, episodes=args.episodes, mean=float(np.mean(returns)),
                              std=float(np.std(returns)), **teams)))  # fmt: skip


if __name__ == "__main__":
    main()
