"""Fixtures: the archive URL on each backend (archive tests); supervise as a module.

`archive_url` runs every test that takes it twice: on a fresh SQLite file, and on a fresh database
of a real PostgreSQL server that this session starts itself (initdb in a temporary directory, its
own port and socket directory, as the `postgres` user when run as root, stopped at the end). The
PostgreSQL runs are skipped, with the reason, only when no server can start here.
"""
import glob
import importlib.machinery
import importlib.util
import os
import pwd
import shutil
import socket
import subprocess
import sys
import tempfile
import uuid

import pytest

SCRIPTS = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(
    os.path.realpath(__file__)))), "scripts")
sys.path.insert(0, SCRIPTS)


@pytest.fixture(scope="module")
def supervise():
    """scripts/supervise loaded as a module (it has no .py name to import by)."""
    loader = importlib.machinery.SourceFileLoader("supervise_script",
                                                  os.path.join(SCRIPTS, "supervise"))
    spec = importlib.util.spec_from_loader("supervise_script", loader)
    module = importlib.util.module_from_spec(spec)
    loader.exec_module(module)
    return module


def _postgres_bin(name):
    found = shutil.which(name)
    if found:
        return found
    candidates = sorted(glob.glob("/usr/lib/postgresql/*/bin/" + name))
    return candidates[-1] if candidates else None


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class PostgresServer:
    """A throwaway PostgreSQL cluster; `url(db)` for a database on it."""

    def __init__(self):
        self.initdb = _postgres_bin("initdb")
        self.pg_ctl = _postgres_bin("pg_ctl")
        self.directory = None
        self.started = False
        self.reason = None
        self.as_user = None

    def _run(self, argv, **kwargs):
        if self.as_user:
            argv = ["runuser", "-u", self.as_user, "--"] + argv
        return subprocess.run(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              universal_newlines=True, timeout=120, **kwargs)

    def start(self):
        if not self.initdb or not self.pg_ctl:
            self.reason = "no PostgreSQL server installed (initdb/pg_ctl not found; " \
                          "tools/install_deps.sh installs postgresql)"
            return False
        if os.geteuid() == 0:
            # the server refuses to run as root
            try:
                pwd.getpwnam("postgres")
            except KeyError:
                self.reason = "running as root and there is no `postgres` user to run the server"
                return False
            self.as_user = "postgres"
        self.directory = tempfile.mkdtemp(prefix="accel_archive_pg_")
        data = os.path.join(self.directory, "data")
        self.socket_dir = os.path.join(self.directory, "socket")
        os.makedirs(self.socket_dir)
        if self.as_user:
            entry = pwd.getpwnam(self.as_user)
            for path in (self.directory, self.socket_dir):
                os.chown(path, entry.pw_uid, entry.pw_gid)
        init = self._run([self.initdb, "-D", data, "-A", "trust", "-U", "postgres",
                          "--encoding", "UTF8", "--no-sync"])
        if init.returncode != 0:
            self.reason = "initdb failed: %s" % init.stdout.strip().splitlines()[-1:]
            return False
        self.port = _free_port()
        options = "-p %d -k %s -c listen_addresses='' -c fsync=off -c max_connections=60" % (
            self.port, self.socket_dir)
        start = self._run([self.pg_ctl, "-D", data, "-o", options, "-l",
                           os.path.join(self.directory, "server.log"), "-w", "-t", "60", "start"])
        if start.returncode != 0:
            log = ""
            try:
                with open(os.path.join(self.directory, "server.log")) as f:
                    log = f.read().strip().splitlines()[-1:]
            except OSError:
                pass
            self.reason = "the PostgreSQL server did not start: %s %s" % (
                start.stdout.strip().splitlines()[-1:], log)
            return False
        self.data = data
        self.started = True
        return True

    def url(self, database, password=None):
        user = "postgres" + (":" + password if password else "")
        return "postgresql://%s@/%s?host=%s&port=%d" % (user, database, self.socket_dir,
                                                        self.port)

    def create_database(self):
        import psycopg2
        name = "archive_" + uuid.uuid4().hex[:12]
        connection = psycopg2.connect(dbname="postgres", user="postgres", host=self.socket_dir,
                                      port=self.port)
        connection.autocommit = True
        with connection.cursor() as cursor:
            cursor.execute("CREATE DATABASE %s" % name)
        connection.close()
        return name

    def stop(self):
        if self.started:
            self._run([self.pg_ctl, "-D", self.data, "-m", "immediate", "-w", "stop"])
            self.started = False
        if self.directory:
            shutil.rmtree(self.directory, ignore_errors=True)


@pytest.fixture(scope="session")
def postgres_server():
    server = PostgresServer()
    server.start()
    yield server
    server.stop()


@pytest.fixture(params=["sqlite", "postgresql"])
def archive_url(request, tmp_path):
    if request.param == "sqlite":
        return "sqlite:///" + str(tmp_path / "archive.db")
    server = request.getfixturevalue("postgres_server")
    if not server.started:
        pytest.skip(server.reason)
    return server.url(server.create_database())
