"""Checks of a saved model file before SB3 loads it: a clear message for a file that is not a MADDPG model or is damaged."""

import io
import json
import os
import pathlib
import zipfile
import zlib
from typing import Any

from stable_baselines3.common.save_util import json_to_data

# Class parameters every saved MADDPG model has and no SB3 algorithm saves
MADDPG_KEYS = ("n_agents", "cvar_alpha")
# What reading a damaged zip member can raise (zip, zlib, JSON, pickle and torch's stream reader)
READ_ERRORS = (zipfile.BadZipFile, zlib.error, EOFError, json.JSONDecodeError, UnicodeDecodeError, RuntimeError)


def resolve_model_path(path: str | os.PathLike) -> pathlib.Path:
    """
    The file SB3's ``load`` opens for ``path``: the path itself, else the path with ``.zip`` added.

    :param path: as given to ``load``
    :return: the file
    """
    target = pathlib.Path(path)
    if not target.exists() and pathlib.Path(f"{target}.zip").exists():
        target = pathlib.Path(f"{target}.zip")
    if target.is_dir():
        raise ValueError(f"{os.fspath(target)} is a folder, not a saved model (.zip)")
    if not target.exists():
        raise FileNotFoundError(f"model file {os.fspath(path)} not found (also tried {os.fspath(path)}.zip)")
    return target


def _saved_by(raw: dict[str, Any]) -> str:
    """What saved a zip whose data lacks MADDPG's parameters, as far as its data tells."""
    if "policy_class" not in raw:
        return "something else than SB3 (its data has no policy_class)"
    try:
        policy_class = json_to_data(json.dumps({"policy_class": raw["policy_class"]}))["policy_class"]
        name = f"{policy_class.__module__}.{policy_class.__qualname__}"
    except Exception:
        name = "a policy class that cannot be read here"
    return f"another algorithm (its policy is {name})"


def read_maddpg_data(source: str | os.PathLike | io.BufferedIOBase, keys: tuple[str, ...] = ()) -> dict[str, Any]:
    """
    Check that a saved model is an intact MADDPG zip and read some of its class parameters, without loading weights.

    :param source: the model file (``.zip`` may be left out, as with SB3's ``load``) or an open binary file (read from
        its current position, then put back there)
    :param keys: class parameters to deserialise and return (e.g. ``("n_agents", "observation_space")``)
    :return: those parameters
    :raises ValueError: one line saying that the file is not a MADDPG model, or is damaged, and which
    """
    if isinstance(source, str | os.PathLike):
        target = resolve_model_path(source)
        name, opened, start = os.fspath(target), open(target, "rb"), 0
    else:
        name, opened, start = getattr(source, "name", "the model file"), source, source.tell()
    try:
        try:
            archive = zipfile.ZipFile(opened)
        except zipfile.BadZipFile as error:
            opened.seek(start)
            if opened.read(4) == b"PK\x03\x04":
                raise ValueError(f"{name} is damaged: it is a truncated or corrupted zip file") from error
            raise ValueError(f"{name} is not a MADDPG model: it is not a zip file (SB3 saves models as .zip)") from error
        with archive:
            try:
                damaged = archive.testzip()
            except READ_ERRORS as error:
                raise ValueError(f"{name} is damaged: its members cannot be read ({error})") from error
            if damaged is not None:
                raise ValueError(f"{name} is damaged: its member {damaged!r} fails the zip's CRC check")
            if "data" not in archive.namelist():
                members = ", ".join(archive.namelist()) or "none"
                raise ValueError(f"{name} is not a MADDPG model: it has no 'data' member (its members: {members})")
            try:
                raw = json.loads(archive.read("data").decode())
            except READ_ERRORS as error:
                raise ValueError(f"{name} is damaged: its 'data' member is not valid JSON ({error})") from error
        if not isinstance(raw, dict) or any(key not in raw for key in MADDPG_KEYS):
            saved_by = _saved_by(raw if isinstance(raw, dict) else {})
            raise ValueError(f"{name} is not a MADDPG model: it was saved by {saved_by}")
        try:
            return json_to_data(json.dumps({key: raw[key] for key in keys if key in raw}))
        except Exception as error:
            raise ValueError(f"{name} is damaged: its {', '.join(keys)} cannot be read ({error})") from error
    finally:
        if opened is not source:
            opened.close()
        else:
            opened.seek(start)
