"""
A replay buffer read from a file: the check that it is whole before a model trains on it (``load_replay_buffer``).
"""

from typing import Any

import numpy as np
import torch as th


def check_loaded_buffer(buffer: Any, name: str) -> None:
    """
    Check that a buffer read from a file is whole: its counters and arrays agree with each other, and its rewards,
    actions and (float) observations are finite. A damaged or edited file would otherwise fail inside ``learn``
    (a position beyond the slots, arrays of another length) or train NaN weights.

    :param buffer: the ``MultiAgentReplayBuffer`` read from the file
    :param name: the file, for the messages
    :raises ValueError: naming the first field that does not fit
    """

    def damaged(what: str) -> ValueError:
        return ValueError(f"the replay buffer {name} is damaged: {what}; save it again from a run")

    for field in ("buffer_size", "n_copies", "n_agents", "action_dim"):
        value = getattr(buffer, field, None)
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
            raise damaged(f"its {field} is {value!r}, not an integer >= 1")
    slots, copies, agents = int(buffer.buffer_size), int(buffer.n_copies), int(buffer.n_agents)
    pos, full = getattr(buffer, "pos", None), getattr(buffer, "full", None)
    if isinstance(pos, bool) or not isinstance(pos, int | np.integer) or not 0 <= pos < slots:
        raise damaged(f"its position pos={pos!r} is outside its {slots} slots (0 to {slots - 1})")
    if not isinstance(full, bool | np.bool_):
        raise damaged(f"its full flag is {full!r}, not True or False")
    obs_shape = tuple(getattr(buffer, "obs_shape", ()))
    layout = f"{slots} slots of {copies} copies x {agents} agents, observations {obs_shape}, actions ({buffer.action_dim},)"
    expected = {
        "observations": (slots, copies, agents, *obs_shape),
        "actions": (slots, copies, agents, buffer.action_dim),
        "rewards": (slots, copies, agents),
        "dones": (slots, copies),
        "timeouts": (slots, copies),
        "next_obs_index": (slots, copies),
        "_next_obs_index_host": (slots, copies),
        "_pending_host": (copies, agents, *obs_shape),
    }
    for field, shape in expected.items():
        found = getattr(getattr(buffer, field, None), "shape", None)
        if found is None or tuple(found) != shape:
            raise damaged(f"its {field} has shape {None if found is None else tuple(found)}, but {layout} need {shape}")
    aux = getattr(getattr(buffer, "_aux", None), "shape", None)
    if aux is None or len(aux) < 2 or aux[0] < copies or tuple(aux[1:]) != (agents, *obs_shape):
        raise damaged(f"its next observations (_aux) have shape {aux}, but {layout} need (>= {copies}, {agents}, ...)")
    n_kept = int(aux[0]) - copies
    index = np.asarray(buffer._next_obs_index_host)
    if index.size and (index.min() < -1 or index.max() >= n_kept):
        raise damaged(f"its next-observation index points outside its {n_kept} kept next observations")
    if any(not 0 <= row < n_kept for row in getattr(buffer, "_free_extra", [])):
        raise damaged(f"its free list names rows outside its {n_kept} kept next observations")
    for field, what in (
        ("rewards", "rewards"),
        ("actions", "actions"),
        ("observations", "observations"),
        ("_aux", "next observations"),
    ):
        values = th.as_tensor(getattr(buffer, field))
        if not values.is_floating_point():
            continue
        # By blocks of slots, so that the check needs little memory beside a large buffer
        for start in range(0, len(values), 4096):
            if not bool(th.isfinite(values[start : start + 4096]).all()):
                row = start + int(th.nonzero(~th.isfinite(values[start : start + 4096]))[0, 0])
                raise ValueError(
                    f"the replay buffer {name} holds NaN or infinite {what} (the first at slot {row}): training on "
                    "them would make every weight NaN; save the buffer again from a run whose env returns finite values"
                )
