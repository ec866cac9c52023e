"""The ``optcal`` command line. Each sub-command lives in ``optcal/commands/<name>.py`` with
``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``; they are found automatically. Other packages
add commands the same way through the ``optcal.commands`` entry-point group (``studies`` adds ``study``).

Errors a user can fix (:class:`~optcal.errors.InputError`) print one line and exit with status 2.
"""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import sys
from importlib.metadata import entry_points

from . import commands
from .errors import InputError


class ArgumentParser(argparse.ArgumentParser):
    """argparse with one-line errors (status 2) instead of usage dumps."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


ENTRY_POINT_GROUP = "optcal.commands"


def _command_modules() -> list[tuple[str, object]]:
    """(name, module) of the built-in commands, then of the plug-ins registered in the ``optcal.commands``
    entry-point group (``optcal study`` is one); a plug-in may not replace a built-in command."""
    found = []
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if not info.name.startswith("_"):
            mod = importlib.import_module(f"{commands.__name__}.{info.name}")
            found.append((getattr(mod, "NAME", info.name), mod))
    taken = {name for name, _ in found}
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


def build_parser() -> argparse.ArgumentParser:
    parser = ArgumentParser(prog="optcal", description="In-field accelerometer calibration and optimiser comparison")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=ArgumentParser)
    for name, mod in _command_modules():
        p = sub.add_parser(name, help=mod.HELP, description=mod.HELP)
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
