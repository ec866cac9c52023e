"""The ``optcal`` command line. Each sub-command lives in ``optcal/app/commands/<name>.py`` with
``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``; they are found automatically. Other packages
add commands the same way through the ``optcal.commands`` entry-point group.

Errors a user can fix (:class:`~optcal.core.errors.InputError`) print one line and exit with status 2. The
library names its parameters in backquotes (`` `workers` ``), never a flag; here a backquoted name that is
the destination of one of the running command's options becomes that option (``--workers``).
``optcal --version`` prints the installed version; ``-q/--quiet`` and ``-v/--verbose`` (before or after the
command's name) set the level of the ``optcal`` logger: WARNING by default, -v INFO, -vv DEBUG, -q ERROR.
"""

from __future__ import annotations

import argparse
import gc
import importlib
import logging
import os
import re
import sys

from optcal.app import commands
from optcal.core.errors import MAX_LINE, InputError, one_line


class ArgumentParser(argparse.ArgumentParser):
    """argparse with one-line errors (status 2) instead of usage dumps, and without abbreviations: argparse
    would take ``--noise 10`` as ``--noise-ug 10``, a unit the user never wrote. Sub-parsers are made of this
    class too (``parser_class``; a sub-parser's own sub-commands, ``optcal study run``, inherit it)."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)
        self._argv: list[str] = []

    def parse_known_args(self, args=None, namespace=None):
        self._argv = list(sys.argv[1:] if args is None else args)
        return super().parse_known_args(args, namespace)

    def error(self, message):
        if message.startswith("unrecognized arguments:"):
            message += _spelled_out(self, self._argv, message.split(":", 1)[1].split())
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _spelled_out(parser: argparse.ArgumentParser, argv: list[str], unknown: list[str]) -> str:
    """For an unknown ``--opt`` that begins one or more options of the command named in ``argv`` (or of
    ``parser`` itself), the options it would have abbreviated, as a hint."""
    for action in parser._actions:  # the command's own parser, sub-commands of sub-commands included
        if isinstance(action, argparse._SubParsersAction):
            named = [a for a in argv if a in action.choices]
            if named:
                return _spelled_out(action.choices[named[0]], argv[argv.index(named[0]) + 1:], unknown)
    options = [s for a in parser._actions for s in a.option_strings if s.startswith("--")]
    hints = [f"for {u} write {' or '.join(m)}" for u in unknown if u.startswith("--")
             for m in [[o for o in options if o.startswith(u.split("=", 1)[0]) and o != u]] if m]
    return f" (options are not abbreviated: {'; '.join(hints)})" if hints else ""


ENTRY_POINT_GROUP = "optcal.commands"


def _builtin_names() -> list[str]:
    """Module names of the built-in commands (the folder's listing: nothing is imported, not even pkgutil)."""
    return sorted(f[:-3] for path in commands.__path__ for f in os.listdir(path)
                  if f.endswith(".py") and not f.startswith("_"))


def _builtin(name: str) -> object:
    # relative to optcal.app.commands: a module of that folder, never one of another package or layer
    return importlib.import_module(f".{name}", commands.__name__)


def _command_modules(only: str | None = None) -> list[tuple[str, object]]:
    """(name, module) of the built-in commands, then of the plug-ins registered in the ``optcal.app.commands``
    entry-point group (``optcal study`` is one); a plug-in may not replace a built-in command. With ``only``
    the name of a built-in command (a module ``only.py``, or ``only_.py`` for a Python keyword), that command
    alone: a command's run then imports nothing of the others nor reads the installed packages' entry points
    (importlib.metadata: a tenth of a second)."""
    if only is not None:
        for m in _builtin_names():
            if m.rstrip("_") == only:
                mod = _builtin(m)
                if getattr(mod, "NAME", m) == only:
                    return [(only, mod)]
    found = []
    for m in _builtin_names():
        mod = _builtin(m)
        found.append((getattr(mod, "NAME", m), mod))
    taken = {name for name, _ in found}
    from importlib.metadata import entry_points

    for ep in sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda e: e.name):
        if ep.name in taken:
            print(f"optcal: warning: plug-in command {ep.name!r} ({ep.value}) ignored: the name is taken",
                  file=sys.stderr)
            continue
        try:
            found.append((ep.name, ep.load()))
        except Exception as exc:  # a broken plug-in must not take the other commands down with it
            print(f"optcal: warning: plug-in command {ep.name!r} ({ep.value}) failed to load: {exc}",
                  file=sys.stderr)
            continue
        taken.add(ep.name)
    return found


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("optcal")
    except PackageNotFoundError:  # pragma: no cover - a source tree that was never installed
        from optcal import __version__

        return __version__


def _verbosity_options(p: argparse.ArgumentParser, suffix: str = "") -> None:
    """-q/-v. The top-level parser and each command's keep separate counts (a sub-parser's defaults would
    otherwise overwrite what was given before the command's name); :func:`_log_level` adds them."""
    p.add_argument("-v", "--verbose", action="count", default=0, dest="verbose" + suffix,
                   help="more messages on stderr: -v informational, -vv debugging")
    p.add_argument("-q", "--quiet", action="count", default=0, dest="quiet" + suffix,
                   help="errors only: no warnings on stderr")


def _log_level(args) -> int:
    v = getattr(args, "verbose", 0) + getattr(args, "verbose_cmd", 0)
    q = getattr(args, "quiet", 0) + getattr(args, "quiet_cmd", 0)
    return logging.ERROR if q > v else {0: logging.WARNING, 1: logging.INFO}.get(v - q, logging.DEBUG)


class _StderrHandler(logging.Handler):
    """Writes ``optcal: warning: message`` to the sys.stderr of the moment (tests swap it)."""

    def emit(self, record):
        try:
            sys.stderr.write(f"optcal: {record.levelname.lower()}: {record.getMessage()}\n")
        except Exception:  # pragma: no cover - as logging.StreamHandler does
            self.handleError(record)


class _VersionAction(argparse.Action):
    """``--version``: the installed version, looked up only when asked (importlib.metadata is slow to import)."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS, help=None):
        super().__init__(option_strings, dest, nargs=0, default=default, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"optcal {_version()}")  # on stdout, as argparse's own version action prints it
        parser.exit()


def _command_named(argv: list[str]) -> str | None:
    """The command ``argv`` names: its first word that is not one of the top-level options (-v, -q)."""
    for a in argv:
        if not (a.startswith("-") and set(a[1:]) <= {"v", "q"} or a in ("--verbose", "--quiet")):
            return None if a.startswith("-") else a
    return None


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The parser of every command, or, when ``argv`` (the arguments to be parsed) names a built-in command,
    of that command alone: its options and errors are the same either way; ``optcal --help``, plug-in
    commands and unknown names get the full parser."""
    parser = ArgumentParser(prog="optcal", description="In-field accelerometer calibration and optimiser comparison")
    parser.add_argument("--version", action=_VersionAction, help="print optcal's version and exit")
    _verbosity_options(parser)
    common = argparse.ArgumentParser(add_help=False)
    _verbosity_options(common, "_cmd")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=ArgumentParser)
    for name, mod in _command_modules(None if argv is None else _command_named(argv)):
        p = sub.add_parser(name, help=mod.HELP, description=mod.HELP, parents=[common])
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run, _flags=_flags_of(p))
    return parser


def _flags_of(parser: argparse.ArgumentParser) -> dict[str, str]:
    """{destination: its long option} of a command's options, sub-commands' included (``optcal study run``)."""
    out: dict[str, str] = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                for dest, flag in _flags_of(sub).items():
                    out.setdefault(dest, flag)
            continue
        longs = [s for s in action.option_strings if s.startswith("--")]
        if longs:
            out.setdefault(action.dest, longs[0])
    return out


def with_flags(message: str, flags: dict[str, str]) -> str:
    """``message`` with every backquoted parameter that is one of the command's options replaced by the
    option (`` `workers` `` → ``--workers``); other backquoted words are left as they are."""
    return re.sub(r"`([A-Za-z_][A-Za-z0-9_]*)`", lambda m: flags.get(m.group(1), m.group(0)), message)


def _keep_freed_memory() -> None:
    """Let glibc's malloc keep freed memory for reuse instead of returning it to the system at every free.

    NumPy's temporaries over 128 KiB (16,384 numbers: one column of a minute at 100 Hz, or of an integration
    over the motions) are otherwise mapped and unmapped, or the heap trimmed, at every operation, and the
    page faults make an array operation four to five times slower than its arithmetic: the whole ``optcal
    calibrate --raw`` on imu_tk's recording takes a sixth less with this (docs/performance.md, "Memory
    allocation"). Both thresholds are glibc's documented tunables (mallopt(3): M_TRIM_THRESHOLD, -1;
    M_MMAP_THRESHOLD, -3, at most 32 MiB); elsewhere (no glibc) nothing changes."""
    import ctypes

    try:
        libc = ctypes.CDLL("libc.so.6")
        libc.mallopt(-1, 64 << 20)  # M_TRIM_THRESHOLD
        libc.mallopt(-3, 32 << 20)  # M_MMAP_THRESHOLD
    except (OSError, AttributeError):
        pass


def _one_blas_thread() -> None:
    """One BLAS thread unless the user set another number: optcal's arrays are small (a few hundred positions,
    tens of motions), where a second BLAS thread costs more to wake than it saves, and on a shared machine it
    takes a core from whatever else runs (measured on imu_tk's pair: the same wall time when the machine is
    quiet, 0.06-0.08 s less CPU per run; docs/performance.md). Read once, when NumPy loads its BLAS: numpy is
    imported by the commands, after this."""
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")


# The cyclic garbage collector's first threshold in the process's own command line (Python's default: a
# collection every 700 allocations of container objects): a command's imports create tens of thousands of
# objects that live as long as the process, and the default traverses them again and again
GC_THRESHOLD = 50_000


def _collect_less() -> None:
    """Collect cyclic garbage every :data:`GC_THRESHOLD` allocations instead of 700: a command allocates few
    cycles, and the modules it imports are no garbage (mallopt's tuning is the allocator's counterpart,
    :func:`_keep_freed_memory`). For the process's own command line only: a program that calls :func:`main`
    keeps its collector as it set it."""
    gc.set_threshold(GC_THRESHOLD, *gc.get_threshold()[1:])


def main(argv: list[str] | None = None) -> int:
    own = argv is None  # the process's own command line (the ``optcal`` script, ``python -m optcal``)
    if "numpy" not in sys.modules:
        _one_blas_thread()
    _keep_freed_memory()
    if own:
        _collect_less()
    parser = build_parser(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(argv)
    logger = logging.getLogger("optcal")
    saved = logger.level
    handler = _StderrHandler()
    logger.setLevel(_log_level(args))
    logger.addHandler(handler)
    try:
        return _run(args)
    finally:  # main() may run many times in one process (the tests): leave the logger as it was
        logger.removeHandler(handler)
        logger.setLevel(saved)
        if own:
            # the process ends now: the interpreter's exit then leaves every object to the system instead of
            # traversing them all for cycles to free (the collections it makes at exit skip frozen objects)
            gc.freeze()


def _run(args) -> int:
    try:
        rc = int(args._run(args) or 0)
        sys.stdout.flush()  # inside the try: a reader that left early is met here, not at interpreter exit
        return rc
    except InputError as exc:
        prefix = f"optcal {args.command}: error: "
        message = one_line(with_flags(str(exc), getattr(args, "_flags", {})), MAX_LINE - len(prefix))
        print(prefix + message, file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"optcal {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader went away (`optcal solvers | head`): not an error of ours. Point stdout at devnull so
        # the interpreter's final flush does not raise again, and exit as a process killed by SIGPIPE would.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 141


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
