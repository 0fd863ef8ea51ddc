"""The throwaway PostgreSQL server the labeling tests run against."""

from __future__ import annotations

import pytest
import sqlalchemy as sa

from langtraj.labeling.devdb import TemporaryPostgres


def _scalar(url: str, query: str) -> object:
    engine = sa.create_engine(url)
    try:
        with engine.connect() as conn:
            return conn.execute(sa.text(query)).scalar()
    finally:
        engine.dispose()


def test_server_answers_through_sqlalchemy(postgres_server: TemporaryPostgres) -> None:
    assert postgres_server.url.startswith("postgresql+psycopg://postgres@127.0.0.1:")
    assert _scalar(postgres_server.url, "select 1") == 1


def test_a_committed_row_survives_a_restart(postgres_server: TemporaryPostgres, postgres_url: str) -> None:
    engine = sa.create_engine(postgres_url)
    try:
        with engine.begin() as conn:
            conn.execute(sa.text("create table kept (id int primary key, note text)"))
            conn.execute(sa.text("insert into kept values (1, 'still here')"))
    finally:
        engine.dispose()
    postgres_server.restart()
    assert _scalar(postgres_url, "select note from kept where id = 1") == "still here"


def test_created_databases_are_isolated(postgres_server: TemporaryPostgres) -> None:
    first = postgres_server.create_database("isolation_first")
    second = postgres_server.create_database("isolation_second")
    assert first != second
    engine = sa.create_engine(first)
    try:
        with engine.begin() as conn:
            conn.execute(sa.text("create table only_in_first (x int)"))
    finally:
        engine.dispose()
    assert _scalar(first, "select current_database()") == "isolation_first"
    assert _scalar(second, "select current_database()") == "isolation_second"
    assert _scalar(first, "select to_regclass('only_in_first') is not null") is True
    assert _scalar(second, "select to_regclass('only_in_first') is not null") is False


@pytest.mark.parametrize("name", ["", "1abc", "a-b", 'x"; drop database postgres; --', "a b", "x" * 64])
def test_a_bad_database_name_is_refused(postgres_server: TemporaryPostgres, name: str) -> None:
    with pytest.raises(ValueError, match="bad database name"):
        postgres_server.create_database(name)
