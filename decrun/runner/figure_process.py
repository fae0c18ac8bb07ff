"""The figures of a single run drawn by a second process, which imports matplotlib while the
run computes.

Importing matplotlib (with the 3-D axes the surface figures need) costs a small run about as
much as its mesh, operators and compute together, and the figures are drawn only after the
result. The ``decrun`` command of a single run therefore forks, at its first instant (before
numpy, Hydra or matplotlib are imported, so no thread is copied), a *figure process*
(:func:`start`). It imports matplotlib and decrun's drawing functions on the machine's second
core while the run composes its config, builds its operators and computes. When the result
and ``metrics.json`` are final, :func:`decrun.runner.run.write` hands it the figure
descriptions, the run directory and the complex (:func:`draw`); it draws the figures — the
first itself and the others each in a process forked from it, up to one per core — and
answers with the files written or the first figure's error. The run waits for the answer, so
the command ends with its figures on disk, as before.

What stays the same as drawing in the run's own process: the same drawing functions write the
same files (each under a temporary name, renamed when complete); a figure that fails is the
same error (its exception is sent back); the warnings and log records (WARNING and above) the
drawing raises reach the run's warnings and log; an interrupt of the run (Ctrl-C, SIGTERM)
while the figures are drawn stops the figure process and waits for it, so no temporary file is
left and the figures on disk are exactly the ones drawn.

The run draws its figures itself when there is no figure process (the Python API, a sweep, one
core, a machine without a core to spare, ``figures=false`` on the command line, a platform
without ``fork``, ``DECRUN_FIGURE_PROCESS=off``: :func:`wanted`), when a figure is a
plugin's own drawing function (it may rely on state of the run's process), when the mesh has
more than :data:`MAX_TOP_SIMPLICES` top simplices (drawing takes seconds there and the import is
a small share of it, while figures drawn at once each hold their own matplotlib objects: one at a
time keeps the memory of one), when the figure process could not
import matplotlib, or when the figure descriptions cannot be pickled.

Messages between the processes are pickles behind their length (:func:`send`, :func:`receive`).
"""

from __future__ import annotations

import logging
import os
import pickle
import signal
import struct
import sys
from pathlib import Path

from decrun.errors import ConfigError, DecrunError

__all__ = ["FigureProcess", "start", "current", "dismiss", "draw", "wanted", "setting", "send", "receive", "MAX_TOP_SIMPLICES",
           "ENVIRONMENT", "FigureProcessLost"]

#: the environment variable that turns the figure process off (``DECRUN_FIGURE_PROCESS=off``)
ENVIRONMENT = "DECRUN_FIGURE_PROCESS"

#: above this many top simplices the run draws its figures itself (see the module's docstring)
MAX_TOP_SIMPLICES = 200_000

#: command-line arguments after which the command draws no figure of a single run (or asks Hydra
#: only for help or a config)
_NO_FIGURES = ("-m", "--multirun", "-h", "--help", "--hydra-help", "-c", "--cfg", "-i", "--info", "-sc",
               "--shell-completion", "-p", "--package", "--resolve")

#: decrun's own drawing functions: the figure process draws only these
_OWN_MODULE = "decrun.runner.plots."

_HEADER = struct.Struct("<Q")

_current: "FigureProcess | None" = None

#: in the figure process: its two pipes to the run (jobs, answers)
_PIPES: list[int] = []


class FigureProcessLost(DecrunError, RuntimeError):
    """The figure process ended without answering (killed, or it crashed)."""


def wanted(args: list[str]) -> bool:
    """Whether the command line ``args`` (``sys.argv[1:]``) is a single run that may draw
    figures, on a machine where a second process helps: a POSIX ``fork``, at least two cores
    this process may run on, no ``-m``/``--multirun``, no ``hydra.mode`` override, no help or
    config printing, no ``figures=false``; and by :func:`setting`: ``on``, or ``auto`` (the
    default) with a core to spare — the load average of the last minute below the cores
    less half a core (on a busy machine a second process only competes with the run: it then
    draws its figures itself, as does ``off``). ConfigError for a setting that is none of these."""
    choice = setting()
    if choice == "off" or not hasattr(os, "fork") or _cores() < 2:
        return False
    for arg in args:
        key, _, value = arg.lstrip("+~").partition("=")
        if arg in _NO_FIGURES or key == "hydra.mode" or (key == "figures" and value.strip().lower() in ("false", "")):
            return False
    return choice == "on" or os.getloadavg()[0] < _cores() - 0.5


#: the values of DECRUN_FIGURE_PROCESS and what each means
_SETTINGS = {"auto": "auto", "": "auto", "on": "on", "1": "on", "true": "on", "yes": "on",
             "off": "off", "0": "off", "false": "off", "no": "off"}


def setting() -> str:
    """``DECRUN_FIGURE_PROCESS``: ``auto`` (unset), ``on`` (``1``) or ``off`` (``0``);
    ConfigError, naming the fix, for any other value."""
    value = os.environ.get(ENVIRONMENT, "").strip().lower()
    if value not in _SETTINGS:
        raise ConfigError(f"{ENVIRONMENT}={value!r}: must be one of auto, on, off (or 1, 0); use {ENVIRONMENT}=auto")
    return _SETTINGS[value]


def _cores() -> int:
    """The cores this process may run on."""
    affinity = getattr(os, "sched_getaffinity", None)
    return len(affinity(0)) if affinity is not None else (os.cpu_count() or 1)


def start() -> "FigureProcess | None":
    """Fork the figure process (once per process; the current one when it exists) and make it
    :func:`current`. Call it before numpy (or anything that starts threads) is imported."""
    global _current
    if _current is None or not _current.owned():
        import atexit

        _current = FigureProcess.fork()
        atexit.register(dismiss)  # the command ends: so does the figure process
    return _current


def current() -> "FigureProcess | None":
    """The figure process this process started and may use, else None (a process forked from
    the command, e.g. a launcher's worker, does not share it)."""
    return _current if _current is not None and _current.owned() and _current.alive else None


def dismiss() -> None:
    """End the figure process, if any (the run draws no figure, or the command ends); it exits
    at once, whatever it was doing."""
    global _current
    if _current is not None and _current.owned():
        _current.close()
    _current = None


def draw(figures: dict, out_dir, K) -> list[Path] | None:
    """Draw the :class:`decrun.apps.base.Figure` descriptions ``figures`` of a finished run into
    ``out_dir`` in the figure process, as :func:`decrun.runner.plots.common.draw_figures` would:
    the written paths, in the order of ``figures``; the first failing figure's exception is
    raised. None when the figure process cannot draw them (none is running, a plugin's drawing
    function, a large mesh, it could not import matplotlib, an unpicklable description): the
    caller draws them itself. An interrupt while waiting stops the figure process (and the
    processes it forked for figures) before it propagates."""
    process = current()
    if process is None or not figures or not all(_drawn_here(f.draw) for f in figures.values()):
        return None
    if K is not None and K.num_simplices(K.dim) > MAX_TOP_SIMPLICES:
        return None
    where = Path(out_dir).absolute()  # the figure process may be elsewhere (hydra.job.chdir)
    written = process.draw(figures, where, K)
    if written is None:
        return None
    # the paths as the run names its directory, as drawing in its own process gives them
    return [Path(out_dir) / path.relative_to(where) if path.is_relative_to(where) else path for path in written]


def _drawn_here(draw: str) -> bool:
    from decrun.runner.plots import FIGURE_KINDS  # no matplotlib: the table only

    return draw in FIGURE_KINDS or draw.startswith(_OWN_MODULE)


# ----------------------------------------------------------------------------------
# messages: a pickle behind its length
# ----------------------------------------------------------------------------------

def send(fd: int, message) -> None:
    """Write ``message`` (any picklable object) to the pipe ``fd``: its pickle's length
    (8 bytes, little-endian) then the pickle."""
    data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    view = memoryview(_HEADER.pack(len(data)) + data)
    while view:
        view = view[os.write(fd, view):]


def receive(fd: int):
    """The next message :func:`send` wrote to the pipe ``fd``; EOFError when the writer closed
    it (or ended) before a whole message."""
    (size,) = _HEADER.unpack(_read_exactly(fd, _HEADER.size))
    return pickle.loads(_read_exactly(fd, size))


def _read_exactly(fd: int, size: int) -> bytes:
    chunks, left = [], size
    while left:
        chunk = os.read(fd, min(left, 1 << 24))
        if not chunk:
            raise EOFError("the pipe was closed")
        chunks.append(chunk)
        left -= len(chunk)
    return b"".join(chunks)


# ----------------------------------------------------------------------------------
# the run's side
# ----------------------------------------------------------------------------------

class FigureProcess:
    """The run's handle on its figure process: its pid and the two pipes (jobs to it, answers
    from it). Made by :meth:`fork`; used through :func:`draw`."""

    def __init__(self, pid: int, jobs: int, answers: int):
        self.pid, self.jobs, self.answers, self.owner = pid, jobs, answers, os.getpid()
        self.alive = True
        self.ended: str | None = None  # how it ended, once stop() has reaped it

    @classmethod
    def fork(cls) -> "FigureProcess | None":
        """Fork the figure process (:func:`_serve` runs in it); None when forking fails."""
        jobs_read, jobs_write = os.pipe()
        answers_read, answers_write = os.pipe()
        for stream in (sys.stdout, sys.stderr):
            stream.flush()
        try:
            pid = os.fork()
        except OSError:
            for fd in (jobs_read, jobs_write, answers_read, answers_write):
                os.close(fd)
            return None
        if pid == 0:  # the figure process: it never returns
            os.close(jobs_write)
            os.close(answers_read)
            _serve(jobs_read, answers_write)
        os.close(jobs_read)
        os.close(answers_write)
        for fd in (jobs_write, answers_read):
            os.set_inheritable(fd, False)
        return cls(pid, jobs_write, answers_read)

    def owned(self) -> bool:
        """Whether this process forked it (a process forked from the run must not use its pipes)."""
        return os.getpid() == self.owner

    def draw(self, figures: dict, out_dir: Path, K) -> list[Path] | None:
        """Send the job, wait for the answer (see :func:`draw`)."""
        try:
            payload = pickle.dumps((figures, out_dir, K), protocol=pickle.HIGHEST_PROTOCOL)
        except Exception:  # an object of the descriptions that does not pickle: the run draws them
            return None
        try:
            try:
                send(self.jobs, (list(sys.path), os.getcwd(), payload))
            except OSError:  # it ended before the job (it was killed): nothing was drawn, the run draws
                self.stop()
                return None
            answer = receive(self.answers)
        except KeyboardInterrupt:  # the run is interrupted: the figure process stops, and nothing is left half-written
            self.stop()
            raise
        except (OSError, EOFError):
            status = self.stop()
            raise FigureProcessLost(f"the figure process ended without an answer ({status})") from None
        kind, value, notes = answer
        _replay(notes)
        if kind == "unavailable":  # it could not import what drawing needs: the run draws (and reports why)
            self.close()
            return None
        if kind == "failed":
            raise _chained(value)
        return value

    def stop(self) -> str:
        """Stop it now (SIGTERM: it removes its temporary files and stops the processes it forked)
        and wait until it is gone (SIGKILL after 10 s); how it ended."""
        import time

        if self.ended is not None:
            return self.ended
        self._terminate()
        deadline = time.monotonic() + 10.0
        while True:
            try:
                pid, status = os.waitpid(self.pid, os.WNOHANG)
            except ChildProcessError:
                pid, status = self.pid, None
            if pid:
                self.ended = "ended" if status is None else _ended(status)
                return self.ended
            if time.monotonic() > deadline:
                os.kill(self.pid, signal.SIGKILL)
                deadline = float("inf")
            time.sleep(0.005)

    def close(self) -> None:
        """End it without waiting: its job pipe closes (an idle figure process exits) and it
        gets SIGTERM (one still importing exits too)."""
        self._terminate()

    def _terminate(self) -> None:
        """No more jobs: the pipes closed and SIGTERM sent, once (a closed descriptor's number or
        a reaped pid may belong to another file or process later)."""
        if not self.alive:
            return
        self.alive = False
        for fd in (self.jobs, self.answers):
            _close(fd)
        try:
            os.kill(self.pid, signal.SIGTERM)
        except ProcessLookupError:
            pass


def _close(fd: int) -> None:
    try:
        os.close(fd)
    except OSError:
        pass


def _ended(status: int) -> str:
    if os.WIFSIGNALED(status):
        number = os.WTERMSIG(status)
        try:
            return f"signal {signal.Signals(number).name}"
        except ValueError:
            return f"signal {number}"
    return f"exit code {os.WEXITSTATUS(status)}"


def _replay(notes: list) -> None:
    """Raise again in the run the warnings, and log the records, the figure process caught."""
    import logging
    import warnings

    for kind, *rest in notes:
        if kind == "warning":
            message, category, filename, lineno = rest
            warnings.warn_explicit(message, category, filename, lineno)
        else:
            name, level, text = rest
            logging.getLogger(name).log(level, "%s", text)


# ----------------------------------------------------------------------------------
# the figure process's side
# ----------------------------------------------------------------------------------

def _serve(jobs: int, answers: int):
    """The figure process: import what drawing needs, then answer jobs until the run closes the
    pipe; never returns (``os._exit``). Its standard streams go to /dev/null (the run reports
    what it says); Ctrl-C is the run's to handle, SIGTERM stops it."""
    code = 0
    _PIPES[:] = [jobs, answers]
    try:
        _quiet()
        ready = _prepare()
        while True:
            try:
                job = receive(jobs)
            except EOFError:
                break
            send(answers, _answered(job) if ready else ("unavailable", None, []))
    except KeyboardInterrupt:  # SIGTERM (Terminated) from the run, or from whoever stops the command
        code = 128 + signal.SIGTERM
    except BaseException:  # noqa: BLE001 — the run learns of it as a lost figure process
        code = 1
    finally:
        os._exit(code)


def _quiet() -> None:
    from decrun.runner.failures import install_sigterm

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the whole group: the run decides
    install_sigterm()
    devnull = os.open(os.devnull, os.O_RDWR)
    for fd in (0, 1, 2):
        os.dup2(devnull, fd)
    os.close(devnull)
    # no BLAS thread in this process, so that forking it for a figure copies none
    for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[name] = "1"


def _prepare() -> bool:
    """Import what drawing needs; False when that fails (the run then draws, and says why)."""
    try:
        import mpl_toolkits.mplot3d  # noqa: F401 — the surfaces' 3-D axes

        import decrun.core.complex  # noqa: F401 — what a job's complex unpickles into
        from decrun.runner.plots.common import new_figure, save_figure
    except ImportError:
        return False
    _warm_up(new_figure, save_figure)
    return True


def _warm_up(new_figure, save_figure) -> None:
    """Draw and save one small figure (a 2-D axes with text, a 3-D axes) into memory: what a
    process's first figure pays once (fonts, glyphs, the PNG writer) is paid while the run
    still computes."""
    import io

    fig = new_figure(2.0, 1.0, dpi=20)
    fig.add_subplot(1, 2, 1).set_title("warm-up")
    fig.add_subplot(1, 2, 2, projection="3d").set_axis_off()
    fig.savefig(io.BytesIO(), format="png")


def _answered(job) -> tuple:
    """The answer to a job (``(sys.path, cwd, pickled (figures, out_dir, K))``): :func:`_answer`'s,
    or its unexpected error as a failed figure."""
    path, cwd, payload = job
    sys.path[:] = path
    os.chdir(cwd)
    try:
        figures, out_dir, K = pickle.loads(payload)
        return _answer(figures, out_dir, K)
    except Exception as exc:
        return ("failed", _picklable(exc), [])


def _answer(figures: dict, out_dir: Path, K) -> tuple:
    """Draw a job's figures: ``("written", paths, notes)`` or ``("failed", exception chain, notes)``.
    The first share of the figures is drawn here, the others each in a process forked for it
    (one per further core), each share in the figures' order."""
    names = list(figures)
    workers = max(1, min(len(names), _cores()))
    shares = [names[i::workers] for i in range(workers)]
    children = []
    try:
        for share in shares[1:]:
            read, write = os.pipe()
            pid = os.fork()
            if pid == 0:  # a figure's process: it answers on its own pipe only (the run's pipes close with
                for fd in (read, *_PIPES):  # the figure process alone, so the run sees it end)
                    os.close(fd)
                try:
                    send(write, _draw_share(share, figures, out_dir, K))
                    code = 0
                except KeyboardInterrupt:
                    code = 128 + signal.SIGTERM
                except BaseException:  # noqa: BLE001
                    code = 1
                os._exit(code)
            os.close(write)
            children.append((pid, read, share))
        answers = [_draw_share(shares[0], figures, out_dir, K)]  # this process's share, then the others'
        for pid, read, share in children:
            try:
                answer = receive(read)
            except EOFError:  # it ended without answering: how is known once it is reaped
                answer = None
            finally:
                os.close(read)
            _, status = os.waitpid(pid, 0)
            lost = FigureProcessLost(f"drawing {', '.join(share)} ended ({_ended(status)})")
            answers.append(answer or ("failed", [lost], [], share[0]))
        children = []
    finally:
        for pid, _, _ in children:  # interrupted: stop the figures' processes and wait for them
            try:
                os.kill(pid, signal.SIGTERM)
                os.waitpid(pid, 0)
            except (ProcessLookupError, ChildProcessError):
                pass
    return _merge(names, shares, answers)


def _merge(names: list[str], shares: list[list[str]], answers: list[tuple]) -> tuple:
    """One answer from the shares' (``answers[i]`` is ``shares[i]``'s): the written paths in the
    figures' order, or the error of the first figure (in that order) that failed; the notes of all."""
    notes = [note for answer in answers for note in answer[2]]
    failed = [(names.index(answer[3]), answer[1]) for answer in answers if answer[0] == "failed"]
    if failed:
        return ("failed", min(failed, key=lambda pair: pair[0])[1], notes)
    by_name = {name: path for share, answer in zip(shares, answers, strict=True)
               for name, path in zip(share, answer[1], strict=True)}
    return ("written", [by_name[name] for name in names], notes)


def _draw_share(share: list[str], figures: dict, out_dir: Path, K) -> tuple:
    """Draw the figures named ``share`` in order: ``("written", paths, notes)``, or
    ``("failed", exception, notes, name)`` at the first that fails (the exception as raised when
    it pickles, else a RuntimeError with its type and message)."""
    import logging
    import warnings

    from decrun.runner.plots.common import draw_figures

    notes: list = []
    handler = _Collect(notes)
    root = logging.getLogger()
    root.addHandler(handler)
    written: list[Path] = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("default")
            for name in share:
                try:
                    written += draw_figures({name: figures[name]}, out_dir, K)
                except Exception as exc:
                    return ("failed", _picklable(exc), notes, name)
                finally:
                    notes += [("warning", str(w.message), w.category, w.filename, w.lineno) for w in caught]
                    caught.clear()
    finally:
        root.removeHandler(handler)
    return ("written", written, notes)


def _picklable(exc: BaseException) -> list[BaseException]:
    """``exc`` and its causes (``__cause__``, else ``__context__``), each as raised when it
    pickles, else a RuntimeError with its type and message; the first carries the figure
    process's traceback as a note (shown with ``-v``)."""
    import traceback

    text = "".join(traceback.format_exception(exc))
    chain: list[BaseException] = []
    link: BaseException | None = exc
    while link is not None and len(chain) < 8:
        try:
            copy = pickle.loads(pickle.dumps(link))
        except Exception:
            copy = RuntimeError(f"{type(link).__name__}: {link}")
        chain.append(copy)
        link = link.__cause__ or (None if link.__suppress_context__ else link.__context__)
    if chain and hasattr(chain[0], "add_note"):
        chain[0].add_note("drawn in decrun's figure process:\n" + text)
    return chain


def _chained(chain: list[BaseException]) -> BaseException:
    """The first exception of :func:`_picklable`'s chain, its causes linked again."""
    for exc, cause in zip(chain, chain[1:], strict=False):
        exc.__cause__ = cause
    return chain[0]


class _Collect(logging.Handler):
    """A logging handler keeping (logger name, level, message) of WARNING and above."""

    def __init__(self, notes: list):
        super().__init__(logging.WARNING)
        self.notes = notes

    def emit(self, record) -> None:
        self.notes.append(("log", record.name, record.levelno, record.getMessage()))
