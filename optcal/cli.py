"""The ``optcal`` command line. Each sub-command lives in ``optcal/commands/<name>.py`` with
``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``; they are found automatically.

Errors a user can fix (:class:`~optcal.errors.InputError`) print one line and exit with status 2.
"""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import sys

from . import commands
from .errors import InputError


class ArgumentParser(argparse.ArgumentParser):
    """argparse with one-line errors (status 2) instead of usage dumps."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = ArgumentParser(prog="optcal", description="In-field accelerometer calibration and optimiser comparison")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=ArgumentParser)
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        mod = importlib.import_module(f"{commands.__name__}.{info.name}")
        p = sub.add_parser(getattr(mod, "NAME", info.name), help=mod.HELP, description=mod.HELP)
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        rc = int(args._run(args) or 0)
        sys.stdout.flush()  # inside the try: a reader that left early is met here, not at interpreter exit
        return rc
    except InputError as exc:
        print(f"optcal {args.command}: error: {exc}", file=sys.stderr)
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
