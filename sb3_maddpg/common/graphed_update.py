"""A gradient step captured as CUDA graphs and replayed (``MADDPG(..., cuda_graph=True)``, MATD3 alike).

One update of all agents (critics, actors, soft target updates) is a few hundred small kernels; on a GPU their
launch overhead, not their arithmetic, sets the time of an update at the report's sizes. A CUDA graph records the
kernels of one step once and replays them with one launch (PyTorch's "whole network capture",
https://pytorch.org/docs/stable/notes/cuda.html#cuda-graphs). PyTorch has no ready-made wrapper for a training step
with two optimizers and target networks, so this module holds the recipe:

- the batch is copied into static tensors, the inputs of the recorded kernels;
- each kind of step (critics only during the warm-up or between delayed actor updates; critics and targets;
  critics, actors and targets) is run eagerly a few times on a side stream, then captured on its next use;
- the optimizers are made capturable (their step counters and learning rates live on the device), so the
  recorded optimizer steps stay correct when replayed, and a learning-rate schedule writes into the tensor.

Each step does exactly what the eager step does on the same batch (the algorithm's step function is the code
recorded); ``capture=False`` runs that code on the static tensors with the capturable optimizers, without recording,
which is how it is checked against the eager update on a machine without CUDA. The module knows no algorithm: it
takes the step function and the optimizers it steps.
"""

from collections.abc import Callable, Iterable
from typing import Any, NamedTuple

import torch as th

from sb3_maddpg.common.buffers import MultiAgentReplayBufferSamples

# A step function: (batch, *flags) -> a NamedTuple of tensors (or None where a flag skipped that part of the step)
StepFunction = Callable[..., NamedTuple]


def set_learning_rate(optimizer: th.optim.Optimizer, learning_rate: float) -> None:
    """
    Set an optimizer's learning rate, as SB3's ``update_learning_rate``, but in place where it is a tensor (the
    capturable optimizers of a recorded step, whose replays read the tensor).

    :param optimizer: the optimizer
    :param learning_rate: the new learning rate
    """
    for param_group in optimizer.param_groups:
        if isinstance(param_group["lr"], th.Tensor):
            param_group["lr"].fill_(learning_rate)
        else:
            param_group["lr"] = learning_rate


def make_capturable(optimizer: th.optim.Optimizer) -> None:
    """
    Switch an optimizer, in place, to the form a CUDA graph can record: ``capturable=True`` where the optimizer has
    that option (Adam, AdamW, ...), the learning rate as a tensor on the parameters' device, and any existing step
    counters on that device. The optimizer's arithmetic is unchanged.

    :param optimizer: the optimizer (its parameters already on their device)
    """
    for group in optimizer.param_groups:
        device = group["params"][0].device
        if "capturable" in group:
            group["capturable"] = True
        if not isinstance(group["lr"], th.Tensor):
            group["lr"] = th.tensor(float(group["lr"]), dtype=th.float32, device=device)
        for param in group["params"]:
            state = optimizer.state.get(param, {})
            if isinstance(state.get("step"), th.Tensor):
                state["step"] = state["step"].to(device=param.device, dtype=th.float32)


class GraphedUpdate:
    """
    Runs a gradient step function from static batch tensors, recorded as one CUDA graph per kind of step (per value
    of its flags and batch shape).

    :param step: the eager step, ``step(batch, *flags)``, returning a NamedTuple of tensors (None for the parts the
        flags skipped); it must not wait for the device or branch on a tensor's value
    :param optimizers: the optimizers the step takes steps with (made capturable here)
    :param capture: record and replay CUDA graphs; False runs the same code eagerly on the static tensors
    :param warmup_steps: eager steps of each kind on a side stream before it is recorded (PyTorch's recipe: lets
        autograd, cuDNN and the allocator settle before capture); they are real updates on the real batches
    """

    def __init__(
        self,
        step: StepFunction,
        optimizers: Iterable[th.optim.Optimizer],
        capture: bool = True,
        warmup_steps: int = 3,
    ) -> None:
        if capture and not th.cuda.is_available():
            raise ValueError("CUDA graphs need CUDA, which is not available here; use capture=False or cuda_graph=False")
        self.step_function = step
        self.capture = capture
        self.warmup_steps = warmup_steps
        for optimizer in optimizers:
            make_capturable(optimizer)
        self._static: dict[tuple, MultiAgentReplayBufferSamples] = {}
        self._graphs: dict[tuple, tuple[th.cuda.CUDAGraph, NamedTuple]] = {}
        self._eager_steps: dict[tuple, int] = {}

    @property
    def n_graphs(self) -> int:
        """How many graphs have been recorded (one per kind of step and batch shape)."""
        return len(self._graphs)

    def _load(self, replay_data: MultiAgentReplayBufferSamples) -> tuple[tuple, MultiAgentReplayBufferSamples]:
        """Copy a batch into the static tensors of its shape (allocated on first use, on the batch's device)."""
        shape_key = tuple((tuple(t.shape), t.dtype) for t in replay_data)
        static = self._static.get(shape_key)
        if static is None:
            static = type(replay_data)(*(th.empty_like(t) for t in replay_data))
            self._static[shape_key] = static
        for target, value in zip(static, replay_data, strict=True):
            target.copy_(value, non_blocking=True)
        return shape_key, static

    def step(self, replay_data: MultiAgentReplayBufferSamples, *flags: bool) -> Any:
        """
        One gradient step on ``replay_data``: the step function's.

        :param replay_data: the batch
        :param flags: the step function's flags (e.g. whether to update the actors, the targets)
        :return: the step's statistics (fresh tensors, safe to keep)
        """
        shape_key, batch = self._load(replay_data)
        if not self.capture:
            return self.step_function(batch, *flags)
        key = (shape_key, *flags)
        recorded = self._graphs.get(key)
        if recorded is None:
            done = self._eager_steps.get(key, 0)
            if done < self.warmup_steps:
                self._eager_steps[key] = done + 1
                side_stream = th.cuda.Stream()
                side_stream.wait_stream(th.cuda.current_stream())
                with th.cuda.stream(side_stream):
                    stats = self.step_function(batch, *flags)
                th.cuda.current_stream().wait_stream(side_stream)
                return stats
            graph = th.cuda.CUDAGraph()
            with th.cuda.graph(graph):
                outputs = self.step_function(batch, *flags)
            recorded = self._graphs[key] = (graph, outputs)
        graph, outputs = recorded
        graph.replay()  # capture only records: this replay is the step's computation, also right after capture
        return type(outputs)(*(None if output is None else output.clone() for output in outputs))
