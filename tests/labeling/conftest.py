"""A throwaway PostgreSQL server for the labeling tests: one per session, a fresh database per test."""

from __future__ import annotations

import itertools
import os
from collections.abc import Iterator

import pytest

from langtraj.labeling.devdb import PostgresUnavailable, TemporaryPostgres

_DATABASE_NUMBERS = itertools.count()


@pytest.fixture(scope="session")
def postgres_server() -> Iterator[TemporaryPostgres]:
    """A running server; the tests that use it skip, with the reason, where PostgreSQL is not installed."""
    try:
        server = TemporaryPostgres()
    except PostgresUnavailable as exc:
        pytest.skip(str(exc))
    with server:
        yield server


@pytest.fixture
def postgres_url(postgres_server: TemporaryPostgres) -> str:
    """SQLAlchemy URL of a new, empty database on the session's server."""
    return postgres_server.create_database(f"test_{os.getpid()}_{next(_DATABASE_NUMBERS)}")
