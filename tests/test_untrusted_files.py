"""Opening a model, a replay buffer or a run folder one did not write runs no code from it."""

import base64
import collections
import json
import os
import pickle
import re
import sys
import zipfile
from pathlib import Path

import pytest
import yaml
from maddpg_test_envs import TargetReachEnv

import sb3_maddpg
from sb3_maddpg import MADDPG, make_multiagent_vec_env
from sb3_maddpg.__main__ import main
from sb3_maddpg.common.model_files import restricted_loads
from sb3_maddpg.evaluation.report import check_model_fits_env, find_run_config


class _RunsCode:
    """Unpickled, it creates the file ``path`` (what ``os.system`` or any other call could do)."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def __reduce__(self):
        return (os.mkdir, (os.fspath(self.path),))


def _model(tmp_path: Path) -> Path:
    env = make_multiagent_vec_env(lambda **kwargs: TargetReachEnv(), n_envs=1)
    path = tmp_path / "model.zip"
    MADDPG("MlpPolicy", env, buffer_size=50, learning_starts=5, batch_size=4, device="cpu").save(path)
    return path


def _with_data(source: Path, target: Path, change) -> Path:
    """A copy of the model zip whose JSON ``data`` is changed by ``change(raw)``."""
    with zipfile.ZipFile(source) as archive:
        members = {name: archive.read(name) for name in archive.namelist()}
    raw = json.loads(members["data"])
    change(raw)
    members["data"] = json.dumps(raw).encode()
    with zipfile.ZipFile(target, "w") as archive:
        for name, content in members.items():
            archive.writestr(name, content)
    return target


def _code(marker: Path) -> dict[str, str]:
    return {":type:": "<class 'type'>", ":serialized:": base64.b64encode(pickle.dumps(_RunsCode(marker))).decode()}


@pytest.mark.parametrize("key", ["policy_class", "observation_space", "action_noise", "lr_schedule"])
def test_a_crafted_model_runs_no_code_on_load(key: str, tmp_path: Path) -> None:
    marker = tmp_path / "ran"
    crafted = _with_data(_model(tmp_path), tmp_path / "crafted.zip", lambda raw: raw.update({key: _code(marker)}))
    if key == "lr_schedule":
        # rebuilt from learning_rate by _setup_model: what it holds is not needed, and not run
        MADDPG.load(crafted, device="cpu")
    else:
        with pytest.raises(ValueError, match=f"the saved {key!r} cannot be read safely: it refers to .*mkdir"):
            MADDPG.load(crafted, device="cpu")
    assert not marker.exists()


def test_a_zip_the_library_refuses_runs_no_code_either(tmp_path: Path) -> None:
    marker = tmp_path / "ran"

    def not_maddpg(raw: dict) -> None:
        del raw["n_agents"]
        raw["policy_class"] = _code(marker)

    crafted = _with_data(_model(tmp_path), tmp_path / "crafted.zip", not_maddpg)
    with pytest.raises(ValueError, match="is not a MADDPG model"):
        MADDPG.load(crafted, device="cpu")
    with pytest.raises(ValueError, match="is not a MADDPG model"):
        check_model_fits_env(crafted, "uav_coverage_fast_v0", {})
    assert not marker.exists()


def test_the_evaluate_pre_check_runs_no_code(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    marker = tmp_path / "ran"
    crafted = _with_data(_model(tmp_path), tmp_path / "crafted.zip", lambda raw: raw.update(observation_space=_code(marker)))
    with pytest.raises(SystemExit):
        main(["evaluate", "--model", os.fspath(crafted), "--episodes", "1", "--out", os.fspath(tmp_path / "out")])
    assert "cannot be read safely" in capsys.readouterr().err
    assert not marker.exists()


def test_a_crafted_replay_buffer_runs_no_code(tmp_path: Path) -> None:
    marker = tmp_path / "ran"
    model = MADDPG.load(_model(tmp_path), env=make_multiagent_vec_env(lambda **kwargs: TargetReachEnv(), n_envs=1))
    (tmp_path / "replay_buffer.pkl").write_bytes(pickle.dumps(_RunsCode(marker)))
    with pytest.raises(ValueError, match="is not a replay buffer that can be read here.*mkdir"):
        model.load_replay_buffer(tmp_path / "replay_buffer.pkl")
    assert not marker.exists()


def test_a_learning_rate_saved_as_code_is_given_again(tmp_path: Path) -> None:
    env = make_multiagent_vec_env(lambda **kwargs: TargetReachEnv(), n_envs=1)
    MADDPG("MlpPolicy", env, learning_rate=lambda progress: 1e-3 * progress, buffer_size=50, device="cpu").save(
        tmp_path / "lambda.zip"
    )
    with pytest.raises(ValueError, match=r"custom_objects=\{'learning_rate': \.\.\.\}"):
        MADDPG.load(tmp_path / "lambda.zip", device="cpu")
    model = MADDPG.load(tmp_path / "lambda.zip", device="cpu", custom_objects={"learning_rate": 1e-4})
    assert model.lr_schedule(1.0) == pytest.approx(1e-4)


def _run_folder(root: Path, env_id: str, args: str, config: str | None = None) -> Path:
    run = root / f"{env_id}_1"
    (run / env_id).mkdir(parents=True)
    (run / env_id / "args.yml").write_text(args)
    if config is not None:
        (run / env_id / "config.yml").write_text(config)
    return run


def test_run_files_are_read_with_safe_yaml(tmp_path: Path) -> None:
    marker = tmp_path / "ran"
    bad = f"!!python/object/apply:os.mkdir [{os.fspath(marker)!r}]\n"
    run = _run_folder(tmp_path / "a", "uav_coverage_fast_v0", "env: uav_coverage_fast_v0\n", config=bad)
    with pytest.raises(ValueError, match="config.yml is not a run file of plain YAML values"):
        find_run_config(run / "uav_coverage_fast_v0.zip")
    run = _run_folder(tmp_path / "b", "uav_coverage_fast_v0", bad)
    with pytest.raises(ValueError, match="args.yml is not a run file of plain YAML values"):
        find_run_config(run / "uav_coverage_fast_v0.zip")
    assert not marker.exists()
    # What RL Zoo writes (an OrderedDict, tuples) is read
    args = yaml.dump(collections.OrderedDict(env="uav_coverage_fast_v0", env_kwargs={"n_uavs": 2}, shape=(1, 2)))
    config = yaml.dump(collections.OrderedDict(env_kwargs={"max_cycles": 7}, train_freq=(1, "step")))
    run = _run_folder(tmp_path / "c", "uav_coverage_fast_v0", args, config)
    assert find_run_config(run / "rl_model_100_steps.zip") == ("uav_coverage_fast_v0", {"n_uavs": 2})


def test_a_models_config_comes_from_its_own_run_folder_only(tmp_path: Path) -> None:
    # DIR/model.zip beside an unrelated run's sub-folder: that run's settings are not the model's
    folder = tmp_path / "models"
    (folder / "other").mkdir(parents=True)
    (folder / "other" / "args.yml").write_text("env: uav_coverage_cpu_v1\nenv_kwargs: {n_uavs: 5}\n")
    assert find_run_config(folder / "model.zip") == (None, {})
    # A run folder's other sub-folders are not read either
    run = _run_folder(tmp_path / "runs", "uav_coverage_fast_v0", "env: uav_coverage_fast_v0\n")
    (run / "aaa").mkdir()
    (run / "aaa" / "args.yml").write_text("env: uav_coverage_cpu_v1\nenv_kwargs: {n_uavs: 5}\n")
    assert find_run_config(run / "best_model.zip") == ("uav_coverage_fast_v0", {})


def test_enjoy_refuses_a_run_yaml_that_would_run_code(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    marker = tmp_path / "ran"
    env_id = "uav_coverage_fast_v0"
    run = _run_folder(tmp_path / "logs" / "maddpg", env_id, f"!!python/object/apply:os.mkdir [{os.fspath(marker)!r}]\n")
    _model(tmp_path).rename(run / f"{env_id}.zip")
    with pytest.raises(SystemExit):
        main(["enjoy", "--env", env_id, "-f", "logs", "--no-render", "-n", "5"])
    assert "args.yml is not a run file of plain YAML values" in capsys.readouterr().err
    assert not marker.exists()


def _module_that_writes_a_marker(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, relative: str) -> Path:
    """A module file inside the sb3_maddpg package (by its ``__path__``) whose import creates the file it returns."""
    marker = tmp_path / "imported"
    source = tmp_path / "package_files" / relative
    source.parent.mkdir(parents=True, exist_ok=True)
    for folder in source.relative_to(tmp_path / "package_files").parents:
        (tmp_path / "package_files" / folder / "__init__.py").touch()
    source.write_text(f"open({os.fspath(marker)!r}, 'w').close()\n\nclass Anything:\n    pass\n")
    monkeypatch.setattr(sb3_maddpg, "__path__", [*sb3_maddpg.__path__, os.fspath(tmp_path / "package_files")])
    for name in [name for name in sys.modules if name.startswith("sb3_maddpg.writes_a_marker")]:
        monkeypatch.delitem(sys.modules, name)
    return marker


@pytest.mark.parametrize(
    ("module", "relative"),
    [
        ("sb3_maddpg.writes_a_marker", "writes_a_marker.py"),
        ("sb3_maddpg.writes_a_marker_package.__main__", "writes_a_marker_package/__main__.py"),
    ],
)
def test_a_module_off_the_list_is_refused_before_it_is_imported(
    module: str, relative: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    marker = _module_that_writes_a_marker(tmp_path, monkeypatch, relative)
    payload = f"c{module}\nAnything\n.".encode()  # protocol 0: GLOBAL module name, STOP
    with pytest.raises(pickle.UnpicklingError, match=f"it refers to {module}.Anything"):
        restricted_loads(payload)
    code = {":type:": "<class 'type'>", ":serialized:": base64.b64encode(payload).decode()}
    crafted = _with_data(_model(tmp_path), tmp_path / "crafted.zip", lambda raw: raw.update(policy_class=code))
    with pytest.raises(ValueError, match=f"the saved 'policy_class' cannot be read safely: it refers to {module}"):
        MADDPG.load(crafted, device="cpu")
    assert not marker.exists() and module not in sys.modules


def test_a_module_attribute_that_would_import_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    # numpy's module __getattr__ imports numpy.f2py for this name: only a module's own attributes are looked up
    monkeypatch.delitem(sys.modules, "numpy.f2py", raising=False)
    with pytest.raises(pickle.UnpicklingError, match="it refers to numpy.f2py"):
        restricted_loads(b"cnumpy\nf2py\n.")
    assert "numpy.f2py" not in sys.modules


ENV = "uav_coverage_fast_v0"
TINY = ["--env", ENV, "--env-kwargs", "obs_size:16", "max_cycles:10", "n_uavs:2", "--seed", "0", "--eval-freq", "-1"]
TINY += ["-params", "learning_starts:20", "train_freq:10", "policy_kwargs:dict(n_quantiles=4, net_arch=[16])"]


def _writes(marker: Path) -> str:
    """A Python expression that creates ``marker`` when it is evaluated, and is a dict (what RL Zoo expects)."""
    return f"open({os.fspath(marker)!r}, 'w').close() or dict()"


def _enjoy_fails(tmp_path: Path, capsys: pytest.CaptureFixture, *extra: str) -> str:
    with pytest.raises(SystemExit):
        main(["enjoy", "--env", ENV, "-f", "logs", "--no-render", "-n", "5", *extra])
    return capsys.readouterr().err


@pytest.mark.parametrize(
    ("layout", "config", "message"),
    [
        ("run", "normalize: {expression!r}\n", "normalize: .* is not read: it is an expression"),
        ("no-args", "!!python/object/apply:os.mkdir [{marker!r}]\n", "config.yml is not a run file of plain YAML values"),
        ("exp-id-1", "normalize: {expression!r}\n", "normalize: .* is not read: it is an expression"),
        ("run", "vec_env_wrapper: writes_a_marker_module.Wrapper\n", "--gym-packages writes_a_marker_module"),
    ],
    ids=["normalize-string", "config-without-args", "exp-id-minus-1", "wrapper-module"],
)
def test_enjoy_checks_every_run_file_rl_zoo_reads(
    layout: str, config: str, message: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    monkeypatch.chdir(tmp_path)
    marker = tmp_path / "ran"
    # a module whose import would create the marker: a wrapper may name only modules already loaded
    (tmp_path / "writes_a_marker_module.py").write_text(f"open({os.fspath(marker)!r}, 'w').close()\nWrapper = dict\n")
    monkeypatch.syspath_prepend(os.fspath(tmp_path))
    algo_folder = tmp_path / "logs" / "maddpg"
    run = algo_folder if layout == "exp-id-1" else algo_folder / f"{ENV}_1"
    (run / ENV).mkdir(parents=True)
    (run / ENV / "config.yml").write_text(config.format(expression=_writes(marker), marker=os.fspath(marker)))
    if layout == "run":
        (run / ENV / "args.yml").write_text(f"env: {ENV}\nenv_kwargs: null\n")
    _model(tmp_path).rename(run / f"{ENV}.zip")
    extra = ["--exp-id", "-1"] if layout == "exp-id-1" else []
    assert re.search(message, _enjoy_fails(tmp_path, capsys, *extra))
    assert not marker.exists() and "writes_a_marker_module" not in sys.modules


def test_record_video_checks_the_run_files_too(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    marker = tmp_path / "ran"
    run = _run_folder(tmp_path / "logs" / "maddpg", ENV, f"env: {ENV}\n", config=f"normalize: {_writes(marker)!r}\n")
    _model(tmp_path).rename(run / f"{ENV}.zip")
    with pytest.raises(SystemExit):
        main(["record-video", "--env", ENV, "-f", "logs", "-n", "5", "-o", os.fspath(tmp_path / "videos")])
    assert re.search("normalize: .* is not read: it is an expression", capsys.readouterr().err)
    assert not marker.exists()


def test_enjoy_reads_vecnormalize_pkl_without_running_code(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    marker = tmp_path / "ran"
    run = _run_folder(tmp_path / "logs" / "maddpg", ENV, f"env: {ENV}\nenv_kwargs: null\n", config="normalize: true\n")
    (run / ENV / "vecnormalize.pkl").write_bytes(pickle.dumps(_RunsCode(marker)))
    _model(tmp_path).rename(run / f"{ENV}.zip")
    assert "vecnormalize.pkl cannot be read safely, it is not read: it refers to" in _enjoy_fails(tmp_path, capsys)
    assert not marker.exists()


def test_vecnormalize_statistics_are_read_by_the_restricted_unpickler(tmp_path: Path) -> None:
    from stable_baselines3.common.vec_env import VecNormalize

    from sb3_maddpg.zoo.run_files import load_vec_normalize

    env = make_multiagent_vec_env(lambda **kwargs: TargetReachEnv(), n_envs=1)
    statistics = VecNormalize(env)
    statistics.reset()
    statistics.save(tmp_path / "vecnormalize.pkl")
    loaded = load_vec_normalize(tmp_path / "vecnormalize.pkl", env)
    assert loaded.venv is env and loaded.obs_rms.mean.shape == statistics.obs_rms.mean.shape
    (tmp_path / "list.pkl").write_bytes(pickle.dumps([1, 2]))
    with pytest.raises(ValueError, match="does not hold VecNormalize statistics"):
        load_vec_normalize(tmp_path / "list.pkl")


def test_train_i_reads_the_runs_vecnormalize_pkl_without_running_code(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["train", *TINY, "-n", "20"]) == 0
    run = tmp_path / "logs" / "maddpg" / f"{ENV}_1"
    marker = tmp_path / "ran"
    (run / ENV / "vecnormalize.pkl").write_bytes(pickle.dumps(_RunsCode(marker)))
    capsys.readouterr()
    with pytest.raises(SystemExit):
        main(["train", *TINY, "-n", "20", "-i", os.fspath(run / f"{ENV}.zip")])
    assert "vecnormalize.pkl cannot be read safely, it is not read" in capsys.readouterr().err
    assert not marker.exists()


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ("  policy_kwargs: {expression!r}\n", "policy_kwargs: .* is not read: it is an expression, and only values"),
        ("  normalize: {expression!r}\n", "normalize: .* is not read: it is an expression"),
        ("  callback: writes_a_marker_module.Callback\n", "callback: .*--gym-packages writes_a_marker_module"),
    ],
    ids=["policy_kwargs", "normalize", "callback"],
)
def test_safe_config_refuses_code_in_the_entry(
    entry: str, message: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    from cli_testing import fails_with

    monkeypatch.chdir(tmp_path)
    marker = tmp_path / "ran"
    (tmp_path / "writes_a_marker_module.py").write_text(f"open({os.fspath(marker)!r}, 'w').close()\nCallback = dict\n")
    monkeypatch.syspath_prepend(os.fspath(tmp_path))
    config = tmp_path / "shared.yml"
    config.write_text(f"{ENV}:\n  n_timesteps: 100\n" + entry.format(expression=_writes(marker)))
    err = fails_with(["train", *TINY, "-n", "20", "-conf", os.fspath(config), "--safe-config"], capsys)
    assert re.search(message, err) and "(--safe-config)" in err
    assert not marker.exists() and "writes_a_marker_module" not in sys.modules


def test_safe_config_reads_yaml_values_only(tmp_path: Path, capsys) -> None:
    from cli_testing import fails_with

    from sb3_maddpg.zoo.command_line import check_config, packaged_config, prepare_zoo_argv

    # the packaged files hold values only (their policy_kwargs strings are dict(...) of literals)
    for algo in ("maddpg", "matd3"):
        config = os.fspath(packaged_config(algo))
        for env_id in yaml.safe_load(Path(config).read_text()):
            check_config(config, env_id, safe=True)
    assert "--safe-config" not in prepare_zoo_argv("train", ["--env", ENV, "--safe-config"])
    (tmp_path / "hyperparams.py").write_text("hyperparams = {}\n")
    err = fails_with(["train", "--env", ENV, "-conf", os.fspath(tmp_path / "hyperparams.py"), "--safe-config"], capsys)
    assert "--safe-config reads YAML files only" in err


def _alias_bomb(levels: int = 8) -> str:
    """A YAML file of nested aliases, 10**levels values once expanded (about 1.9 KB for 8 levels)."""
    lines = ["env: uav_coverage_fast_v0", "l0: &l0 [x, x, x, x, x, x, x, x, x, x]"]
    lines += [f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 10)}]" for i in range(1, levels + 1)]
    return "\n".join(lines) + "\n"


def test_yaml_aliases_are_bounded(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    import time

    from cli_testing import fails_with

    from sb3_maddpg.evaluation.report import MAX_YAML_VALUES, read_run_yaml

    run = _run_folder(tmp_path, ENV, _alias_bomb())
    _model(tmp_path).rename(run / f"{ENV}.zip")
    started = time.perf_counter()
    err = fails_with(["evaluate", "--model", os.fspath(run / f"{ENV}.zip"), "--out", os.fspath(tmp_path / "out")], capsys)
    assert (
        f"args.yml is not a run file of plain YAML values, it is not read: its aliases expand to more than {MAX_YAML_VALUES}"
        in err
    )
    assert time.perf_counter() - started < 5
    (tmp_path / "recursive.yml").write_text("a: &a [1, *a]\n")
    with pytest.raises(ValueError, match="a recursive alias"):
        read_run_yaml(tmp_path / "recursive.yml")
    # a -conf file too, and an ordinary file with aliases is read
    (tmp_path / "bomb.yml").write_text(_alias_bomb() + f"{ENV}: {{n_timesteps: 10, big: *l8}}\n")
    assert "aliases expand to more than" in fails_with(
        ["train", "--env", ENV, "-conf", os.fspath(tmp_path / "bomb.yml")], capsys
    )
    (tmp_path / "small.yml").write_text(_alias_bomb(2))
    assert len(read_run_yaml(tmp_path / "small.yml")["l2"]) == 10
