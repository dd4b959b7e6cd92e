"""
The Hugging Face Hub commands without the Hub: ``push-to-hub --dry-run``'s folder and model card by content, the
card's table against ``evaluate``'s, ``load-from-hub`` from a local snapshot laid out as the Hub's cache (offline
mode) with a model that acts as saved, a crafted model refused, and one clear line when the Hub cannot be reached.
"""

import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from cli_testing import fails_with

from sb3_maddpg.__main__ import main

if os.environ.get("CI", "").lower() == "true":
    import huggingface_hub  # CI installs the hub extra (scripts/install.sh): there these tests run
else:
    huggingface_hub = pytest.importorskip("huggingface_hub", reason='the hub extra is not installed: pip install -e ".[hub]"')

ROOT = Path(__file__).resolve().parent.parent
ENV = "uav_coverage_fast_v0"
ENV_KWARGS = {"obs_size": 16, "max_cycles": 20, "n_uavs": 3}
ORGANIZATION = "test-org"
REPO = f"{ORGANIZATION}/maddpg-{ENV}"
MODEL_FILE = f"maddpg-{ENV}.zip"
EPISODES = ["--episodes", "2", "--seed", "0"]


@pytest.fixture(scope="module")
def pushed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny run (40 timesteps, no update) and the repository folder ``push-to-hub --dry-run`` writes for it."""
    root = tmp_path_factory.mktemp("hub")
    env_kwargs = [f"{key}:{value}" for key, value in ENV_KWARGS.items()]
    params = ["-params", "learning_starts:100", "buffer_size:100"]
    with pytest.MonkeyPatch.context() as patch:
        patch.chdir(root)
        assert main(["train", "--env", ENV, "--env-kwargs", *env_kwargs, *params, "-n", "40", "--seed", "0"]) == 0
        push = ["push-to-hub", "--env", ENV, "-orga", ORGANIZATION, "--dry-run", "--local-dir", "repo", *EPISODES]
        assert main(push) == 0
    return root


def run_model(root: Path) -> Path:
    return root / "logs" / "maddpg" / f"{ENV}_1" / f"{ENV}.zip"


def card_parts(card: str) -> tuple[dict, str, str]:
    """The card's YAML metadata, its evaluation table and its YAML entry."""
    _, metadata, body = card.split("---\n", 2)
    lines = body.splitlines()
    table = "\n".join(line for line in lines[lines.index("## Evaluation") :] if line.startswith("|"))
    entry = body[body.index("```yaml\n") + len("```yaml\n") :]
    return yaml.safe_load(metadata), table, entry[: entry.index("```")]


def test_push_to_hub_dry_run_writes_rl_zoos_layout_and_a_card(pushed: Path) -> None:
    from PIL import Image

    from sb3_maddpg.evaluation.report import read_run_yaml

    repo = pushed / "repo"
    files = {path.relative_to(repo).as_posix() for path in repo.rglob("*") if path.is_file()}
    rl_zoo_files = {MODEL_FILE, "config.yml", "args.yml", "env_kwargs.yml", "train_eval_metrics.zip"}
    assert rl_zoo_files | {"README.md", "replay.gif", "evaluation/results.md", "evaluation/results.json"} <= files
    run = run_model(pushed).parent
    assert (repo / MODEL_FILE).read_bytes() == run_model(pushed).read_bytes()
    assert (repo / "config.yml").read_bytes() == (run / ENV / "config.yml").read_bytes()
    assert yaml.safe_load((repo / "env_kwargs.yml").read_text()) == {**ENV_KWARGS, "start": "random"}
    with Image.open(repo / "replay.gif") as gif:
        assert gif.n_frames > 1

    metadata, _, entry = card_parts((repo / "README.md").read_text())
    assert metadata["library_name"] == "stable-baselines3" and ENV in metadata["tags"]
    metrics = {metric["type"]: metric["value"] for metric in metadata["model-index"][0]["results"][0]["metrics"]}
    model_row = yaml.safe_load((repo / "evaluation" / "results.json").read_text())["summary"][0]
    assert model_row["method"] == "maddpg"
    for name, key in (("mean_reward", "return"), ("coverage", "coverage"), ("energy_efficiency", "energy_efficiency")):
        assert metrics[name] == f"{model_row[f'{key}_mean']:.4f} +/- {model_row[f'{key}_std']:.4f}"
    # The run's YAML, as an entry for -conf
    assert yaml.safe_load(entry) == {ENV: read_run_yaml(run / ENV / "config.yml")}


def test_the_cards_table_is_evaluates(pushed: Path, capsys: pytest.CaptureFixture) -> None:
    out = pushed / "evaluate"
    main(["evaluate", "--model", str(run_model(pushed)), *EPISODES, "--out", str(out), "--no-gif", "--verbose", "0"])
    _, table, _ = card_parts((pushed / "repo" / "README.md").read_text())
    assert table == (out / "results.md").read_text().strip()
    assert "| maddpg | 2 |" in table and "greedy_static" in table and "eta_T" in table


def hub_cache(folder: Path, cache: Path, repo: str) -> str:
    """
    Lay ``folder`` out as huggingface_hub's cache holds a downloaded model repository: ``models--ORG--NAME/`` with
    the files under ``blobs/`` (named by their hash), ``snapshots/<commit>/`` linking to them, and ``refs/main``.

    :return: the commit
    """
    commit = hashlib.sha1(repo.encode()).hexdigest()
    storage = cache / f"models--{repo.replace('/', '--')}"
    for path in sorted(folder.rglob("*")):
        if not path.is_file():
            continue
        blob = storage / "blobs" / hashlib.sha256(path.read_bytes()).hexdigest()
        blob.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(path, blob)
        link = storage / "snapshots" / commit / path.relative_to(folder)
        link.parent.mkdir(parents=True, exist_ok=True)
        link.symlink_to(os.path.relpath(blob, link.parent))
    (storage / "refs").mkdir(parents=True, exist_ok=True)
    (storage / "refs" / "main").write_text(commit)
    return commit


def test_load_from_hub_reads_a_local_snapshot_offline_and_the_model_acts_as_saved(pushed: Path, tmp_path: Path) -> None:
    from sb3_maddpg import MADDPG
    from sb3_maddpg.evaluation.report import find_run_config
    from sb3_maddpg.zoo.registry import make_multiagent_env

    cache = tmp_path / "hf" / "hub"
    commit = hub_cache(pushed / "repo", cache, REPO)
    (cached,) = huggingface_hub.scan_cache_dir(cache).repos  # huggingface_hub reads it as its own
    assert cached.repo_id == REPO and [revision.commit_hash for revision in cached.revisions] == [commit]
    # A fresh process, as a user runs it: HF_HUB_OFFLINE and HF_HUB_CACHE are read when huggingface_hub is imported
    env = {**os.environ, "HF_HUB_OFFLINE": "1", "HF_HUB_CACHE": str(cache), "HF_HOME": str(tmp_path / "hf")}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    command = [sys.executable, "-m", "sb3_maddpg", "load-from-hub", "--env", ENV, "-orga", ORGANIZATION, "-f", "downloaded"]
    result = subprocess.run(command, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr

    run = tmp_path / "downloaded" / "maddpg" / f"{ENV}_1"
    assert f"Saved to {Path('downloaded', 'maddpg', f'{ENV}_1')}" in result.stdout
    assert (run / "monitor.csv").is_file() and (run / ENV / "args.yml").is_file()
    # evaluate and enjoy read the downloaded run's env as the trained one's
    assert find_run_config(run / f"{ENV}.zip") == find_run_config(run_model(pushed))
    saved, loaded = (MADDPG.load(path, device="cpu") for path in (run_model(pushed), run / f"{ENV}.zip"))
    parallel_env = make_multiagent_env(ENV, **ENV_KWARGS)
    for seed in range(3):
        observations, _ = parallel_env.reset(seed=seed)
        expected, _ = saved.predict(observations, deterministic=True)
        actions, _ = loaded.predict(observations, deterministic=True)
        assert set(actions) == set(parallel_env.possible_agents)
        for agent in actions:
            np.testing.assert_array_equal(actions[agent], expected[agent])


def test_load_from_hub_refuses_a_model_that_would_run_code(
    pushed: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    from test_untrusted_files import _code, _with_data

    marker = tmp_path / "ran"
    crafted = tmp_path / "crafted"
    shutil.copytree(pushed / "repo", crafted)
    _with_data(pushed / "repo" / MODEL_FILE, crafted / MODEL_FILE, lambda raw: raw.update(observation_space=_code(marker)))
    hub_cache(crafted, tmp_path / "cache", REPO)
    monkeypatch.setattr(huggingface_hub.constants, "HF_HUB_OFFLINE", True)
    argv = ["load-from-hub", "--env", ENV, "-orga", ORGANIZATION, "-f", str(tmp_path / "logs"), "--cache-dir"]
    err = fails_with([*argv, str(tmp_path / "cache")], capsys)
    assert f"{MODEL_FILE} from the Hub is refused" in err and "cannot be read safely" in err
    assert not marker.exists() and not (tmp_path / "logs").exists()


def test_without_the_network_the_commands_say_so_in_one_line(
    pushed: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    # Nothing listens on port 9: the connection is refused at once
    monkeypatch.setattr(huggingface_hub.constants, "ENDPOINT", "http://127.0.0.1:9")
    monkeypatch.setenv("HF_TOKEN", "hf_not_a_real_token")
    load = ["load-from-hub", "--env", ENV, "-orga", ORGANIZATION, "-f", str(tmp_path / "logs"), "--cache-dir"]
    err = fails_with([*load, str(tmp_path / "empty_cache")], capsys)
    assert "cannot download test-org/maddpg-uav_coverage_fast_v0: the Hub at http://127.0.0.1:9 cannot be reached" in err
    assert "holds no complete copy of it" in err

    monkeypatch.chdir(pushed)
    push = ["push-to-hub", "--env", ENV, "-orga", ORGANIZATION, "--local-dir", str(tmp_path / "repo")]
    err = fails_with(push, capsys)
    assert "cannot push to test-org/maddpg-uav_coverage_fast_v0: the Hub at http://127.0.0.1:9 cannot be reached" in err
    assert not (tmp_path / "repo").exists()  # the command stopped before it evaluated

    monkeypatch.setattr(huggingface_hub.constants, "HF_HUB_OFFLINE", True)
    err = fails_with(push, capsys)
    assert "HF_HUB_OFFLINE is set" in err and "--dry-run" in err
