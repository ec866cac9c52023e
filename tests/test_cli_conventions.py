"""Command-line conventions: ``optcal --version``, ``-q/--quiet`` and ``-v/--verbose`` on every command
(the level of the ``optcal`` logger), help text on every option, and each command's default model in its
help."""

from __future__ import annotations

import argparse
import logging
import subprocess
import sys
from importlib.metadata import version

import pytest

from optcal.app import cli

CLI = [sys.executable, "-c", "import sys; from optcal.app.cli import main; sys.exit(main())"]


def _subparsers(parser):
    return [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]


def _commands():
    (sub,) = _subparsers(cli.build_parser())
    return sub.choices


def test_version_prints_the_package_version():
    proc = subprocess.run([*CLI, "--version"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == f"optcal {version('optcal')}"
    assert proc.stdout.strip().split()[1].count(".") == 2  # X.Y.Z


def _undocumented(parser, where):
    """(where, option) of every action without help, sub-commands of sub-commands included."""
    out = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            # documented through the help of each choice (argparse lists them under the metavar)
            helped = {a.dest for a in action._choices_actions if a.help}
            out += [(f"{where} {name}", "(no help)") for name in action.choices if name not in helped]
            for name, sub in action.choices.items():
                out += _undocumented(sub, f"{where} {name}")
        elif not action.help or action.help == argparse.SUPPRESS:
            out.append((where, "/".join(action.option_strings) or action.dest))
    return out


def test_every_option_of_every_command_has_help():
    parser = cli.build_parser()
    assert _undocumented(parser, "optcal") == []
    (sub,) = _subparsers(parser)
    assert all(a.help for a in sub._choices_actions), "every command has a one-line help"


@pytest.mark.parametrize("name", sorted(_commands()))
def test_every_command_accepts_quiet_and_verbose(name):
    parser = _commands()[name]
    for opt in ("-q", "--quiet", "-v", "--verbose"):
        assert opt in parser._option_string_actions, (name, opt)


@pytest.mark.parametrize("command, option, default", [
    ("calibrate", "--model", "nonlinear12"),
    ("discover", "--base", "linear9"),
    ("info", "--model", "seed15"),
    ("demo", "--model", "nonlinear12"),
    ("simulate", "--model", "nonlinear12"),
])
def test_help_states_the_default_model(command, option, default):
    parser = _commands()[command]
    assert parser._option_string_actions[option].default == default  # the real default ...
    assert default in parser.description  # ... is the one the command's help names
    assert default in parser._option_string_actions[option].help


@pytest.fixture
def levels(monkeypatch):
    """Replace info's run by one that records the optcal logger's level and logs one message per level."""
    from optcal.app.commands import info

    seen = []

    def fake_run(args):
        log = logging.getLogger("optcal.test")
        seen.append(logging.getLogger("optcal").level)
        for level in (logging.DEBUG, logging.INFO, logging.WARNING, logging.ERROR):
            log.log(level, f"message at {logging.getLevelName(level)}")
        return 0

    monkeypatch.setattr(info, "run", fake_run)
    return seen


@pytest.mark.parametrize("argv, level", [
    (["info"], logging.WARNING),
    (["-v", "info"], logging.INFO),
    (["info", "-v"], logging.INFO),
    (["-vv", "info"], logging.DEBUG),
    (["-v", "info", "--verbose"], logging.DEBUG),
    (["-q", "info"], logging.ERROR),
    (["info", "--quiet"], logging.ERROR),
])
def test_quiet_and_verbose_set_the_optcal_logger_level(argv, level, levels, capsys):
    before = logging.getLogger("optcal").level
    assert cli.main(argv) == 0
    assert levels == [level]
    err = capsys.readouterr().err
    shown = [n for n in ("DEBUG", "INFO", "WARNING", "ERROR") if f"optcal: {n.lower()}: message at {n}" in err]
    assert shown == [n for n in ("DEBUG", "INFO", "WARNING", "ERROR") if logging.getLevelName(n) >= level]
    assert logging.getLogger("optcal").level == before  # main() leaves the logger as it found it
    assert not any(isinstance(h, cli._StderrHandler) for h in logging.getLogger("optcal").handlers)


def test_quiet_and_verbose_in_a_real_run(capsys):
    assert cli.main(["-q", "info", "--scheme", "6", "--model", "linear9", "--json"]) == 0
    assert capsys.readouterr().err == ""


def test_parser_building_imports_no_heavy_module_or_allantools():
    code = ("import sys, optcal.app.cli; optcal.app.cli.build_parser(); "
            "print(sorted({m.split('.')[0] for m in sys.modules} & {'numpy', 'allantools', 'matplotlib', 'scipy'}))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[]"


def test_library_errors_name_parameters_and_the_cli_names_its_options(tmp_path, capsys):
    """The library names a parameter in backquotes, never a flag; the command line shows its own option."""
    import pytest

    from optcal.core.errors import InputError
    from optcal.studies.execute import run_study
    from optcal.studies.spec import load

    with pytest.raises(InputError, match="`workers` must be at least 1") as e:
        run_study(load("ci"), tmp_path / "s1", workers=0, progress=False)
    assert "--" not in str(e.value)
    assert cli.main(["study", "run", "ci", "--workers", "0", "--out", str(tmp_path / "s2")]) == 2
    err = capsys.readouterr().err
    assert "--workers must be at least 1" in err and "`" not in err
    # a backquoted word that is not one of the command's options stays as it is
    assert cli.with_flags("`workers` and `nothing`", {"workers": "--workers"}) == "--workers and `nothing`"


def _parsers(parser, where="optcal"):
    """(where, parser) of the top-level parser and every sub-command's, sub-commands of sub-commands included."""
    out = [(where, parser)]
    for action in _subparsers(parser):
        for name, sub in action.choices.items():
            out += _parsers(sub, f"{where} {name}")
    return out


def test_no_parser_takes_an_abbreviated_option():
    parsers = _parsers(cli.build_parser())
    assert {"optcal", "optcal calibrate", "optcal study run"} <= {w for w, _ in parsers}
    assert [w for w, p in parsers if p.allow_abbrev] == []


@pytest.mark.parametrize("argv, unknown, hint", [
    # argparse would read --noise-ug 10: µg the user never wrote
    (["info", "--noise", "10"], "--noise 10", "for --noise write --noise-ug"),
    (["simulate", "-o", "x.csv", "--dwell", "5"], "--dwell 5", "for --dwell write --dwell-s"),
    (["study", "run", "ci", "--work", "2"], "--work 2", "for --work write --workers"),
    (["calibrate", "p.csv", "--mod=linear9"], "--mod=linear9", "for --mod=linear9 write --model"),
    (["--verb", "info"], "--verb", "for --verb write --verbose"),
    (["info", "--bogus"], "--bogus", None),
])
def test_an_abbreviated_option_is_refused_in_one_line(argv, unknown, hint, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.count("\n") == 1, err
    assert f"unrecognized arguments: {unknown}" in err
    assert (f"(options are not abbreviated: {hint}" in err) if hint else "abbreviated" not in err
