"""
CPU seconds per timestep of MADDPG training, measured side by side against another commit.

Two tasks:

- ``--task simple_spread`` (the default): MPE2's ``simple_spread_v3`` (3 agents, continuous actions), 8 environment
  copies, one update of batch 256 per VecEnv step, ``net_arch=[64, 64]``, with ``n_quantiles=25`` and
  ``n_quantiles=1``: the CPU configuration of ``docs/benchmarks.md``.
- ``--task uav``: the quick start's configuration, ``zoo_configs/maddpg.yml``'s ``uav_coverage_cpu_v1`` entry *as each
  commit ships it* (its env copies, batch, update schedule, policy and encoder), so that a ratio says how much
  faster the quick start trains. Two settings are changed so that the timed part is the steady state of training
  (updates of critics and actors): ``learning_starts`` is half the warm-up and ``critic_warmup_steps`` is 0.

With ``--reference REV`` the same measurement also runs on the code of the git revision REV (exported to a
temporary folder, package and env alike), alternating reference and current runs in one invocation, so that both see
the same machine and the same load; the table gives the ratios. Each measurement runs in its own process, pinned to
one core with one torch thread, and counts that process's CPU time (``time.process_time``), not wall time.

    python benchmarks/cpu_step_cost.py --reference 6888883 --rounds 3
    python benchmarks/cpu_step_cost.py --task uav --reference 901880e --rounds 3 --timesteps 2000 --warmup 1000
    python benchmarks/cpu_step_cost.py --task uav --reference 901880e --override 'b32={"batch_size": 32}'
    python benchmarks/cpu_step_cost.py --reference 6888883 --override 'compiled={"compile_quantile_loss": true}'
    python benchmarks/cpu_step_cost.py --timesteps 100000        # the current code only, long run
"""

import argparse
import datetime
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
N_COPIES = 8
UAV_ENV = "uav_coverage_cpu_v1"


def import_envs_from(code_dir: str) -> None:
    """Import ``sb3_maddpg_envs`` from ``code_dir/envs`` (an installed package maps that name to the working tree's)."""
    import importlib.util

    folder = os.path.join(code_dir, "envs")
    spec = importlib.util.spec_from_file_location(
        "sb3_maddpg_envs", os.path.join(folder, "__init__.py"), submodule_search_locations=[folder]
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["sb3_maddpg_envs"] = module
    spec.loader.exec_module(module)


def measure_uav(timesteps: int, warmup: int, override: dict | None = None) -> dict[str, float]:
    """
    The quick start's config of the code in the working directory, with the settings of ``override`` in place of the
    entry's (``policy_kwargs`` and ``features_extractor_kwargs`` merged key by key); CPU ms per timestep after ``warmup``.
    """
    import numpy as np
    import torch as th
    import yaml

    th.set_num_threads(1)
    from sb3_maddpg import MADDPG, make_multiagent_vec_env
    from sb3_maddpg.common.noise import DecayingGaussianNoise
    from sb3_maddpg.zoo.registry import make_multiagent_env

    with open("zoo_configs/maddpg.yml") as file:
        config = dict(yaml.safe_load(file)[UAV_ENV])
    env_kwargs = config.pop("env_kwargs", {})
    policy = config.pop("policy")
    # RL Zoo evaluates policy_kwargs strings as Python expressions; the YAML files hold only dict(...) literals
    policy_kwargs = eval(config.pop("policy_kwargs", "dict()"), {"dict": dict})  # noqa: S307
    override = dict(override or {})
    policy_override = override.pop("policy_kwargs", {})
    extractor_override = policy_override.pop("features_extractor_kwargs", {})
    policy_kwargs.update(policy_override)
    if extractor_override:
        policy_kwargs["features_extractor_kwargs"] = {
            **policy_kwargs.get("features_extractor_kwargs", {}),
            **extractor_override,
        }
    config.update(override)
    config.pop("n_timesteps")
    n_envs = config.pop("n_envs", 1)
    config.pop("noise_type")
    noise = {key: config.pop(f"noise_{key}") for key in ("std", "final_std", "decay")}
    venv = make_multiagent_vec_env(
        lambda **kw: make_multiagent_env(UAV_ENV, **kw), n_envs=n_envs, seed=0, env_kwargs=env_kwargs
    )
    action_noise = DecayingGaussianNoise(
        np.zeros(venv.action_space.shape), sigma=noise["std"], final_sigma=noise["final_std"], decay=noise["decay"]
    )
    config.update(learning_starts=warmup // 2, critic_warmup_steps=0)
    model = MADDPG(policy, venv, action_noise=action_noise, policy_kwargs=policy_kwargs, seed=0, **config)
    model.learn(warmup)
    cpu = time.process_time()
    model.learn(timesteps, reset_num_timesteps=False)
    cpu = time.process_time() - cpu
    return {"cpu_ms_per_timestep": cpu / timesteps * 1e3, "timesteps_per_cpu_s": timesteps / cpu, "n_envs": n_envs}


def measure(n_quantiles: int, timesteps: int, warmup: int, override: dict | None = None) -> dict[str, float]:
    """
    simple_spread: train past ``learning_starts``, then time ``timesteps`` more timesteps; CPU ms per VecEnv step.
    ``override``: MADDPG arguments over the benchmark's (e.g. ``{"compile_quantile_loss": true}``).
    """
    import torch as th

    th.set_num_threads(1)
    from sb3_maddpg import MADDPG, make_multiagent_vec_env
    from sb3_maddpg.zoo.registry import make_multiagent_env

    venv = make_multiagent_vec_env(lambda: make_multiagent_env("simple_spread_v3"), n_envs=N_COPIES, seed=0)
    model = MADDPG(
        "MlpPolicy",
        venv,
        batch_size=256,
        learning_starts=warmup // 2,
        train_freq=1,
        gradient_steps=1,
        policy_kwargs=dict(n_quantiles=n_quantiles, net_arch=[64, 64]),
        seed=0,
        **(override or {}),
    )
    model.learn(warmup)
    wall, cpu = time.perf_counter(), time.process_time()
    model.learn(timesteps, reset_num_timesteps=False)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    steps = timesteps / N_COPIES
    return {
        "cpu_ms_per_step": cpu / steps * 1e3,
        "wall_ms_per_step": wall / steps * 1e3,
        "timesteps_per_cpu_s": timesteps / cpu,
    }


def run_child(
    code_dir: str, n_quantiles: int, args: argparse.Namespace, core: int | None, override: str = "{}"
) -> dict[str, float]:
    """One measurement in a fresh process importing the package and the envs from ``code_dir``."""
    command = [sys.executable, os.path.abspath(__file__), "--child", str(n_quantiles), "--task", args.task]
    command += ["--override", override]
    command += ["--timesteps", str(args.timesteps), "--warmup", str(args.warmup)]
    if core is not None:
        command = ["taskset", "-c", str(core), *command]
    env = dict(os.environ, PYTHONPATH=code_dir, OMP_NUM_THREADS="1")
    out = subprocess.run(command, env=env, check=True, capture_output=True, text=True, cwd=code_dir).stdout
    return json.loads(out.strip().splitlines()[-1])


def export_revision(revision: str, folder: str) -> str:
    """The tracked files of ``revision`` in ``folder`` (git archive), for importing the reference code."""
    archive = subprocess.run(["git", "-C", REPO, "archive", revision], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", folder], input=archive, check=True)
    return folder


def versions_to_measure(args: argparse.Namespace, folder: str) -> dict[str, tuple[str, str]]:
    """
    Name -> (code folder, JSON settings) of every version to measure: the reference revision (exported to ``folder``)
    first when given, then the current code, then the current code with each ``--override``.
    """
    versions = {"current": (REPO, "{}")}
    for item in args.override:
        name, _, settings = item.partition("=")
        versions[f"current, {name}"] = (REPO, settings)
    if args.reference:
        versions = {f"reference {args.reference}": (export_revision(args.reference, folder), "{}"), **versions}
    return versions


def print_header(args: argparse.Namespace, task: str) -> int | None:
    """Print the date, machine, task and load; return the core to pin measurements to (None: no pinning)."""
    print(
        f"date: {datetime.date.today().isoformat()}, machine: {platform.node()} ({platform.processor() or platform.machine()})"
    )
    print(task)
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    return None if args.core < 0 else args.core


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--reference", help="git revision to measure in the same run, alternating with this code")
    parser.add_argument("--rounds", type=int, default=3, help="measurements per code version and configuration")
    parser.add_argument("--timesteps", type=int, default=8000, help="timed timesteps per measurement")
    parser.add_argument("--warmup", type=int, default=1600, help="timesteps before timing (half of them random)")
    parser.add_argument("--core", type=int, default=0, help="CPU core to pin each measurement to (-1: none)")
    parser.add_argument("--task", choices=("simple_spread", "uav"), default="simple_spread")
    parser.add_argument(
        "--override",
        action="append",
        default=[],
        help="NAME=JSON, settings over the current code's (uav: over its YAML entry; simple_spread: MADDPG arguments), "
        "measured as one more version (repeatable)",
    )
    parser.add_argument("--child", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child is not None:
        import_envs_from(os.getcwd())
        override = json.loads(args.override[0]) if args.override else None
        if args.task == "uav":
            print(json.dumps(measure_uav(args.timesteps, args.warmup, override)))
        else:
            print(json.dumps(measure(args.child, args.timesteps, args.warmup, override)))
        return
    if args.task == "uav":
        compare_uav(args)
        return

    core = print_header(
        args, f"simple_spread_v3, {N_COPIES} copies, batch 256, one update per VecEnv step, {args.timesteps} timed timesteps"
    )
    with tempfile.TemporaryDirectory() as folder:
        versions = versions_to_measure(args, folder)
        results: dict[tuple[str, int], list[dict[str, float]]] = {}
        for _ in range(args.rounds):
            for n_quantiles in (25, 1):
                for name, (code_dir, override) in versions.items():
                    result = run_child(code_dir, n_quantiles, args, core, override)
                    results.setdefault((name, n_quantiles), []).append(result)
                    print(
                        f"  {name:>20s} n_quantiles={n_quantiles:2d}: {result['cpu_ms_per_step']:.2f} CPU ms/step", flush=True
                    )
    print(f"load average after: {os.getloadavg()[0]:.2f}")

    def median(name: str, n_quantiles: int) -> float:
        return statistics.median(r["cpu_ms_per_step"] for r in results[(name, n_quantiles)])

    print()
    print("| code | n_quantiles | CPU ms per VecEnv step (median) | timesteps per CPU second |")
    print("|---|---:|---:|---:|")
    for name in versions:
        for n_quantiles in (25, 1):
            ms = median(name, n_quantiles)
            print(f"| {name} | {n_quantiles} | {ms:.2f} | {N_COPIES / ms * 1e3:,.0f} |")
    print()
    for name in versions:
        print(f"{name}: n_quantiles=25 step / n_quantiles=1 step = {median(name, 25) / median(name, 1):.2f}")
    if args.reference:
        reference = next(iter(versions))
        for name in list(versions)[1:]:
            for n_quantiles in (25, 1):
                speedup = median(reference, n_quantiles) / median(name, n_quantiles)
                print(f"n_quantiles={n_quantiles}: timesteps per CPU second, {name} / reference = {speedup:.2f}")


def compare_uav(args: argparse.Namespace) -> None:
    """The quick start's config of each code version, alternating versions in each round."""
    core = print_header(
        args, f"{UAV_ENV}, each version's zoo_configs/maddpg.yml entry, {args.timesteps} timed timesteps after {args.warmup}"
    )
    with tempfile.TemporaryDirectory() as folder:
        versions = versions_to_measure(args, folder)
        results: dict[str, list[dict[str, float]]] = {}
        for _ in range(args.rounds):
            for name, (code_dir, override) in versions.items():
                result = run_child(code_dir, 0, args, core, override)
                results.setdefault(name, []).append(result)
                print(f"  {name:>20s}: {result['cpu_ms_per_timestep']:.2f} CPU ms/timestep", flush=True)
    print(f"load average after: {os.getloadavg()[0]:.2f}")

    def median(name: str) -> float:
        return statistics.median(r["cpu_ms_per_timestep"] for r in results[name])

    print()
    print("| code | env copies | CPU ms per timestep (median) | timesteps per CPU second |")
    print("|---|---:|---:|---:|")
    for name in versions:
        print(f"| {name} | {results[name][0]['n_envs']} | {median(name):.2f} | {1e3 / median(name):,.1f} |")
    if args.reference:
        reference = next(iter(versions))
        print()
        for name in list(versions)[1:]:
            print(f"timesteps per CPU second, {name} / reference = {median(reference) / median(name):.2f}")


if __name__ == "__main__":
    main()
