"""Database connection: an engine for SQLite (the embedded default, one file) or PostgreSQL, brought to the
newest schema by the Alembic migrations in `migrations/`. See docs/labeling.md ('Database').
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path

from alembic import command
from alembic.config import Config
from sqlalchemy import Engine, create_engine, event
from sqlalchemy.engine import make_url
from sqlalchemy.exc import ArgumentError
from sqlalchemy.orm import Session, sessionmaker

from langtraj.errors import InputError

MIGRATIONS = Path(__file__).with_name("migrations")
DEFAULT_DB_NAME = "labeling.sqlite"
"""The embedded database's file, inside the dataset folder."""


SQLITE_PRAGMAS = (
    "PRAGMA journal_mode=WAL",
    "PRAGMA synchronous=FULL",
    "PRAGMA busy_timeout=30000",
    "PRAGMA foreign_keys=ON",
)


def utcnow() -> datetime:
    """Now, as the naive UTC datetime every table stores."""
    return datetime.now(UTC).replace(tzinfo=None)


def default_url(dataset: Path) -> str:
    return f"sqlite:///{(Path(dataset) / DEFAULT_DB_NAME).resolve()}"


def _sqlite_pragmas(dbapi_connection, _record) -> None:  # type: ignore[no-untyped-def]
    """WAL lets readers run beside the one writer; a busy writer waits instead of failing; FULL sync makes
    every acknowledged commit durable; SQLite enforces foreign keys only when asked."""
    cursor = dbapi_connection.cursor()
    for statement in SQLITE_PRAGMAS:
        cursor.execute(statement)
    cursor.close()


def make_engine(url: str) -> Engine:
    """An engine for `url` (sqlite:///FILE or postgresql+psycopg://...); a malformed or unsupported URL
    raises InputError naming --db."""
    try:
        parsed = make_url(url)
    except ArgumentError:
        raise InputError(f"not a database URL: {url!r}", where="--db") from None
    backend = parsed.get_backend_name()
    if backend == "sqlite":
        if not parsed.database or parsed.database == ":memory:":
            raise InputError("SQLite needs a file (sqlite:///PATH); an in-memory database is lost", where="--db")
        Path(parsed.database).parent.mkdir(parents=True, exist_ok=True)
        engine = create_engine(parsed, connect_args={"check_same_thread": False, "timeout": 30})
        event.listen(engine, "connect", _sqlite_pragmas)
        return engine
    if backend == "postgresql":
        if parsed.drivername == "postgresql":
            parsed = parsed.set(drivername="postgresql+psycopg")
        return create_engine(parsed, pool_size=20, max_overflow=40, pool_pre_ping=True)
    raise InputError(f"unsupported database {backend!r}: use sqlite:///FILE or postgresql://...", where="--db")


def migrate(engine: Engine, revision: str = "head") -> None:
    """Upgrade the schema to `revision` with Alembic (a no-op when it is there already)."""
    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS))
    with engine.begin() as connection:
        config.attributes["connection"] = connection
        command.upgrade(config, revision)


class Database:
    """An engine and its session factory; `session()` commits on success and rolls back on error."""

    def __init__(self, url: str, *, upgrade: bool = True):
        self.url = url
        self.engine = make_engine(url)
        if upgrade:
            migrate(self.engine)
        self._sessions = sessionmaker(self.engine, expire_on_commit=False)

    @contextmanager
    def session(self) -> Iterator[Session]:
        with self._sessions() as session, session.begin():
            yield session

    def dispose(self) -> None:
        self.engine.dispose()
