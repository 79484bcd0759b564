"""Fixtures of the calibration database tests:

- ``pg_server``: a real PostgreSQL server started for the test session (``initdb`` + ``pg_ctl`` from
  ``pg_ctl`` on PATH or ``/usr/lib/postgresql/*/bin``, Debian's ``postgresql`` package; as root the
  server runs as the ``postgres`` user, which ``initdb`` requires), stopped at the end; the tests
  that need it are skipped, with the reason, where no server can be started;
- ``pg_url``: a fresh database on it per test (``pytest_postgresql.janitor.DatabaseJanitor``);
- ``db_url``: parametrized over both back-ends: an SQLite file and a PostgreSQL database;
- ``synthetic_text``: the parameter file text of a calibration with given values and 1 sigma (of
  ``lab_synthetic.synthetic_result``).
"""

from __future__ import annotations

import glob
import os
import pwd
import re
import shutil
import socket
import subprocess
import tempfile
import uuid
from dataclasses import dataclass
from pathlib import Path

import pytest
from lab_synthetic import synthetic_result

from inscal.lab import param_file_text


def pg_bindir() -> Path | None:
    """The folder of the newest PostgreSQL server binaries (pg_ctl, initdb), None if none."""
    found = shutil.which("pg_ctl")
    if found:
        return Path(found).parent
    cands = glob.glob("/usr/lib/postgresql/*/bin/pg_ctl")

    def version(p):
        m = re.search(r"/postgresql/(\d+)", p)
        return int(m.group(1)) if m else 0

    return Path(max(cands, key=version)).parent if cands else None


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@dataclass
class PgServer:
    host: str
    port: int
    user: str

    def url(self, dbname: str) -> str:
        return f"postgresql://{self.user}@{self.host}:{self.port}/{dbname}"


@pytest.fixture(scope="session")
def pg_server():
    bindir = pg_bindir()
    if bindir is None:
        pytest.skip("no PostgreSQL server binaries (pg_ctl on PATH or /usr/lib/postgresql/*/bin): install Debian's "
                    "postgresql package (.ci/run does when it can)")
    try:
        import psycopg  # noqa: F401
        import pytest_postgresql  # noqa: F401
    except ImportError as exc:
        pytest.skip(f"PostgreSQL tests need the test extra (pip install -e '.[test]'): {exc}")
    prefix: list[str] = []
    base = Path(tempfile.mkdtemp(prefix="inscal-pg-"))
    if os.geteuid() == 0:  # initdb and postgres refuse to run as root
        for name in ("postgres", "nobody"):
            try:
                pw = pwd.getpwnam(name)
                break
            except KeyError:
                pw = None
        runuser = shutil.which("runuser") or shutil.which("setpriv")
        if pw is None or runuser is None:
            shutil.rmtree(base, ignore_errors=True)
            pytest.skip("running as root without a 'postgres' user and runuser: PostgreSQL cannot be started")
        os.chown(base, pw.pw_uid, pw.pw_gid)
        prefix = ([runuser, "-u", pw.pw_name, "--"] if runuser.endswith("runuser")
                  else [runuser, f"--reuid={pw.pw_uid}", f"--regid={pw.pw_gid}", "--clear-groups"])
    data, log = base / "data", base / "server.log"
    port = free_port()
    env = {**os.environ, "LC_ALL": "C", "LANG": "C"}
    try:
        subprocess.run(prefix + [str(bindir / "initdb"), "-D", str(data), "-U", "postgres", "-A", "trust", "--no-sync",
                                 "-E", "UTF8"], check=True, capture_output=True, env=env, timeout=120)
        subprocess.run(prefix + [str(bindir / "pg_ctl"), "-D", str(data), "-l", str(log), "-w", "-t", "60", "-o",
                                 f"-F -p {port} -k {base} -c listen_addresses=127.0.0.1 -c max_connections=60",
                                 "start"], check=True, capture_output=True, env=env, timeout=120)
    except (subprocess.CalledProcessError, subprocess.TimeoutExpired, OSError) as exc:
        detail = getattr(exc, "stderr", b"") or b""
        shutil.rmtree(base, ignore_errors=True)
        pytest.skip(f"cannot start a PostgreSQL server from {bindir}: {exc} {detail.decode(errors='replace')[-300:]}")
    try:
        yield PgServer("127.0.0.1", port, "postgres")
    finally:
        subprocess.run(prefix + [str(bindir / "pg_ctl"), "-D", str(data), "-m", "immediate", "-w", "stop"],
                       capture_output=True, env=env, timeout=120, check=False)
        shutil.rmtree(base, ignore_errors=True)


@pytest.fixture
def pg_url(pg_server):
    """A fresh, empty PostgreSQL database (dropped after the test)."""
    from pytest_postgresql.janitor import DatabaseJanitor

    name = f"inscal_{uuid.uuid4().hex[:12]}"
    with DatabaseJanitor(user=pg_server.user, host=pg_server.host, port=pg_server.port, dbname=name):
        yield pg_server.url(name)


@pytest.fixture(params=["sqlite", "postgresql"])
def db_url(request, tmp_path):
    """The URL of an empty database of each back-end (an SQLite file path; a PostgreSQL URL)."""
    if request.param == "sqlite":
        return str(tmp_path / "calib.sqlite")
    return request.getfixturevalue("pg_url")


@pytest.fixture(scope="session")
def synthetic_text():
    """``synthetic_text(values, sigma, method="manual", data_hash=None)``: a parameter file's text."""

    def make(values: dict, sigma: dict, method: str = "manual", data_hash: str | None = None) -> str:
        return param_file_text(synthetic_result(values, sigma, method), "run.h5", data_hash, {"imu_serial": "synthetic"})

    return make
