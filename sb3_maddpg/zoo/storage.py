"""
Optuna storages for ``optimize``: the checks made before RL Zoo runs, and the creation of a shared study that several
worker processes (on one machine or many) may attempt at the same moment.

- no ``--storage``: a local SQLite file (``logs/maddpg/optuna.db``), for one process at a time;
- ``--storage PATH.log``: RL Zoo opens Optuna's ``JournalStorage`` on that file, for several processes on one machine;
- ``--storage postgresql://USER:PASSWORD@HOST:PORT/DB`` (or any SQLAlchemy URL): Optuna's ``RDBStorage``, for workers
  on several machines.
"""

import os
import random
import re
import socket
import time
from typing import Any

from sb3_maddpg.zoo.registry import UsageError

POSTGRES_EXTRA = 'pip install "sb3_maddpg[zoo,postgres]"'
URL_FORMS = "postgresql://USER:PASSWORD@HOST:PORT/DB, sqlite:///PATH.db, or a journal file PATH.log"
# How long the check waits for a database server that does not answer
CONNECT_TIMEOUT_S = 10
# Workers starting at the same moment race to create Optuna's tables and the study; the losers retry
CREATION_ATTEMPTS = 8
# A worker's running trial records a heartbeat this often (seconds); a trial whose last heartbeat is older than the
# grace period belongs to a worker that died (killed, out of memory, a node lost): it is failed and its parameters
# are tried again (Optuna's RetryHeartbeatStaleTrialCallback), at most MAX_RETRY times
HEARTBEAT_INTERVAL_S = 60
HEARTBEAT_GRACE_S = 180
MAX_RETRY = 2
_PASSWORD = re.compile(r"(://[^:/@\s]*:)[^@/\s]*@")


def mask_password(text: str) -> str:
    """
    :param text: a database URL, or a command line holding one
    :return: the text with every URL's password replaced by ``***``
    """
    return _PASSWORD.sub(r"\1***@", text)


def is_database_url(storage: str | None) -> bool:
    """
    :param storage: the ``--storage`` value
    :return: whether it is a SQLAlchemy database URL (not a file name, not a ``.log`` journal file)
    """
    return storage is not None and "://" in storage


def _driver_hint(backend: str, driver: str) -> str:
    if backend == "postgresql" and driver == "psycopg":
        return f"install the postgres extra: {POSTGRES_EXTRA}"
    if backend == "postgresql":
        return (
            f"install {driver}, or use a postgresql:// URL (driver psycopg) and install the postgres extra: {POSTGRES_EXTRA}"
        )
    if backend in ("mysql", "mariadb"):
        return "install a MySQL driver, e.g. pip install pymysql, and use a mysql+pymysql:// URL"
    return "install the database driver SQLAlchemy names for this URL"


def check_storage(storage: str) -> None:
    """
    Check an ``optimize --storage`` URL before any work is done: that it parses, that its database driver is
    installed, and that its server answers.

    :param storage: a SQLAlchemy database URL
    :raises UsageError: naming what is wrong, in one line (passwords hidden)
    """
    import sqlalchemy
    from sqlalchemy.engine import make_url

    try:
        url = make_url(storage)
    except (sqlalchemy.exc.ArgumentError, ValueError) as error:
        shown = mask_password(storage)
        raise UsageError(f"--storage: malformed database URL {shown!r} ({error}); expected {URL_FORMS}") from error
    shown = url.render_as_string(hide_password=True)
    backend = url.get_backend_name()
    try:
        dialect = url.get_dialect()
    except sqlalchemy.exc.NoSuchModuleError as error:
        raise UsageError(f"--storage: unknown database kind {url.drivername!r} in {shown}; expected {URL_FORMS}") from error
    if backend == "sqlite":
        return
    if not (url.host or url.query.get("host")) or not url.database:
        raise UsageError(f"--storage: {shown} must name a host and a database; expected {URL_FORMS}")
    try:
        dialect.import_dbapi()
    except ImportError as error:
        raise UsageError(
            f"--storage: no driver for {url.drivername} URLs ({error}); {_driver_hint(backend, url.get_driver_name())}"
        ) from error

    address = f"{url.host}:{url.port or _default_port(backend)}"
    connect_args: dict[str, Any] = {"connect_timeout": CONNECT_TIMEOUT_S} if backend in ("postgresql", "mysql") else {}
    engine = sqlalchemy.create_engine(url, connect_args=connect_args, poolclass=sqlalchemy.pool.NullPool)
    try:
        with engine.connect():
            pass
    except sqlalchemy.exc.DBAPIError as error:
        reason = " ".join(str(error.orig).split()) if error.orig is not None else type(error).__name__
        raise UsageError(f"--storage: cannot connect to the database server at {address} for {shown}: {reason}") from error
    finally:
        engine.dispose()


def _default_port(backend: str) -> int | str:
    return {"postgresql": 5432, "mysql": 3306, "mariadb": 3306}.get(backend, "default port")


def create_shared_study(storage: Any, study_name: str | None, direction: str = "maximize") -> Any:
    """
    Create the study in a database storage, or load it where another worker has, as ``optuna.create_study(...,
    load_if_exists=True)`` does, but safe for workers that start at the same moment: Optuna creates its tables when it
    first opens an empty database, and two processes doing so together make one of them fail (``IntegrityError`` or
    ``ProgrammingError`` from PostgreSQL's catalogue, ``OperationalError: table ... already exists`` from SQLite).
    Such a worker waits a moment and tries again, by which time the tables (and the study) exist.

    :param storage: a SQLAlchemy database URL, or an ``RDBStorage`` on one
    :param study_name: the study's name
    :param direction: ``"maximize"`` (RL Zoo maximises the mean evaluation reward)
    :return: the ``optuna.Study``
    """
    import optuna
    import sqlalchemy

    races = (
        sqlalchemy.exc.IntegrityError,
        sqlalchemy.exc.ProgrammingError,
        sqlalchemy.exc.OperationalError,
        optuna.exceptions.DuplicatedStudyError,
    )
    for attempt in range(CREATION_ATTEMPTS):
        try:
            return optuna.create_study(storage=storage, study_name=study_name, load_if_exists=True, direction=direction)
        except races:
            if attempt == CREATION_ATTEMPTS - 1:
                raise
            # Random back-off, so that the workers that lost do not collide again
            time.sleep(0.2 * (attempt + 1) * (1.0 + random.random()))
    raise AssertionError("unreachable")


def beyond_max_total_trials(trial: Any, max_total_trials: int | None) -> bool:
    """
    Whether a new trial would exceed ``--max-total-trials`` over all workers. RL Zoo's ``MaxTrialsCallback`` checks
    the count after each trial, and two workers that pass that check together both ask for one more trial. Optuna
    numbers the trials in the order it creates them, so the trials beyond the bound are those with
    ``max_total_trials`` counted trials (complete, pruned or running: RL Zoo's count) before them.

    :param trial: the ``optuna.Trial`` just created
    :param max_total_trials: the bound, or None
    :return: whether the trial must not run
    """
    if max_total_trials is None:
        return False
    from optuna.trial import TrialState

    counted = (TrialState.COMPLETE, TrialState.PRUNED, TrialState.RUNNING)
    earlier = [other for other in trial.study.get_trials(deepcopy=False, states=counted) if other.number < trial.number]
    return len(earlier) >= max_total_trials


def _process_exists(pid: int) -> bool:
    """Whether a process of this id runs on this machine (signal 0 checks without sending anything)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process: it exists
        return True
    return True


def fail_dead_workers_trials(study: Any) -> list[int]:
    """
    On a journal file storage (``--storage PATH.log``, workers on one machine), which keeps no heartbeat: fail the
    RUNNING trials whose worker (the ``host:pid`` of the trial's ``worker`` attribute) ran on this machine and no longer
    exists, so that a killed worker's trial does not stay RUNNING for ever and count towards ``--max-total-trials``.
    Its parameters are enqueued once more, as ``RetryHeartbeatStaleTrialCallback`` does on a database storage (the
    retry names the failed trial in ``failed_trial``). A trial of a worker on another machine, or of a process id
    reused since, is left as it is.

    :param study: the Optuna study
    :return: the numbers of the trials failed
    """
    from optuna.exceptions import UpdateFinishedTrialError
    from optuna.trial import TrialState

    host = socket.gethostname()
    failed = []
    for trial in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
        worker_host, _, pid = str(trial.user_attrs.get("worker", "")).rpartition(":")
        if worker_host != host or not pid.isdigit() or _process_exists(int(pid)):
            continue
        try:
            study._storage.set_trial_state_values(trial._trial_id, state=TrialState.FAIL)
        except (UpdateFinishedTrialError, RuntimeError):
            continue  # another worker failed it first
        if "failed_trial" not in trial.user_attrs:  # retried once at most
            study.enqueue_trial(trial.params, user_attrs={"failed_trial": trial.number})
        failed.append(trial.number)
    return failed
