"""The console scripts ``decrun-table`` (a sweep's table rebuilt and printed) and ``decrun-track``
(a finished run or sweep logged to a tracker)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from decrun.errors import DecrunError
from decrun.runner.io.files import SweepFiles
from decrun.runner.job.failures import (
    shorten_words,
)


def table_main(argv: list[str] | None = None) -> int:
    """Console script ``decrun-table SWEEP [SWEEP ...]`` (also ``--plot METRIC --x KEY`` and
    ``--compare RUN_A RUN_B``): rebuild each sweep's ``metrics.csv``
    / ``metrics.md`` (only in directories a sweep wrote) and print the table — several
    sweeps stacked with a ``sweep`` column; one line on stderr for each ``corrupt`` job,
    naming the file, and for each sweep directory the table could not be saved in (read-only:
    the table is printed all the same). Exit 1 when a job is not ok, 2 on an error."""
    import argparse

    # lazy: pandas, only for decrun-table (start-up speed)
    from decrun.runner.sweep.tables import failed_jobs, is_sweep_dir, select, stack, to_markdown, write_sweep_table

    parser = argparse.ArgumentParser(prog="decrun-table", description=table_main.__doc__)
    parser.add_argument("sweep_dirs", nargs="*", metavar="SWEEP", help="a sweep directory, e.g. outputs/sweeps/<stamp>")
    parser.add_argument("--csv", action="store_true", help="print CSV instead of markdown")
    parser.add_argument("--metrics", help="comma-separated metric columns to show (default: the apps' headline "
                                          "metrics in markdown, all in --csv)")
    parser.add_argument("--all", action="store_true", help="show every column, constant ones included")
    parser.add_argument("--sort", help="comma-separated columns to sort the rows by")
    parser.add_argument("--descending", action="store_true", help="sort in descending order")
    parser.add_argument("--drop-constant", action=argparse.BooleanOptionalAction, default=None,
                        help="drop columns with one value in every row (default: on for markdown, off for --csv and --all)")
    parser.add_argument("--plot", metavar="METRIC", help="draw METRIC against --x KEY as a PNG (decrun.runner.sweep.plot)")
    parser.add_argument("--x", metavar="KEY", help="the swept key on the x axis of --plot")
    parser.add_argument("-o", "--output", metavar="FILE", help="the PNG of --plot (default: in the first sweep)")
    parser.add_argument("--compare", nargs=2, metavar=("RUN_A", "RUN_B"), help="max and L2 difference of every field")
    args = parser.parse_args(argv)
    from decrun.runner.sweep.table_commands import compare_command, plot_command

    if args.compare:
        return compare_command(args.compare[0], args.compare[1], csv=args.csv)
    if args.plot:
        return plot_command(args.sweep_dirs, args.plot, args.x, args.output)
    if not args.sweep_dirs:
        parser.error("give a sweep directory (or --compare RUN_A RUN_B)")

    def split(text: str | None) -> list[str] | None:
        return [k.strip() for k in text.split(",") if k.strip()] if text else None

    unsaved = []  # a sweep directory the table cannot be written into (read-only): printed, not saved
    try:
        for sweep_dir in args.sweep_dirs:
            if not Path(sweep_dir).is_dir():
                raise FileNotFoundError(f"sweep directory {sweep_dir!r} does not exist")
            if is_sweep_dir(sweep_dir):
                try:
                    write_sweep_table(sweep_dir)
                except OSError as exc:
                    cause = os.strerror(exc.errno) if exc.errno else str(exc)
                    unsaved.append(f"decrun-table: the table above could not be saved in {sweep_dir} "
                                   f"({SweepFiles.TABLE_CSV}, {SweepFiles.TABLE_MD}: {cause}); it is printed only "
                                   f"(`decrun-table --csv {sweep_dir} > FILE` saves it elsewhere)")
        table = stack(args.sweep_dirs)
        if len(args.sweep_dirs) == 1:
            table = table.drop(columns="sweep")
        drop = not (args.csv or args.all) if args.drop_constant is None else args.drop_constant
        shown = select(table, split(args.metrics), split(args.sort), args.descending, drop,
                       narrow=not (args.all or args.csv))
    except (FileNotFoundError, KeyError, DecrunError) as exc:
        print(shorten_words(f"decrun-table: error: {exc.args[0] if isinstance(exc, KeyError) else exc}"),
              file=sys.stderr)
        return 2
    if table.empty:
        print(f"decrun-table: error: no jobs (no manifest.json, no job directories with .hydra/) in "
              f"{', '.join(args.sweep_dirs)}", file=sys.stderr)
        return 2
    print(shown.to_csv(index=False) if args.csv else to_markdown(shown), end="")
    for row in table[table["status"] == "corrupt"].itertuples(index=False):  # one line each, naming the file
        print(f"decrun-table: job {row.job} corrupt: {row.error}", file=sys.stderr)
    for line in unsaved:
        print(line, file=sys.stderr)
    return 1 if len(failed_jobs(table)) else 0


def track_main(argv: list[str] | None = None) -> int:
    """Console script ``decrun-track DIR [tracker=mlflow tracker.uri=URI ...]``: log the sweep
    (a directory with ``manifest.json`` or ``multirun.yaml``) or the single run in ``DIR`` to
    the tracker the overrides compose (:mod:`decrun.runner.tracking`) — a sweep that ran
    with ``tracker=none``, or whose tracker could not be reached. Runs it logged before go
    into the same tracker runs (their ids are kept in the directories). Exit 2 on an error."""
    import argparse

    parser = argparse.ArgumentParser(prog="decrun-track", description=track_main.__doc__)
    parser.add_argument("dir", metavar="DIR", help="a sweep directory (outputs/sweeps/<stamp>) or a run directory")
    parser.add_argument("overrides", nargs="*", help="tracker=mlflow and tracker.<option>=<value> overrides")
    args = parser.parse_args(argv)
    from decrun.runner.job.config import compose_config
    from decrun.runner.job.plugins import build
    from decrun.runner.sweep.tables import is_sweep_dir
    from decrun.runner.tracking import Tracker, track_run, track_sweep

    where = Path(args.dir)
    try:
        outside = [o for o in args.overrides if not o.startswith("tracker")]
        if outside:
            raise DecrunError(f"{outside[0]}: decrun-track takes only tracker overrides (tracker=mlflow "
                              "tracker.uri=URI ...)")
        if not where.is_dir():
            raise DecrunError(f"{where}: no such directory; give a sweep or run directory")
        tracker = build(compose_config(args.overrides).tracker, "tracker", Tracker)
        tracker.check()
        if not tracker.active():
            raise DecrunError("tracker=none logs nothing; choose one, e.g. decrun-track DIR tracker=mlflow")
        if is_sweep_dir(where):
            tracked = track_sweep(tracker, where)
            print(f"decrun-track: tracker={tracker.name}: {len(tracked.runs)} jobs under run {tracked.sweep_run} "
                  f"({tracked.sent} sent) in {tracker.store()}")
        else:
            print(f"decrun-track: tracker={tracker.name}: run {track_run(tracker, where)} in {tracker.store()}")
    except DecrunError as exc:
        print(shorten_words(f"decrun-track: error: {exc}"), file=sys.stderr)
        return 2
    except Exception as exc:  # noqa: BLE001 — the tracker's own errors (unreachable server): one line
        text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        print(shorten_words(f"decrun-track: error: {type(exc).__name__}: {text}"), file=sys.stderr)
        return 2
    return 0
