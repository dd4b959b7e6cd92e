"""
``optimize`` on a shared Optuna study in a real PostgreSQL server: workers started together share one study.

The server comes from ``SB3_MADDPG_TEST_POSTGRES_URL`` (``.ci/run`` starts one and sets it); without it, a throwaway
server is started with ``scripts/local_postgres.sh`` where PostgreSQL's binaries are installed. In CI (``CI=true``) a
missing server is a failure, not a skip.
"""

import os
import socket
import subprocess
import sys
import tempfile
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
CONFIG = str(ROOT / "zoo_configs" / "maddpg.yml")
URL_VARIABLE = "SB3_MADDPG_TEST_POSTGRES_URL"
MAX_TOTAL_TRIALS = 4
TINY_OPTIMIZE = [
    "--env",
    "uav_coverage_fast_v0",
    "-conf",
    CONFIG,
    "--env-kwargs",
    "obs_size:16",
    "max_cycles:10",
    "n_uavs:2",
    "-params",
    "learning_starts:40",
    "train_freq:10",
    "-n",
    "100",
    "--eval-episodes",
    "1",
    "--n-evaluations",
    "1",
    "--n-startup-trials",
    "2",
    "--max-total-trials",
    str(MAX_TOTAL_TRIALS),
]


def _unavailable(reason: str) -> None:
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(f"CI=true but no PostgreSQL server for the shared-study tests: {reason}")
    pytest.skip(reason)


@pytest.fixture(scope="module")
def server_url() -> Iterator[str]:
    """The URL of a PostgreSQL database whose user may create databases."""
    pytest.importorskip("optuna")
    try:
        import psycopg  # noqa: F401
    except ImportError:
        _unavailable('the PostgreSQL driver is not installed (pip install "sb3_maddpg[zoo,postgres]")')
    url = os.environ.get(URL_VARIABLE)
    if url:
        yield url
        return
    with tempfile.TemporaryDirectory(prefix="sb3_maddpg_pg_") as folder:
        script = ROOT / "scripts" / "local_postgres.sh"
        started = subprocess.run(["bash", str(script), "start", folder], capture_output=True, text=True)
        if started.returncode != 0:
            _unavailable(f"{URL_VARIABLE} is not set and no PostgreSQL server could be started: {started.stderr.strip()}")
        try:
            yield started.stdout.strip()
        finally:
            subprocess.run(["bash", str(script), "stop", folder], check=False)


@pytest.fixture
def fresh_database(server_url: str) -> str:
    """A new, empty database on the server (Optuna has to create its tables in it), as a URL."""
    import sqlalchemy

    url = sqlalchemy.engine.make_url(server_url)
    name = f"sb3_maddpg_test_{uuid.uuid4().hex[:12]}"
    engine = sqlalchemy.create_engine(url, isolation_level="AUTOCOMMIT", poolclass=sqlalchemy.pool.NullPool)
    with engine.connect() as connection:
        connection.execute(sqlalchemy.text(f'CREATE DATABASE "{name}"'))
    engine.dispose()
    return url.set(database=name).render_as_string(hide_password=False)


# Generous limits: the workers take seconds on an idle machine, but far longer on one busy with other work
WORKER_TIMEOUT_S = 900


def _outputs(workers: list[subprocess.Popen]) -> list[str]:
    """Wait for the workers and return their outputs; kill them all if one has not ended within the limit."""
    try:
        return [worker.communicate(timeout=WORKER_TIMEOUT_S)[0] for worker in workers]
    except subprocess.TimeoutExpired:
        for worker in workers:
            worker.kill()
        pytest.fail(f"the worker processes had not ended after {WORKER_TIMEOUT_S} s")


def _python(code_or_args: list[str], cwd: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, *code_or_args], cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )


def test_workers_started_together_create_one_study(fresh_database: str, tmp_path: Path) -> None:
    # Three processes open the empty database at the same instant: without the retry, all but one fail while
    # creating Optuna's tables (IntegrityError from PostgreSQL's catalogue).
    # After its imports, each process waits until all three are ready, so that they open the database together.
    code = (
        "import os, sys, time\n"
        "import optuna, psycopg, sqlalchemy\n"
        "from sb3_maddpg.zoo.storage import create_shared_study\n"
        "ready = sys.argv[2]\n"
        "open(os.path.join(ready, str(os.getpid())), 'w').close()\n"
        "while len(os.listdir(ready)) < 3: time.sleep(0.001)\n"
        "print('study', create_shared_study(sys.argv[1], 'race')._study_id)\n"
    )
    ready = tmp_path / "ready"
    ready.mkdir()
    workers = [_python(["-c", code, fresh_database, str(ready)], tmp_path) for _ in range(3)]
    outputs = _outputs(workers)
    assert [worker.returncode for worker in workers] == [0, 0, 0], outputs
    study_ids = {line.split()[1] for output in outputs for line in output.splitlines() if line.startswith("study ")}
    assert len(study_ids) == 1, outputs


def test_two_optimize_workers_share_one_study(fresh_database: str, tmp_path: Path) -> None:
    import optuna

    study_name = "shared"
    workers = []
    for seed in (1, 2):
        folder = tmp_path / f"worker{seed}"
        folder.mkdir()
        argv = ["-m", "sb3_maddpg", "optimize", *TINY_OPTIMIZE, "--storage", fresh_database, "--study-name", study_name]
        workers.append(_python([*argv, "--seed", str(seed)], folder))
    outputs = _outputs(workers)
    assert [worker.returncode for worker in workers] == [0, 0], "\n\n".join(output[-3000:] for output in outputs)

    # A third process reads the study and its best trial
    reader = (
        "import sys, optuna\n"
        "study = optuna.load_study(study_name=sys.argv[2], storage=sys.argv[1])\n"
        "print('best', study.best_trial.number, study.best_value)\n"
    )
    read = subprocess.run([sys.executable, "-c", reader, fresh_database, study_name], capture_output=True, text=True)
    assert read.returncode == 0, read.stderr
    best_number = int(read.stdout.split()[1])

    study = optuna.load_study(study_name=study_name, storage=fresh_database)
    trials = study.get_trials(deepcopy=False)
    counted = [trial for trial in trials if trial.state in (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.PRUNED)]
    # --max-total-trials bounds the trials of all workers together, and none is left running
    assert len(counted) == MAX_TOTAL_TRIALS, [(trial.number, trial.state) for trial in trials]
    # a trial asked for by two workers passing RL Zoo's check together is recorded as not run
    assert all("not_run" in trial.user_attrs for trial in trials if trial.state == optuna.trial.TrialState.FAIL)
    assert not [trial for trial in trials if trial.state == optuna.trial.TrialState.RUNNING]
    numbers = [trial.number for trial in trials]
    assert len(set(numbers)) == len(numbers)
    # Both workers ran trials, and each reported its own
    workers_of_trials = {trial.user_attrs["worker"] for trial in trials}
    assert len(workers_of_trials) == 2, workers_of_trials
    for output in outputs:
        assert "Trials run by this worker" in output
        assert "Best trial:" in output
    assert best_number == study.best_trial.number
    assert study.best_trial.state == optuna.trial.TrialState.COMPLETE


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@pytest.mark.parametrize(
    ("storage", "message"),
    [
        ("postgresql://user:secret@:notaport/db", "malformed database URL"),
        ("postgress://user:secret@localhost/db", "unknown database kind 'postgress'"),
        ("postgresql://user:secret@/db", "must name a host and a database"),
        ("postgresql://user:secret@127.0.0.1:{port}/db", "cannot connect to the database server at 127.0.0.1:{port}"),
    ],
    ids=["malformed", "unknown-kind", "no-host", "unreachable"],
)
def test_bad_storage_is_one_line_without_the_password(
    storage: str, message: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    pytest.importorskip("psycopg")
    monkeypatch.chdir(tmp_path)
    from sb3_maddpg.__main__ import main

    port = _free_port()
    storage, message = storage.format(port=port), message.format(port=port)
    with pytest.raises(SystemExit) as exit_info:
        main(["optimize", "--env", "uav_coverage_fast_v0", "-conf", CONFIG, "--storage", storage])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("sb3_maddpg optimize: error: --storage:") and len(err.strip().splitlines()) == 1, err
    assert message in err and "secret" not in err


def test_missing_driver_names_the_extra(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    from sb3_maddpg.__main__ import main

    monkeypatch.chdir(tmp_path)
    # As if psycopg were not installed
    monkeypatch.setitem(sys.modules, "psycopg", None)
    with pytest.raises(SystemExit) as exit_info:
        main(["optimize", "--env", "uav_coverage_fast_v0", "-conf", CONFIG, "--storage", "postgresql://u:p@db.example/x"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert 'pip install "sb3_maddpg[zoo,postgres]"' in err and len(err.strip().splitlines()) == 1, err


def test_trials_beyond_max_total_trials_are_not_run() -> None:
    optuna = pytest.importorskip("optuna")
    from sb3_maddpg.zoo.storage import beyond_max_total_trials

    study = optuna.create_study(direction="maximize")
    # two workers each asked for a trial after 3 of a bound of 4: trial 3 runs, trial 4 must not
    for _ in range(3):
        study.tell(study.ask(), 1.0)
    third, fourth = study.ask(), study.ask()
    assert not beyond_max_total_trials(third, 4) and beyond_max_total_trials(fourth, 4)
    assert not beyond_max_total_trials(fourth, None) and not beyond_max_total_trials(fourth, 5)
    # a failed trial does not count (RL Zoo's count: complete, pruned, running)
    study.tell(third, state=optuna.trial.TrialState.FAIL)
    assert not beyond_max_total_trials(fourth, 4)
