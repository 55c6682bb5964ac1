"""The ``nsbench`` command line: one module per sub-command.

Bad input (unknown problem, integrator or parameter, bad value) exits with
status 2 and one line on stderr, never a traceback.
"""

from __future__ import annotations

import argparse
import os
import sys
from typing import NoReturn, Sequence

from nsbench.errors import NsbenchError

# Sub-command modules; each defines ``add_parser(subparsers)`` and ``main(args) -> int``.
COMMANDS = (
    "listing",
    "simulate",
    "check",
    "run",
    "bench",
    "report",
    "compare",
    "history",
    "archive",
    "ingest",
    "bifurcation",
    "continuation",
    "lyapunov",
    "paper",
)


class UsageError(NsbenchError):
    """A command line argparse cannot read (unknown option, missing value, an option given twice)."""


def _refuse_empty(action: argparse.Action, values) -> None:
    # an empty value never means "the default": `--events-out ''` used to write nothing, silently
    if isinstance(values, str) and not values.strip():
        raise argparse.ArgumentError(action, f"empty value {values!r}; give a value or leave the option out")


class _Once(argparse.Action):
    """``store``, but an option given twice is an error (the last value silently winning,
    ``--out A --out B`` writing only to B, hides a typo), and so is an empty value."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        _refuse_empty(self, values)
        seen = namespace.__dict__.setdefault("_nsbench_given", {})
        if option_string is not None and self.dest in seen:
            raise argparse.ArgumentError(self, f"given twice ({seen[self.dest]!r} and {values!r}); give it once")
        seen[self.dest] = values
        setattr(namespace, self.dest, values)


class _Append(argparse.Action):
    """``append`` (a repeatable option), refusing an empty value."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        _refuse_empty(self, values)
        setattr(namespace, self.dest, [*(getattr(namespace, self.dest, None) or []), values])


class Parser(argparse.ArgumentParser):
    """argparse with nsbench's one-line errors; value options given at most once, never empty.

    argparse prints its usage and exits on an error; here the error becomes a
    :class:`UsageError`, printed by :func:`main` as the one ``nsbench: error:``
    line every bad input gets, with the sub-command's ``--help`` named.
    """

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.register("action", None, _Once)
        self.register("action", "store", _Once)
        self.register("action", "append", _Append)

    def error(self, message: str) -> NoReturn:
        raise UsageError(f"{message} (see {self.prog} --help)")


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The parser of every sub-command, or of the sub-command ``only`` alone (the others' modules
    are then not imported: a command that starts worker processes starts them sooner)."""
    import importlib

    parser = Parser(
        prog="nsbench",
        description="Compare time integrators on non-smooth dynamical systems (friction, impacts, sliding).",
    )
    from nsbench import __version__

    parser.add_argument("--version", action="version", version=f"nsbench {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMANDS if only is None else (only,):
        module = importlib.import_module(f"nsbench.cli.{name}")
        module.add_parser(sub)
    return parser


#: Exit status when stdout is a pipe whose reader has gone (``nsbench compare ... | head``):
#: 128 + SIGPIPE, what a shell reports for a process ended by that signal.
EXIT_BROKEN_PIPE = 141


def fail(message: str) -> int:
    """Print one error line and return the bad-input exit status."""
    line = " ".join(str(message).split("\n")).strip() or "unknown error"
    print(f"nsbench: error: {line}", file=sys.stderr)
    return 2


def os_error_message(exc: OSError) -> str:
    """One line for an ``OSError``: the path(s) it names and what is wrong."""
    reason = exc.strerror or str(exc) or type(exc).__name__
    paths = [str(p) for p in (exc.filename, exc.filename2) if p is not None]
    if not paths:
        return reason
    return f"{' -> '.join(paths)}: {reason}"


def _stdout_reader_gone() -> bool:
    """Whether stdout is a pipe (or socket) whose reading end is closed."""
    try:
        import select

        fd = sys.stdout.fileno()
        poll = select.poll()
        poll.register(fd, select.POLLOUT)
        return any(event & select.POLLERR for _, event in poll.poll(0))
    except (AttributeError, OSError, ValueError):  # no real stdout (captured), or no poll
        return False


def _silence_stdout() -> None:
    """Point stdout at /dev/null so that the flush at exit does not fail again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (AttributeError, OSError, ValueError):
        pass


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``nsbench`` console script.

    Returns the exit status: 0, 1 (the run finished but something failed, see
    each sub-command), 2 (bad input: one ``nsbench: error:`` line on stderr),
    130 (interrupted) or 141 (stdout closed by its reader, e.g. ``| head``).
    """
    words = sys.argv[1:] if argv is None else list(argv)
    # a command named first is parsed by its own parser alone (the same result); anything else
    # (--help, --version, an unknown command) by the whole one
    parser = build_parser(words[0] if words and words[0] in COMMANDS else None)
    if words[:1] == ["--version"] and len(words) > 1:  # argparse prints the version and ignores the rest
        return fail(f"--version takes no other argument, got {' '.join(words[1:])!r}")
    try:
        try:
            args = parser.parse_args(argv)
        except SystemExit as exc:  # --help and --version print and end here
            return int(exc.code or 0) if not isinstance(exc.code, str) else fail(exc.code)
        code = int(args.handler(args) or 0)
        sys.stdout.flush()  # a closed pipe shows here, not in the interpreter's exit
        return code
    except NsbenchError as exc:
        return fail(str(exc))
    except BrokenPipeError as exc:
        if _stdout_reader_gone():
            _silence_stdout()
            return EXIT_BROKEN_PIPE
        return fail(os_error_message(exc))
    except OSError as exc:  # the safety net: an unwritable or unreadable path not checked up front
        return fail(os_error_message(exc))
    except KeyboardInterrupt:
        print("nsbench: interrupted", file=sys.stderr)
        return 130


def console() -> None:
    """The ``nsbench`` console script: :func:`main`, then a quick exit.

    Once the command has ended, its output flushed and the exit handlers run (kept
    worker pools ended), nothing is left to do but the interpreter's tear-down of
    every module and of the compiled code: about half a second that a user would
    wait for. It is skipped, unless a thread of the command (a Dask client's, say) is
    still running and must be let finish.
    """
    import atexit
    import threading

    code = main()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    if any(t.is_alive() and not t.daemon for t in threading.enumerate() if t is not threading.main_thread()):
        sys.exit(code)
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(code)


if __name__ == "__main__":  # pragma: no cover
    console()
