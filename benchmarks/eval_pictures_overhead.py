"""
The share of a training run spent drawing its evaluations for TensorBoard (the coverage heat map, and with --eval-video
the episode's video): ``train`` is run as the command line runs it, and the time every ``EvalTensorBoardCallback``
spent playing and drawing its pictured episodes is set against the run's wall time.

    taskset -c 1 python benchmarks/eval_pictures_overhead.py -n 5000 --eval-freq 2500
    taskset -c 1 python benchmarks/eval_pictures_overhead.py -n 5000 --eval-freq 2500 --eval-video
"""

import argparse
import os
import tempfile
import time

import torch as th

from sb3_maddpg.__main__ import main
from sb3_maddpg.common import eval_tensorboard


def measure(env: str, n_timesteps: int, eval_freq: int, eval_episodes: int, video: bool) -> dict[str, float]:
    """
    :return: the run's wall time, the drawing time and the number of evaluations
    """
    callbacks: list[eval_tensorboard.EvalTensorBoardCallback] = []
    init = eval_tensorboard.EvalTensorBoardCallback.__init__

    def keep(self: eval_tensorboard.EvalTensorBoardCallback, *args: object, **kwargs: object) -> None:
        init(self, *args, **kwargs)
        callbacks.append(self)

    eval_tensorboard.EvalTensorBoardCallback.__init__ = keep  # type: ignore[method-assign]
    cwd = os.getcwd()
    with tempfile.TemporaryDirectory() as folder:
        os.chdir(folder)
        argv = ["train", "--env", env, "-n", str(n_timesteps), "--eval-freq", str(eval_freq)]
        argv += ["--eval-episodes", str(eval_episodes), "-tb", "tb", "--seed", "0", "--num-threads", "1"]
        try:
            start = time.perf_counter()
            assert main([*argv, *(["--eval-video"] if video else [])]) == 0
            wall = time.perf_counter() - start
        finally:
            os.chdir(cwd)
            eval_tensorboard.EvalTensorBoardCallback.__init__ = init  # type: ignore[method-assign]
    drawing = sum(callback.drawing_seconds for callback in callbacks)
    return {"wall_s": wall, "drawing_s": drawing, "evaluations": n_timesteps // eval_freq}


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--env", default="uav_coverage_cpu_v1")
    parser.add_argument("-n", "--n-timesteps", type=int, default=5000)
    parser.add_argument("--eval-freq", type=int, default=2500)
    parser.add_argument("--eval-episodes", type=int, default=2)
    parser.add_argument("--eval-video", action="store_true")
    args = parser.parse_args()
    th.set_num_threads(1)
    result = measure(args.env, args.n_timesteps, args.eval_freq, args.eval_episodes, args.eval_video)
    share = 100 * result["drawing_s"] / result["wall_s"]
    print(
        f"{args.env} -n {args.n_timesteps} --eval-freq {args.eval_freq}{' --eval-video' if args.eval_video else ''}: "
        f"{result['evaluations']} evaluations, drawing {result['drawing_s']:.2f} s of {result['wall_s']:.1f} s "
        f"({share:.2f} %), {result['drawing_s'] / max(result['evaluations'], 1):.2f} s per evaluation"
    )
