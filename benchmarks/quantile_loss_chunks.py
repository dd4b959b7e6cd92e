"""
Time of the fused quantile Huber loss with its gradient on CPU for several row-chunk sizes (``_CHUNK_PAIRS``), at
the shape of the CPU step-cost benchmark: batch 256, 3 agents, 25 x 25 quantile pairs. One torch thread; median
of ``--repeats`` timings of ``--calls`` calls each.

    taskset -c 0 python benchmarks/quantile_loss_chunks.py
"""

import argparse
import platform
import statistics
import time

import torch as th

from sb3_maddpg.common import distributional


def time_loss(current: th.Tensor, target: th.Tensor, calls: int) -> float:
    """Milliseconds per loss + backward call."""
    for _ in range(20):
        distributional.quantile_huber_loss(current, target).sum().backward()
    start = time.perf_counter()
    for _ in range(calls):
        distributional.quantile_huber_loss(current, target).sum().backward()
    return (time.perf_counter() - start) / calls * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument("--batch", type=int, default=256)
    parser.add_argument("--agents", type=int, default=3)
    parser.add_argument("--quantiles", type=int, default=25)
    parser.add_argument("--calls", type=int, default=500)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    th.set_num_threads(1)
    current = th.randn(args.batch, args.agents, args.quantiles, requires_grad=True)
    target = th.randn(args.batch, args.agents, args.quantiles)
    pairs = args.batch * args.agents * args.quantiles**2
    default = distributional._CHUNK_PAIRS
    print(f"machine: {platform.processor() or platform.machine()}, torch {th.__version__}, one thread")
    print(f"shape ({args.batch}, {args.agents}, {args.quantiles}): {pairs} pairs in all")
    print("| pairs per chunk | chunks | ms per loss + gradient (median) |")
    print("|---:|---:|---:|")
    for chunk in (pairs, 1 << 20, 1 << 18, 1 << 17, 1 << 16, 1 << 15):
        distributional._CHUNK_PAIRS = chunk
        rows_per_chunk = max(1, chunk // args.quantiles**2)
        n_chunks = -(-(args.batch * args.agents) // rows_per_chunk)
        times = [time_loss(current, target, args.calls) for _ in range(args.repeats)]
        label = f"{chunk}" + (" (default)" if chunk == default else "") + (" (one piece)" if chunk == pairs else "")
        print(f"| {label} | {n_chunks} | {statistics.median(times):.3f} |")
    distributional._CHUNK_PAIRS = default


if __name__ == "__main__":
    main()
