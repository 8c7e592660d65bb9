"""``tunnel-contact``: command-line entry point (argument parsing only).

The commands themselves live in :mod:`workflows.commands`; ``serve`` starts the
REST service of :mod:`service.server`.
"""
from __future__ import annotations

import argparse
import os
import sys


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``tunnel-contact``."""
    parser = argparse.ArgumentParser(
        prog="tunnel-contact",
        description="Tunnel lining / ground unilateral contact: solve cases and sweeps, show "
                    "results, serve the REST API.")
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="more log output (-v info, -vv debug)")
    from solver.version import SOFTWARE_VERSION

    parser.add_argument("--version", action="version", version=f"tunnel-contact {SOFTWARE_VERSION}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def results(p: argparse.ArgumentParser) -> None:
        p.add_argument("--results", default="results", metavar="DIR",
                       help="result store folder (default: ./results)")

    def scheduler(p: argparse.ArgumentParser) -> None:
        p.add_argument("--scheduler", default=os.environ.get("DASK_SCHEDULER_ADDRESS") or None,
                       metavar="ADDR", help="dask scheduler address (default: $DASK_SCHEDULER_ADDRESS; "
                                            "unset: an embedded LocalCluster)")

    p = sub.add_parser("run", help="solve one case and store it")
    p.add_argument("case", nargs="?", metavar="CASE.json", help="case file (default: the default case)")
    p.add_argument("--force", action="store_true", help="recompute even if stored")
    p.add_argument("--retry-failed", action="store_true",
                   help="recompute the case if it failed before (else its recorded failure is shown)")
    results(p)

    p = sub.add_parser("sweep", help="solve every case of a sweep on dask, print a comparison table")
    p.add_argument("sweep", metavar="SWEEP.json", help="sweep file")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--retry-failed", action="store_true",
                   help="recompute the cases that failed before (else their recorded failures are shown)")
    scheduler(p)
    results(p)

    p = sub.add_parser("show", help="print a stored case's summary and write its plots")
    p.add_argument("case_id", metavar="CASE_ID", help="a case id or a unique prefix of one (4+ hex digits)")
    results(p)

    p = sub.add_parser("report", help="write a stored case's printable report (PDF)")
    p.add_argument("case_id", metavar="CASE_ID", help="a case id or a unique prefix of one (4+ hex digits)")
    p.add_argument("-o", "--output", default=None, metavar="FILE.pdf",
                   help="where to write it (default: CASE_ID.pdf in the current folder)")
    for field in ("project", "job", "author", "checker", "revision", "date"):
        p.add_argument(f"--{field}", default=None, help=f"the title block's {field}"
                       + (" (default today)" if field == "date" else ""))
    results(p)

    p = sub.add_parser("list", help="list the cases of the result store (done and failed) as a table")
    results(p)

    p = sub.add_parser("search", help="find the smallest design value meeting a requirement over a set of cases")
    p.add_argument("search", metavar="SEARCH.json", help="search file (SPEC §8)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    scheduler(p)
    results(p)

    p = sub.add_parser("reliability", help="probability of failure by FORM, subset simulation or AK-MCS")
    p.add_argument("study", metavar="STUDY.json", help="reliability study file (SPEC §9.6)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    scheduler(p)
    results(p)

    _study_and_serve_commands(sub, results, scheduler)
    return parser


def _study_and_serve_commands(sub, results, scheduler) -> None:
    """The ``analyse`` and ``serve`` commands."""
    p = sub.add_parser("analyse", help="sensitivity or reliability of a stored sweep's result")
    p.add_argument("sweep_id", metavar="SWEEP_ID", help="a sweep id or a unique prefix of one")
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--sensitivity", metavar="OUTPUT", help="sensitivity indices of this result scalar")
    what.add_argument("--reliability", metavar="OUTPUT", help="probability that this result scalar exceeds --limit")
    p.add_argument("--limit", type=float, default=1.0, help="the limit of --reliability (default 1)")
    results(p)

    p = sub.add_parser("serve", help="run the REST service")
    p.add_argument("--host", default=None,
                   help="bind address (default: $TUNNEL_CONTACT_HOST or 127.0.0.1)")
    p.add_argument("--port", type=int, default=None, help="bind port (default: $TUNNEL_CONTACT_PORT or 8000)")
    scheduler(p)
    p.add_argument("--results", default=None, metavar="DIR",
                   help="result store folder (default: $TUNNEL_CONTACT_RESULTS or ./results)")
    p.add_argument("--access-log", action="store_true", default=None,
                   help="log every request (default: $TUNNEL_CONTACT_ACCESS_LOG, or off)")


def main(argv: list[str] | None = None) -> int:
    """Run ``tunnel-contact`` with ``argv``; return the exit code (2: bad input)."""
    args = build_parser().parse_args(argv)
    from workflows.commands import configure_logging

    configure_logging(args.verbose)
    if args.command == "serve":
        from service.server import serve

        serve(host=args.host, port=args.port, scheduler=args.scheduler, results=args.results,
              access_log=args.access_log)
        return 0

    from workflows import commands

    try:
        if args.command == "run":
            return commands.run_command(args.case, args.results, force=args.force, retry_failed=args.retry_failed)
        if args.command == "sweep":
            return commands.sweep_command(args.sweep, args.results, scheduler=args.scheduler,
                                          progress=not args.no_progress, retry_failed=args.retry_failed)
        if args.command == "list":
            return commands.list_command(args.results)
        if args.command == "search":
            return commands.search_command(args.search, args.results, scheduler=args.scheduler,
                                           progress=not args.no_progress)
        if args.command == "reliability":
            from workflows.reliability_methods.command import reliability_command

            return reliability_command(args.study, args.results, scheduler=args.scheduler,
                                       progress=not args.no_progress)
        if args.command == "analyse":
            return commands.analyse_command(args.sweep_id, args.results, sensitivity=args.sensitivity,
                                            reliability=args.reliability, limit=args.limit)
        if args.command == "report":
            title = {k: getattr(args, k) for k in ("project", "job", "author", "checker", "revision", "date")}
            return commands.report_command(args.case_id, args.results, output=args.output, title=title)
        return commands.show_command(args.case_id, args.results)
    except commands.InputError as exc:
        print(f"tunnel-contact: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # the machine's side: a results path that is a file, a scheduler that does not answer
        print(f"tunnel-contact: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
