"""
Flushing denormal floats to zero while a model trains on CPU.

Adam's moving averages of a weight whose gradient is always 0 (a ReLU unit that never fires, a critic input that a
dead feature leaves at 0) shrink by beta1 = 0.9 at every step and reach the float32 denormal range (below 1.2e-38)
after about 800 steps; BatchNorm's running statistics of such a channel do the same. x86 CPUs compute with denormal
operands through a slow microcode path (a vectorised multiply: 16 times slower on the project's Intel Xeon), so a
few tens of thousands of them in the optimizer's state slow every update: on the UAV quick start's networks the
fused Adam step of the critics took 2.5 ms on average against 1.2 ms for its median (docs/benchmarks.md, "Denormal
floats").

PyTorch can set the CPU's flush-to-zero and denormals-are-zero modes (``torch.set_flush_denormal``), as TensorFlow
does by default, but has no way to read them back; ``flush_denormal_enabled`` tells by computing with a denormal
number, so that ``flushed_denormals`` can restore what it found. The modes belong to a thread: they apply to the
thread that trains (where PyTorch also runs the backward pass of CPU tensors), not to the worker threads of
``torch.set_num_threads(n > 1)``.
"""

import contextlib
from collections.abc import Iterator

import torch as th

# The largest float32 denormal is about 1.18e-38: 1e-39 is one, and any product with it is 0 once they are flushed
_DENORMAL = 1e-39


def flush_denormal_enabled() -> bool:
    """Whether this thread's CPU flushes denormal floats to zero (``torch.set_flush_denormal(True)`` in effect)."""
    return th.tensor([_DENORMAL], dtype=th.float32).mul_(1.0).item() == 0.0


@contextlib.contextmanager
def flushed_denormals(enabled: bool = True) -> Iterator[None]:
    """
    Flush denormal floats to zero on this thread's CPU for the duration of the block, then leave the mode as it was.

    :param enabled: False makes the block change nothing
    """
    # Where the CPU cannot flush denormals (set_flush_denormal returns False), nothing changes
    turned_on = enabled and not flush_denormal_enabled() and th.set_flush_denormal(True)
    try:
        yield
    finally:
        if turned_on:
            th.set_flush_denormal(False)
