"""`impactlab replay LOG... [-o out.rrd] [--analysis results/] [--spawn|--serve|--connect]`."""

from __future__ import annotations

import argparse
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

from impactlab.cli.options import path
from impactlab.text import terminal_text

DEFAULT_URL = "rerun+http://127.0.0.1:9876/proxy"


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the `replay` subcommand to the command line's subparsers."""
    p = sub.add_parser(
        "replay",
        help="convert logs (and their analysis) into Rerun recordings (.rrd) and view them",
        description="Convert each log into a Rerun recording next to it (or into -o FOLDER); "
        "with -o FILE.rrd, all runs go into one recording, one subtree per run, to compare "
        "them. Open a recording with `rerun FILE.rrd`.",
    )
    p.add_argument("logs", nargs="+", type=path, metavar="LOG", help="logs, folders or globs")
    p.add_argument(
        "-o",
        "--out",
        type=path,
        help="FILE.rrd: one recording of all runs; otherwise a folder for one .rrd per log",
    )
    p.add_argument(
        "--analysis",
        type=path,
        metavar="DIR",
        help="analysis output folder (bounces.parquet, collisions.parquet) for the event texts",
    )
    view = p.add_mutually_exclusive_group()
    view.add_argument("--spawn", action="store_true", help="also stream to a new Rerun viewer")
    view.add_argument(
        "--serve", action="store_true", help="serve the recordings to a web viewer (blocks)"
    )
    view.add_argument(
        "--connect",
        nargs="?",
        const=DEFAULT_URL,
        metavar="ADDR",
        help=f"also stream to a running viewer (default {DEFAULT_URL}); put it last",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Write the recordings (and stream or serve them); exit 1 when a log failed."""
    from impactlab.logs.inputs import require_logs

    logs = list(args.logs)
    connect = args.connect
    if connect is not None and Path(connect).is_file():  # `--connect LOG`: LOG is no address
        logs.append(Path(connect))
        connect = DEFAULT_URL
    paths, empty = require_logs(logs)  # no input names a log: exit 2 before rerun is loaded

    import rerun as rr

    from impactlab.errors import ImpactlabError, LogError
    from impactlab.progress import ConsoleProgress
    from impactlab.replay.recordings import replay_logs

    failed: list[ImpactlabError] = [LogError(where, why) for where, why in empty]
    for error in failed:
        print(terminal_text(f"impactlab: error: {error}"), file=sys.stderr)
    sinks: list[Callable[[], rr.GrpcSink]] = []
    if args.spawn:
        rr.spawn(connect=False, executable_path=_rerun_executable())
        sinks.append(rr.GrpcSink)
    elif connect is not None:
        url = connect if "://" in connect else f"rerun+http://{connect}/proxy"
        sinks.append(lambda: rr.GrpcSink(url))
    with ConsoleProgress() as progress:
        written = replay_logs(
            paths,
            out=args.out,
            analysis_dir=args.analysis,
            viewer_sinks=sinks,
            on_error=failed.append,
            progress=progress,
        )
    for rrd in written:
        print(terminal_text(f"wrote {rrd}"))
    if args.serve and written:
        subprocess.run([_rerun_executable() or "rerun", "--serve-web", *map(str, written)])
    return 1 if failed else 0


def _rerun_executable() -> str | None:
    """The `rerun` CLI of this Python environment (None: rely on PATH)."""
    candidate = Path(sys.executable).parent / "rerun"
    return str(candidate) if candidate.exists() else None
