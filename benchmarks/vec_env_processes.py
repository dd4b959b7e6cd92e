"""Speed-up of running the UAV env's copies in worker processes (``vec_env_cls="subproc"``) over one process.

Times ``VecEnv.step`` with uniform random actions (drawn beforehand) on ``make_multiagent_vec_env(uav_coverage_v0,
n_envs=COPIES)`` with the copies in this process and in 2 worker processes, at ``obs_size`` 16 and 80 (the default
configuration otherwise: N = 6, K = 256). The figure to read is the ratio of the two, measured in one run: absolute
rates depend on whatever else the machine is doing, which is recorded as its load average.

Usage::

    python benchmarks/vec_env_processes.py             # print a markdown table
    python benchmarks/vec_env_processes.py --write     # also update its section of docs/benchmarks.md
"""

from __future__ import annotations

import argparse
import datetime
import os
import statistics
import sys
import time

import numpy as np
from env_throughput import machine, write_section

from sb3_maddpg import make_multiagent_vec_env
from sb3_maddpg_envs import uav_coverage_v0

SECTION = "Environment copies in worker processes"


def vec_steps_per_second(obs_size: int, copies: int, processes: int, steps: int, seed: int) -> float:
    """
    VecEnv steps per second (one step = one joint step of every copy), resets included.

    :param obs_size: observation side in pixels
    :param copies: environment copies
    :param processes: 1 (copies in this process) or the number of worker processes
    :param steps: VecEnv steps to time, after 20 untimed ones
    :param seed: seed of the copies and of the actions
    """
    kwargs = {"vec_env_cls": "subproc", "n_processes": processes} if processes > 1 else {}
    env = make_multiagent_vec_env(
        uav_coverage_v0.parallel_env, n_envs=copies, seed=seed, env_kwargs={"obs_size": obs_size}, **kwargs
    )
    rng = np.random.default_rng(seed)
    actions = rng.random((steps + 20, env.num_envs, 2), dtype=np.float32)
    env.reset()
    for t in range(20):
        env.step(actions[t])
    start = time.perf_counter()
    for t in range(20, steps + 20):
        env.step(actions[t])
    rate = steps / (time.perf_counter() - start)
    env.close()
    return rate


def run(copies: int, steps: int, repeats: int) -> list[tuple[int, float, float]]:
    """Rows (obs_size, median VecEnv steps/s with 1 process, with 2 processes); runs alternate between the two."""
    rows = []
    for obs_size in (16, 80):
        rates: dict[int, list[float]] = {1: [], 2: []}
        for repeat in range(repeats):
            for processes in (1, 2):
                rates[processes].append(vec_steps_per_second(obs_size, copies, processes, steps, seed=repeat))
        rows.append((obs_size, statistics.median(rates[1]), statistics.median(rates[2])))
    return rows


def table(rows: list[tuple[int, float, float]], copies: int) -> str:
    lines = [
        "| obs_size | 1 process: VecEnv steps/s | 2 processes: VecEnv steps/s | speed-up (2 / 1) |",
        "|---:|---:|---:|---:|",
    ]
    for obs_size, one, two in rows:
        lines.append(f"| {obs_size} | {one:,.0f} ({one * copies:,.0f} joint steps/s) | {two:,.0f} | {two / one:.2f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--copies", type=int, default=8, help="environment copies (n_envs)")
    parser.add_argument("--steps", type=int, default=500, help="VecEnv steps per timed run")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs per cell, alternating 1 and 2 processes")
    parser.add_argument("--write", action="store_true", help=f"update the '{SECTION}' section of docs/benchmarks.md")
    args = parser.parse_args(argv)

    load_before = os.getloadavg()[0]
    rows = run(args.copies, args.steps, args.repeats)
    load_after = os.getloadavg()[0]
    result = table(rows, args.copies)
    print(result)
    print(f"load average (1 min) before / after: {load_before:.2f} / {load_after:.2f} on {os.cpu_count()} cores")
    if args.write:
        command = "python benchmarks/vec_env_processes.py " + " ".join(sys.argv[1:] if argv is None else argv)
        text = (
            f"`make_multiagent_vec_env(uav_coverage_v0, n_envs={args.copies}, env_kwargs={{'obs_size': S}})` with the "
            "copies in one process and with `vec_env_cls='subproc', n_processes=2`, random actions, median of "
            f"{args.repeats} runs of {args.steps} VecEnv steps each (one VecEnv step = one joint step of all "
            f"{args.copies} copies, resets included).\n\n"
            f"- date: {datetime.date.today().isoformat()}\n"
            f"- machine: {machine()}\n"
            f"- load: 1-minute load average {load_before:.2f} before and {load_after:.2f} after the run, on "
            f"{os.cpu_count()} cores\n"
            f"- command: `{command.strip()}`\n\n"
            f"{result}\n"
        )
        write_section(text, title=SECTION)
        print("updated docs/benchmarks.md")


if __name__ == "__main__":
    main()
