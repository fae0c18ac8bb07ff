"""``python -m decrun`` = the ``decrun`` command (:func:`command`, its console script; :func:`console_main`
in a process that goes on)."""

import sys

from decrun.errors import DecrunError
from decrun.runner.failures import exit_code, install_sigterm, interrupt_cause
from decrun.runner.interrupts import ignore_interrupts


def console_main() -> None:
    """The ``decrun`` console script: SIGTERM handled and Ctrl-C reported in one line from
    the first instant, also while the command imports Hydra and numpy (~0.5 s); a single run
    that may draw figures forks its figure process (:mod:`decrun.runner.figure_process`: it
    imports matplotlib meanwhile); then :func:`decrun.runner.cli.main`."""
    install_sigterm()
    from decrun.core.threads import bound_blas_spin, bound_openmp_spin
    from decrun.runner import figure_process

    bound_openmp_spin()  # before pymeshlab loads libgomp (decrun.core.threads); the command's, not import decrun's
    bound_blas_spin()  # before numpy and scipy load OpenBLAS
    try:
        if figure_process.wanted(sys.argv[1:]):
            figure_process.start()  # before numpy: no thread is running to be copied
    except DecrunError as exc:  # DECRUN_FIGURE_PROCESS set to what it cannot be
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(1)
    try:
        from decrun.runner.cli import main  # lazy: after the signal handler (reports a Ctrl-C during the imports)
    except KeyboardInterrupt as exc:
        ignore_interrupts()  # a second Ctrl-C while this is printed is ignored
        print(f"decrun: interrupted ({interrupt_cause(exc)}) before the run started", file=sys.stderr)
        sys.exit(exit_code(exc))
    main()


def command() -> None:
    """The ``decrun`` command as a process (its console script and ``python -m decrun``):
    :func:`console_main`, then a single run's process ends with its exit code without the
    interpreter's teardown of every module and object (matplotlib, scipy, Hydra...), which
    costs a small run about a tenth of its time and changes nothing it wrote: the exit
    handlers run first (logging closes the log file; temporary files go), then stdout and
    stderr are flushed. After a sweep (its launcher's worker processes and threads are shut
    down by the interpreter's exit), with another non-daemon thread still running, or with an
    exception escaping, the interpreter exits the usual way. In a process that goes on
    afterwards call :func:`console_main`."""
    import atexit
    import os
    import threading

    status: str | int | None = 0
    try:
        console_main()
    except SystemExit as exc:
        status = exc.code
    if isinstance(status, int):
        code = status
    else:  # sys.exit(None) is 0, sys.exit("text") prints it and is 1
        if status is not None:
            print(status, file=sys.stderr)
        code = 0 if status is None else 1
    cli = sys.modules.get("decrun.runner.cli")
    swept = cli is not None and cli.SweepTable.sweep_dir is not None
    if swept or any(t.is_alive() and not t.daemon for t in threading.enumerate() if t is not threading.main_thread()):
        sys.exit(code)
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe: nothing more can reach it
            pass
    os._exit(code)


if __name__ == "__main__":
    command()
