"""Throughput of the UAV coverage environment with random actions, in one process.

Measures joint steps per second (all N agents act once) and agent-steps per second (N times that) of:

- the PettingZoo ``ParallelEnv`` at the default configuration (N = 6, K = 256, 3 x 80 x 80 observations),
- the same with ``obs_size=16`` (1 pixel per cell),
- the numpy core alone at the default configuration (no dicts, no infos).

Usage::

    python benchmarks/env_throughput.py             # print a markdown table
    python benchmarks/env_throughput.py --write     # also update the "Environment throughput" section of docs/benchmarks.md
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import re
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from sb3_maddpg_envs import uav_coverage_v0
from sb3_maddpg_envs.uav_coverage.core import UAVCoverageCore

SECTION = "Environment throughput"
DOCS = Path(__file__).resolve().parents[1] / "docs" / "benchmarks.md"


def time_parallel_env(steps: int, seed: int, **kwargs) -> float:
    """
    Joint steps per second of the ParallelEnv over ``steps`` steps with uniform random actions (resets included).

    :param steps: joint steps to time
    :param seed: seed of the env and of the actions
    :param kwargs: env parameters
    """
    env = uav_coverage_v0.parallel_env(**kwargs)
    rng = np.random.default_rng(seed)
    actions = rng.random((steps, env.core.n_uavs, 2), dtype=np.float32)  # drawn beforehand: we time the env only
    env.reset(seed=seed)
    agents = env.possible_agents
    start = time.perf_counter()
    for t in range(steps):
        if not env.agents:
            env.reset()
        env.step(dict(zip(agents, actions[t], strict=True)))
    return steps / (time.perf_counter() - start)


def time_core(steps: int, seed: int, **kwargs) -> float:
    """
    Joint steps per second of the numpy core alone (same loop, no PettingZoo dicts or infos).

    :param steps: joint steps to time
    :param seed: seed of the env and of the actions
    :param kwargs: core parameters
    """
    core = UAVCoverageCore(**kwargs)
    rng = np.random.default_rng(seed)
    actions = rng.random((steps, core.n_uavs, 2))
    core.reset(seed=seed)
    start = time.perf_counter()
    for t in range(steps):
        _, _, terminated, truncated = core.step(actions[t])
        if terminated or truncated:
            core.reset()
    return steps / (time.perf_counter() - start)


def median_rate(fn: Callable[..., float], repeats: int, steps: int, **kwargs) -> float:
    """Median over ``repeats`` timed runs (the first run also warms caches up)."""
    return statistics.median(fn(steps, seed=i, **kwargs) for i in range(repeats))


def machine() -> str:
    """CPU model and number of cores, from /proc/cpuinfo where it exists."""
    model = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as file:
            for line in file:
                if line.startswith("model name"):
                    model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return f"{model}, {os.cpu_count()} cores, Python {platform.python_version()}, numpy {np.__version__}"


def run(steps: int, repeats: int) -> list[tuple[str, str, int, float]]:
    """Rows (what, configuration, N, joint steps/s)."""
    n = 6
    return [
        ("ParallelEnv", "defaults (N=6, K=256, obs 3x80x80)", n, median_rate(time_parallel_env, repeats, steps)),
        ("ParallelEnv", "obs_size=16 (obs 3x16x16)", n, median_rate(time_parallel_env, repeats, steps, obs_size=16)),
        ("numpy core", "defaults (N=6, K=256, obs 3x80x80)", n, median_rate(time_core, repeats, steps)),
    ]


def table(rows: list[tuple[str, str, int, float]]) -> str:
    lines = ["| what | configuration | joint steps/s | agent-steps/s |", "|---|---|---:|---:|"]
    for what, config, n, rate in rows:
        lines.append(f"| {what} | {config} | {rate:,.0f} | {rate * n:,.0f} |")
    return "\n".join(lines)


def write_section(text: str, path: Path = DOCS, title: str = SECTION) -> None:
    """Replace (or append) the ``## <title>`` section of ``path``, leaving the other sections alone."""
    content = path.read_text() if path.exists() else "# Benchmarks\n"
    section = f"## {title}\n\n{text.strip()}\n"
    pattern = re.compile(rf"^## {re.escape(title)}\n.*?(?=^## |\Z)", re.MULTILINE | re.DOTALL)
    if pattern.search(content):
        content = pattern.sub(lambda _: section + "\n", content, count=1).rstrip() + "\n"
    else:
        content = content.rstrip() + "\n\n" + section
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(content)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=3000, help="joint steps per timed run (300 steps = one episode)")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs per row; the median is reported")
    parser.add_argument("--write", action="store_true", help=f"update the '{SECTION}' section of {DOCS.name}")
    args = parser.parse_args(argv)

    rows = run(args.steps, args.repeats)
    result = table(rows)
    print(result)
    if args.write:
        command = "python benchmarks/env_throughput.py " + " ".join(sys.argv[1:] if argv is None else argv)
        text = (
            "Random actions, one process, median of "
            f"{args.repeats} runs of {args.steps} joint steps (episode resets included). "
            "A joint step is one step of all N agents; agent-steps/s = N x joint steps/s.\n\n"
            f"- date: {datetime.date.today().isoformat()}\n"
            f"- machine: {machine()}\n"
            f"- command: `{command.strip()}`\n\n"
            f"{result}\n"
        )
        write_section(text)
        print(f"updated {DOCS}")


if __name__ == "__main__":
    main()
