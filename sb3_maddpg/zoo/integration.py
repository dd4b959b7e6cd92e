"""
Register the library's algorithms and the multi-agent envs into RL Zoo's own machinery, then run its ``train``, ``enjoy``,
``record_video`` and Optuna code unchanged.

RL Zoo reads its algorithms from ``rl_zoo3.utils.ALGOS``, its samplers from ``rl_zoo3.hyperparams_opt``, builds
training envs in ``ExperimentManager.create_envs`` and test envs with ``create_test_env``. :func:`register_with_rl_zoo`
adds the library's algorithms (``sb3_maddpg.algorithms``) to the first two and points ``rl_zoo3.train`` and
``rl_zoo3.enjoy`` at the multi-agent versions of the last two; single-agent envs and algorithms keep working as before.
"""

import functools
import importlib
import signal
import threading
from typing import Any

_REGISTERED = False


def register_with_rl_zoo() -> None:
    """
    Make ``--algo maddpg``, ``--algo matd3`` and the multi-agent env ids available to RL Zoo (idempotent).
    """
    global _REGISTERED
    if _REGISTERED:
        return
    import rl_zoo3.hyperparams_opt
    import rl_zoo3.train
    import rl_zoo3.utils

    from sb3_maddpg.algorithms import ALGORITHM_NAMES, algorithm_class
    from sb3_maddpg.zoo.exp_manager import MultiAgentExperimentManager
    from sb3_maddpg.zoo.hyperparams_opt import convert_maddpg_params, sample_maddpg_params
    from sb3_maddpg.zoo.registry import load_env_packages

    # the env ids, the installed task packages' included, into Gymnasium's registry, where RL Zoo checks --env
    load_env_packages()

    # One dict object shared by rl_zoo3.utils, .train, .enjoy and .exp_manager: adding a key is seen everywhere.
    for name in ALGORITHM_NAMES:
        rl_zoo3.utils.ALGOS[name] = algorithm_class(name)
        # The library's algorithms take MADDPG's arguments: one search space for all
        rl_zoo3.hyperparams_opt.HYPERPARAMS_SAMPLER[name] = sample_maddpg_params
        rl_zoo3.hyperparams_opt.HYPERPARAMS_CONVERTER[name] = convert_maddpg_params
    # `train()` looks ExperimentManager up in its module's globals when it runs.
    rl_zoo3.train.ExperimentManager = MultiAgentExperimentManager  # type: ignore[misc]
    _REGISTERED = True


def _patch_enjoy() -> Any:
    """
    Import RL Zoo's enjoy module (it needs ``requests`` through its Hugging Face helpers, so only when used) and make
    its ``create_test_env`` build multi-agent envs.

    :return: the module
    """
    enjoy_module = importlib.import_module("rl_zoo3.enjoy")
    from sb3_maddpg.zoo.vec_envs import create_multiagent_test_env

    if not isinstance(enjoy_module.create_test_env, functools.partial):
        import rl_zoo3.utils

        enjoy_module.create_test_env = functools.partial(create_multiagent_test_env, _fallback=rl_zoo3.utils.create_test_env)
    return enjoy_module


def run_train(argv: list[str], eval_images: bool = True, eval_video: bool = False) -> None:
    """
    RL Zoo's ``train`` (also ``-optimize``) with the given command-line arguments.

    :param argv: arguments as for ``python -m rl_zoo3.train``
    :param eval_images: with ``-tb``, draw the task's picture after each evaluation (on the UAV envs the coverage heat
        map), where the task can draw itself
    :param eval_video: with ``-tb``, record a video of one episode after each evaluation, where the task can draw itself
    :raises TrainingStopped: after the final save, when SIGTERM or an env worker process that ended stopped the run
    """
    import sys

    register_with_rl_zoo()
    import rl_zoo3.train

    from sb3_maddpg.zoo.registry import EXIT_SIGTERM, TrainingStopped
    from sb3_maddpg.zoo.storage import mask_password

    saved, saved_orig = sys.argv, getattr(sys, "orig_argv", None)
    sys.argv = ["sb3_maddpg train", *argv]
    if saved_orig is not None:
        # RL Zoo writes the command line into command.txt and the study: without the --storage password
        sys.orig_argv = [mask_password(arg) for arg in saved_orig]
    # SIGTERM (what SLURM and most schedulers send at a time limit) stops training as Ctrl-C does: RL Zoo then saves
    # the model (and, with --save-replay-buffer, the replay buffer) before the process ends, with EXIT_SIGTERM.
    received: list[int] = []

    def stop(signum: int, frame: Any) -> None:
        received.append(signum)
        raise KeyboardInterrupt

    in_main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, stop) if in_main_thread else None
    manager = rl_zoo3.train.ExperimentManager
    # This run's picture settings, on a subclass that train() builds: the registered class is left as it is
    settings = {"eval_images": eval_images, "eval_video": eval_video}
    rl_zoo3.train.ExperimentManager = type(manager.__name__, (manager,), settings)  # type: ignore[misc]
    try:
        rl_zoo3.train.train()
    finally:
        rl_zoo3.train.ExperimentManager = manager  # type: ignore[misc]
        sys.argv = saved
        if saved_orig is not None:
            sys.orig_argv = saved_orig
        if in_main_thread:
            signal.signal(signal.SIGTERM, signal.SIG_DFL if previous is None else previous)
    if received:
        raise TrainingStopped("stopped by SIGTERM before the end of the run; what was done is saved", EXIT_SIGTERM)


def run_enjoy(argv: list[str]) -> None:
    """
    RL Zoo's ``enjoy`` with the given command-line arguments.

    :param argv: arguments as for ``python -m rl_zoo3.enjoy``
    """
    import sys

    register_with_rl_zoo()
    enjoy_module = _patch_enjoy()
    saved = sys.argv
    sys.argv = ["sb3_maddpg enjoy", *argv]
    try:
        enjoy_module.enjoy()
    finally:
        sys.argv = saved


def run_record_video(argv: list[str]) -> None:
    """
    RL Zoo's ``record_video`` script (a video of ``-n`` timesteps of a trained agent, written with SB3's
    ``VecVideoRecorder`` to ``-o`` or ``<run>/videos``) with the given command-line arguments.

    :param argv: arguments as for ``python -m rl_zoo3.record_video``
    """
    import runpy
    import sys

    import rl_zoo3.utils

    from sb3_maddpg.zoo.vec_envs import create_multiagent_test_env

    register_with_rl_zoo()
    saved_argv, saved_create = sys.argv, rl_zoo3.utils.create_test_env
    # The script is a `__main__` block that imports create_test_env from rl_zoo3.utils when it runs
    rl_zoo3.utils.create_test_env = functools.partial(create_multiagent_test_env, _fallback=saved_create)
    sys.argv = ["sb3_maddpg record-video", *argv]
    try:
        runpy.run_module("rl_zoo3.record_video", run_name="__main__")
    finally:
        sys.argv, rl_zoo3.utils.create_test_env = saved_argv, saved_create
