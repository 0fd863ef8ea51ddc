"""`langtraj label ...`: the InterDrive labeling tool for human annotators (docs/labeling.md).

serve a dataset over the web; add users (password from standard input) and tasks; show progress;
export accepted labels; or start a ready-made demo.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from langtraj.errors import InputError

INSTALL_HINT = 'the labeling tool needs the label extra: pip install -e ".[label]"'


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("label", help="the web tool for human InterDrive labels (serve, users, tasks, export)")
    verbs = p.add_subparsers(dest="label_verb", required=True, metavar="ACTION")

    def with_db(q: argparse.ArgumentParser) -> argparse.ArgumentParser:
        q.add_argument("dataset", type=Path, metavar="DATASET", help="InterDrive dataset folder (interdrive build)")
        q.add_argument("--db", help="database URL (default: SQLite file labeling.sqlite in DATASET); postgresql://...")
        return q

    q = with_db(verbs.add_parser("serve", help="serve the labeling web app"))
    _serve_options(q)
    q.set_defaults(func=run_serve)

    q = verbs.add_parser("demo", help="synthesize a few windows, create demo accounts (passwords printed), serve")
    q.add_argument("--out", type=Path, default=Path("langtraj-label-demo"), help="folder (default langtraj-label-demo)")
    q.add_argument("--db", help="database URL (default: SQLite in the demo's dataset folder)")
    q.add_argument("--windows", type=int, default=4, help="windows to synthesize (default 4)")
    q.add_argument("--overlap", type=int, default=2, help="annotators per window (default 2)")
    q.add_argument("--seed", type=int, default=0)
    q.add_argument("--no-serve", action="store_true", help="prepare only")
    _serve_options(q)
    q.set_defaults(func=run_demo)

    q = with_db(verbs.add_parser("user", help="add a user; the password is read from standard input"))
    q.add_argument("name")
    q.add_argument("--role", default="annotator", help="annotator, reviewer or admin (default annotator)")
    q.set_defaults(func=run_user)

    q = with_db(verbs.add_parser("tasks", help="add windows of the dataset as tasks"))
    q.add_argument("--scenario", nargs="+", metavar="ID", help="scenario ids (default: every window)")
    q.add_argument("--overlap", type=int, default=2, help="annotators per window (default 2)")
    q.add_argument("--quorum", type=int, help="matching annotations that accept a window (default: the overlap)")
    q.set_defaults(func=run_tasks)

    q = with_db(verbs.add_parser("progress", help="progress and agreement, as JSON"))
    q.set_defaults(func=run_progress)

    q = with_db(verbs.add_parser("export", help="accepted labels to InterDrive JSON, an audit file, and the dataset"))
    q.add_argument("--out", type=Path, required=True, help="folder of {scenario_id}.json files")
    q.add_argument("--audit", type=Path, help="audit file (default: OUT/../labeling-audit.json)")
    q.add_argument("--into", action="store_true", help="also import the labels into DATASET as human labels")
    q.set_defaults(func=run_export)


def _serve_options(q: argparse.ArgumentParser) -> None:
    q.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    q.add_argument("--port", type=int, default=8000, help="port (default 8000)")
    q.add_argument("--lock-minutes", type=float, default=30.0, help="how long a claimed window stays locked")


@contextlib.contextmanager
def _database(args: argparse.Namespace) -> Iterator[Any]:
    """The dataset's labeling database (checked, migrated), disposed of after the block."""
    try:
        from langtraj.labeling.db import Database, default_url
    except ImportError as exc:
        raise InputError(f"{INSTALL_HINT} ({exc.name} is missing)") from None
    if not (args.dataset / "manifest.json").is_file():
        raise InputError(
            "not an InterDrive dataset folder (no manifest.json; run langtraj interdrive build)", path=args.dataset
        )
    db = Database(args.db or default_url(args.dataset))
    try:
        yield db
    finally:
        db.dispose()


def _serve(dataset: Path, db_url: str | None, args: argparse.Namespace) -> int:
    try:
        import uvicorn

        from langtraj.labeling.app import ServerConfig, create_app
    except ImportError as exc:
        raise InputError(f"{INSTALL_HINT} ({exc.name} is missing)") from None
    if args.lock_minutes <= 0:
        raise InputError(f"must be positive, got {args.lock_minutes}", where="--lock-minutes")
    app = create_app(ServerConfig(dataset, db_url, lock_minutes=args.lock_minutes))
    print(f"labeling {dataset} at http://{args.host}:{args.port}/ (Ctrl-C stops)", flush=True)
    uvicorn.run(app, host=args.host, port=args.port, log_level="warning")
    return 0


def run_serve(args: argparse.Namespace) -> int:
    with _database(args):  # checks the dataset and the URL, migrates
        pass
    return _serve(args.dataset, args.db, args)


def run_demo(args: argparse.Namespace) -> int:
    try:
        from langtraj.labeling.demo import prepare_demo
    except ImportError as exc:
        raise InputError(f"{INSTALL_HINT} ({exc.name} is missing)") from None
    if args.windows < 1 or args.overlap < 1:
        raise InputError("--windows and --overlap must be at least 1")
    setup = prepare_demo(args.out, args.db, args.windows, args.seed, args.overlap)
    print(f"dataset {setup.dataset}: {setup.tasks_added} new tasks")
    for name, password in setup.passwords.items():
        print(f"  user {name:10s} password {password}")
    if not setup.passwords:
        print("  the demo accounts exist already (their passwords were printed when they were made)")
    if args.no_serve:
        return 0
    return _serve(setup.dataset, args.db, args)


def run_user(args: argparse.Namespace) -> int:
    with _database(args) as db:
        from langtraj.labeling.auth import create_user, parse_role

        role = parse_role(args.role)
        password = sys.stdin.readline().rstrip("\r\n")
        with db.session() as session:
            create_user(session, args.name, password, role)
    print(f"added {role.value} {args.name}")
    return 0


def run_tasks(args: argparse.Namespace) -> int:
    with _database(args) as db:
        from langtraj.labeling.tasks import add_tasks

        added, present = add_tasks(db, args.dataset, args.scenario, args.overlap, args.quorum)
    print(f"added {added} tasks ({present} were there already)")
    return 0


def run_progress(args: argparse.Namespace) -> int:
    with _database(args) as db:
        from langtraj.labeling.review import agreement
        from langtraj.labeling.tasks import progress

        print(json.dumps({"progress": progress(db), "agreement": agreement(db)}, indent=1))
    return 0


def run_export(args: argparse.Namespace) -> int:
    with _database(args) as db:
        from langtraj.labeling.export import export_accepted

        result = export_accepted(db, args.out, args.audit, args.dataset if args.into else None)
    print(
        f"wrote {result.written} InterDrive files to {args.out} ({result.pending} windows not accepted yet)"
        + (f"; {result.imported} windows updated in {args.dataset}" if args.into else "")
    )
    return 0
