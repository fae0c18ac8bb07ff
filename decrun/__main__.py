"""``python -m decrun`` = the ``decrun`` command (:func:`command`, its console script; :func:`console_main`
in a process that goes on)."""

import sys

from decrun.runner.io.interrupts import ignore_interrupts
from decrun.runner.job.failures import exit_code, install_sigterm, interrupt_cause


def console_main() -> None:
    """The ``decrun`` console script: SIGTERM handled and Ctrl-C reported in one line from
    the first instant, also while the command imports Hydra and numpy (~0.5 s); then
    :func:`decrun.runner.command.task.main`."""
    install_sigterm()
    from decrun.core.threads import bound_blas_spin, bound_openmp_spin

    bound_openmp_spin()  # before pymeshlab loads libgomp (decrun.core.threads); the command's, not import decrun's
    bound_blas_spin()  # before numpy and scipy load OpenBLAS
    try:
        from decrun.runner.command.task import (
            main,  # lazy: after the signal handler (reports a Ctrl-C during the imports)
        )
    except KeyboardInterrupt as exc:
        ignore_interrupts()  # a second Ctrl-C while this is printed is ignored
        print(f"decrun: interrupted ({interrupt_cause(exc)}) before the run started", file=sys.stderr)
        sys.exit(exit_code(exc))
    main()


def command() -> None:
    """The ``decrun`` command as a process (its console script and ``python -m decrun``):
    :func:`console_main`; the interpreter exits the usual way (exit handlers, module teardown and
    its last garbage collections: skipping them with ``gc.freeze`` made nanobind-based solvers report
    their objects as leaked at exit). In a process that goes on afterwards call :func:`console_main`."""
    console_main()


if __name__ == "__main__":
    command()
