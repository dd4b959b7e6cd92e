"""
Train MADDPG on a UAV coverage env and evaluate it: the script behind the learning measurements of
``docs/results.md`` and ``docs/environment.md``.

Each run trains one seed, evaluates the deterministic policy every ``--eval-every`` timesteps on a few episodes with
random starts (the learning curve), then on ``--eval-episodes`` episodes with random starts (seeds 10_000 + e, the
same for every run, so runs are paired), and prints one JSON line per evaluation. Timing is wall clock on one torch
thread: pin each run to a core (``taskset -c 0``) and run at most one per core.

    taskset -c 0 python experiments/uav_learning.py --env uav_coverage_cpu_v1 --timesteps 60000 --seed 0 \\
        --algo-kwargs '{"cvar_alpha": 0.5}' --out runs/learning/alpha05_s0.jsonl
"""

import argparse
import json
import os
import sys
import time
from typing import Any

import numpy as np
import torch as th
from rl_zoo3.utils import linear_schedule
from stable_baselines3.common.callbacks import BaseCallback

from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg.common.noise import DecayingGaussianNoise
from sb3_maddpg.evaluation.baselines import ModelController
from sb3_maddpg.evaluation.evaluate import evaluate_controllers, worst_decile
from sb3_maddpg.evaluation.metrics import task_metrics
from sb3_maddpg.zoo.registry import make_multiagent_env

EVAL_SEED = 10_000


def evaluate(model: MADDPG, env_id: str, env_kwargs: dict[str, Any], n_episodes: int) -> dict[str, float]:
    """Episode-end metrics (means), team return and its worst decile over ``n_episodes`` random-start episodes."""
    kwargs = {**env_kwargs, "start": "random"}
    results, _ = evaluate_controllers(
        lambda: make_multiagent_env(env_id, **kwargs), [ModelController(model)], n_episodes, seed=EVAL_SEED
    )
    episodes = results["maddpg"]
    metrics = task_metrics(make_multiagent_env(env_id, **kwargs))
    summary = {key: float(np.mean([e[key] for e in episodes])) for key in (*metrics.values, "wall_hits", "return")}
    summary["return_worst_decile"] = worst_decile([e["return"] for e in episodes])
    # hazard events per episode, where the env reports them (uav_coverage_hazard_cpu_v1)
    summary.update({key: float(np.mean([e[key] for e in episodes])) for key in metrics.table_counts if key in episodes[0]})
    return summary


class LearningCurve(BaseCallback):
    """Evaluate every ``every`` timesteps and print a JSON line (and append it to ``out``)."""

    def __init__(self, env_id: str, env_kwargs: dict[str, Any], every: int, episodes: int, emit: Any) -> None:
        super().__init__()
        self.env_id, self.env_kwargs, self.every, self.episodes, self.emit = env_id, env_kwargs, every, episodes, emit
        self.next_eval = every
        self.start = time.perf_counter()

    def _on_step(self) -> bool:
        if self.num_timesteps >= self.next_eval:
            self.next_eval += self.every
            metrics = evaluate(self.model, self.env_id, self.env_kwargs, self.episodes)  # type: ignore[arg-type]
            logged = self.model.logger.name_to_value
            names = self.model.agent_names or []
            q_means = [logged[f"train/q_mean_{name}"] for name in names if f"train/q_mean_{name}" in logged]
            self.emit(
                dict(
                    kind="curve",
                    timesteps=self.num_timesteps,
                    seconds=time.perf_counter() - self.start,
                    saturation=logged.get("train/actor_saturation"),
                    critic_loss=logged.get("train/critic_loss"),
                    q_mean=float(np.mean(q_means)) if q_means else None,
                    **metrics,
                )
            )
        return True


#: Env variants measured with no gain (docs/results.md) and removed from the env; fb832a8 is the last commit with them.
LAST_COMMIT_WITH_REMOVED_VARIANTS = "fb832a8"
REMOVED_ENV_VARIANTS: dict[str, tuple[Any, ...] | None] = {
    "action_mode": ("waypoint",),
    "reward_mode": ("marginal", "team"),
    "hover_deadband": None,  # any value
    "coverage_edge": None,
}


def reject_removed_variants(env_kwargs: dict[str, Any]) -> None:
    """Exit with a message naming the commit to check out when ``env_kwargs`` asks for a removed env variant."""
    for name, values in REMOVED_ENV_VARIANTS.items():
        if name in env_kwargs and (values is None or env_kwargs[name] in values):
            commit = LAST_COMMIT_WITH_REMOVED_VARIANTS
            raise SystemExit(
                f"--env-kwargs: {name}={env_kwargs[name]!r} is a research variant that was removed from the env "
                f"(it measured no gain, see docs/results.md); commit {commit} is the last that has it: "
                f"git checkout {commit} (where the scripts of experiments/ were in benchmarks/)"
            )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument("--env", default="uav_coverage_cpu_v1", help="env id of sb3_maddpg's registry")
    parser.add_argument("--env-kwargs", type=json.loads, default={}, help="JSON dict of env parameters")
    parser.add_argument(
        "--algo-kwargs",
        type=json.loads,
        default={},
        help='JSON dict of MADDPG arguments; a learning rate "lin_X" decays linearly from X to 0',
    )
    parser.add_argument("--policy-kwargs", type=json.loads, default={}, help="JSON dict of policy arguments")
    parser.add_argument(
        "--noise-kwargs",
        type=json.loads,
        default=None,
        help="JSON dict of DecayingGaussianNoise arguments (sigma, final_sigma, decay); default MADDPG's own noise",
    )
    parser.add_argument("--policy", default="CnnPolicy")
    parser.add_argument("--timesteps", type=int, default=60_000)
    parser.add_argument("--n-envs", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--eval-every", type=int, default=10_000)
    parser.add_argument("--curve-episodes", type=int, default=5)
    parser.add_argument("--eval-episodes", type=int, default=20)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--out", help="append the JSON lines to this file")
    parser.add_argument("--save", help="save the trained model here")
    parser.add_argument("--tensorboard-log", help="TensorBoard folder")
    args = parser.parse_args(argv)
    reject_removed_variants(args.env_kwargs)
    th.set_num_threads(args.threads)

    def emit(record: dict[str, Any]) -> None:
        record = dict(
            env=args.env,
            seed=args.seed,
            env_kwargs=args.env_kwargs,
            algo_kwargs=args.algo_kwargs,
            policy_kwargs=args.policy_kwargs,
            **({"noise_kwargs": args.noise_kwargs} if args.noise_kwargs is not None else {}),
            **record,
        )
        line = json.dumps(record)
        print(line, flush=True)
        if args.out:
            os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
            with open(args.out, "a") as file:
                file.write(line + "\n")

    # The policy's extractor kwargs are a nested dict; anything else goes to the policy as given.
    policy_kwargs = dict(args.policy_kwargs)
    if "features_extractor_kwargs" in policy_kwargs:
        policy_kwargs["features_extractor_kwargs"] = dict(policy_kwargs["features_extractor_kwargs"])
    vec_env = make_multiagent_vec_env(
        lambda **kw: make_multiagent_env(args.env, **kw), n_envs=args.n_envs, seed=args.seed, env_kwargs=args.env_kwargs
    )
    # "lin_<value>" learning rates decay linearly to 0 over the run, as in RL Zoo's YAML files
    algo_kwargs = {
        key: linear_schedule(value.split("_", 1)[1]) if isinstance(value, str) and value.startswith("lin_") else value
        for key, value in args.algo_kwargs.items()
    }
    action_noise = None
    if args.noise_kwargs is not None:
        action_noise = DecayingGaussianNoise(np.zeros(vec_env.action_space.shape), **args.noise_kwargs)
    model = MADDPG(
        args.policy,
        vec_env,
        action_noise=action_noise,
        seed=args.seed,
        policy_kwargs=policy_kwargs,
        tensorboard_log=args.tensorboard_log,
        **algo_kwargs,
    )
    curve = LearningCurve(args.env, args.env_kwargs, args.eval_every, args.curve_episodes, emit)
    start = time.perf_counter()
    model.learn(args.timesteps, callback=curve)
    train_seconds = time.perf_counter() - start
    if args.save:
        model.save(args.save)
    final = evaluate(model, args.env, args.env_kwargs, args.eval_episodes)
    emit(dict(kind="final", timesteps=model.num_timesteps, train_seconds=train_seconds, **final))


if __name__ == "__main__":
    sys.exit(main())
