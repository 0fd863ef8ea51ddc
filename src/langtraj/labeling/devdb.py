"""A throwaway PostgreSQL server (own data dir, free port) for the labeling tool's tests and benchmarks.

See docs/labeling.md.
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
from pathlib import Path
from types import TracebackType

import psycopg
from psycopg import sql

_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,62}")


class PostgresUnavailable(RuntimeError):
    """No PostgreSQL server binaries (or no way to run them) on this machine."""


def _bin_dir() -> Path:
    """The directory holding initdb and pg_ctl: from PATH, else the newest /usr/lib/postgresql/*/bin."""
    on_path = shutil.which("initdb")
    if on_path and shutil.which("pg_ctl"):
        return Path(os.path.realpath(on_path)).parent
    found = [Path(p).parent for p in glob.glob("/usr/lib/postgresql/*/bin/initdb")]
    found = [d for d in found if (d / "pg_ctl").exists() and d.parent.name.isdigit()]
    if not found:
        raise PostgresUnavailable("PostgreSQL is not installed (no initdb/pg_ctl on PATH or in /usr/lib/postgresql)")
    return max(found, key=lambda d: int(d.parent.name))


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class TemporaryPostgres:
    """Start a PostgreSQL server in a fresh temporary directory; stop it and delete its data on exit.

    As root the server runs as the `postgres` system user (PostgreSQL refuses to run as root).
    """

    def __init__(self) -> None:
        self._bin = _bin_dir()
        self._as_user: list[str] = []
        if os.geteuid() == 0:
            runuser = shutil.which("runuser")
            if runuser is None:
                raise PostgresUnavailable("running as root and `runuser` is missing to run PostgreSQL as `postgres`")
            try:
                entry = pwd.getpwnam("postgres")
            except KeyError:
                raise PostgresUnavailable("running as root and there is no `postgres` system user") from None
            self._as_user = [runuser, "-u", "postgres", "--"]
            self._uid, self._gid = entry.pw_uid, entry.pw_gid
        self._dir: Path | None = None
        self.port = 0

    @property
    def url(self) -> str:
        """SQLAlchemy URL of the server's `postgres` database."""
        return f"postgresql+psycopg://postgres@127.0.0.1:{self.port}/postgres"

    def _run(self, *args: str) -> None:
        assert self._dir is not None
        cmd = [*self._as_user, str(self._bin / args[0]), *args[1:]]
        done = subprocess.run(cmd, cwd=self._dir, capture_output=True, text=True, check=False)
        if done.returncode != 0:
            log = self._dir / "server.log"
            tail = log.read_text(errors="replace")[-2000:] if log.exists() else ""
            raise RuntimeError(f"{' '.join(cmd)} failed ({done.returncode}): {done.stdout}{done.stderr}{tail}")

    def _pg_ctl(self, action: str, *extra: str) -> None:
        assert self._dir is not None
        self._run("pg_ctl", action, "-D", str(self._dir / "data"), "-l", str(self._dir / "server.log"), *extra)

    def __enter__(self) -> TemporaryPostgres:
        self._dir = Path(tempfile.mkdtemp(prefix="langtraj-pg-"))
        try:
            if self._as_user:
                os.chown(self._dir, self._uid, self._gid)
            # --no-sync only skips initdb's own final flush; the server runs with fsync on.
            data = self._dir / "data"
            self._run("initdb", "--no-sync", "-D", str(data), "-U", "postgres", "-E", "UTF8", "--locale=C")
            (data / "pg_hba.conf").write_text(
                "local all all trust\nhost all all 127.0.0.1/32 trust\n", encoding="utf-8"
            )
            self.port = _free_port()
            with open(data / "postgresql.conf", "a", encoding="utf-8") as conf:
                conf.write(
                    f"\nlisten_addresses = '127.0.0.1'\nport = {self.port}\n"
                    f"unix_socket_directories = '{self._dir}'\nfsync = on\n"
                )
            self._pg_ctl("start", "-w", "-t", "60")
        except BaseException:
            if (self._dir / "data" / "postmaster.pid").exists():  # started, but not answering in time
                stop = [str(self._bin / "pg_ctl"), "stop", "-D", str(self._dir / "data"), "-m", "immediate"]
                subprocess.run([*self._as_user, *stop], capture_output=True, check=False)
            shutil.rmtree(self._dir, ignore_errors=True)
            raise
        return self

    def restart(self) -> None:
        """Stop the server (fast shutdown) and start it again on the same port and data."""
        self._pg_ctl("restart", "-w", "-t", "60", "-m", "fast")

    def create_database(self, name: str) -> str:
        """Create database `name` (a plain identifier) and return its SQLAlchemy URL."""
        if not _IDENTIFIER.fullmatch(name):
            raise ValueError(f"bad database name {name!r}: letters, digits and _ only, not starting with a digit")
        conninfo = f"host=127.0.0.1 port={self.port} user=postgres dbname=postgres"
        with psycopg.connect(conninfo, autocommit=True) as conn:
            conn.execute(sql.SQL("CREATE DATABASE {}").format(sql.Identifier(name)))
        return f"postgresql+psycopg://postgres@127.0.0.1:{self.port}/{name}"

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        if self._dir is None:
            return
        try:
            self._pg_ctl("stop", "-w", "-t", "60", "-m", "fast")
        finally:
            shutil.rmtree(self._dir, ignore_errors=True)
            self._dir = None
