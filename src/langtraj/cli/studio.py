"""`langtraj studio [FILES|DIRS...] [--checkpoint CKPT] [--port 8000] [--host 127.0.0.1] [--data DIR]`: LangTraj
Studio, the local web app in which a test engineer picks a scene, writes prompts, simulates, watches and judges
the rollouts and keeps the case in a test suite (docs/studio.md). It has no accounts: it listens on 127.0.0.1
unless told otherwise, and warns when told otherwise."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from langtraj.errors import InputError

INSTALL_HINT = 'the studio needs FastAPI and uvicorn (the label extra): pip install -e ".[label]"'
LOCAL_HOSTS = ("127.0.0.1", "localhost", "::1")


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("studio", help="the web app: prompts to judged closed-loop rollouts and suite cases")
    p.add_argument(
        "paths",
        nargs="*",
        type=Path,
        metavar="FILES|DIRS",
        help="scenario files, or folders searched recursively (default: the current folder)",
    )
    p.add_argument("--checkpoint", type=Path, help="trained checkpoint (default: the shipped one)")
    p.add_argument("--data", type=Path, default=Path("studio-data"), help="jobs and suites (default ./studio-data)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    p.add_argument("--port", type=int, default=8000, help="port (default 8000)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    try:
        import uvicorn

        from langtraj.studio.app import StudioConfig, create_app
    except ImportError as exc:
        raise InputError(f"{INSTALL_HINT} ({exc.name} is missing)") from None
    if args.checkpoint is not None and not args.checkpoint.is_file():
        raise InputError("no such file", path=args.checkpoint, where="--checkpoint")
    if not 0 < args.port < 65536:
        raise InputError(f"must be in 1..65535, got {args.port}", where="--port")
    paths = tuple(args.paths) or (Path("."),)
    if args.host not in LOCAL_HOSTS:
        print(
            f"warning: the studio has no accounts; anyone who can reach {args.host}:{args.port} can run simulations "
            "and write into its data folder",
            file=sys.stderr,
        )
    app = create_app(StudioConfig(paths, args.checkpoint, args.data))
    scenes = len(app.state.catalog.entries)
    print(
        f"studio: {scenes} scenes, data in {args.data}, at http://{args.host}:{args.port}/ (Ctrl-C stops)", flush=True
    )
    uvicorn.run(app, host=args.host, port=args.port, log_level="warning")
    return 0
