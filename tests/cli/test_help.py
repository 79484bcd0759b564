"""The command-line help reads like a manual: every value named by what it is (no ``<str>``), flags without a
value, and two or three examples under every command's options that parse with that command's own options;
the cheap ones (the database's, the list of experiments) run."""

import shlex

import pytest
import typer.main
from typer.testing import CliRunner

from inscal.cli.app import app
from inscal.cli.examples import EXAMPLES

ROOT = typer.main.get_command(app)


def commands(group=ROOT, prefix=()):
    """``(("db", "add"), command)`` for every command of the tree."""
    for name, cmd in group.commands.items():
        if hasattr(cmd, "commands"):
            yield from commands(cmd, prefix + (name,))
        else:
            yield prefix + (name,), cmd


ALL = dict(commands())


def test_every_command_has_two_or_three_examples_and_no_other():
    assert set(EXAMPLES) == {" ".join(path) for path in ALL}
    for name, lines in EXAMPLES.items():
        assert 2 <= len(lines) <= 3, name
        assert all(line.startswith(f"inscal {name} ") or line == f"inscal {name}" for line in lines), name


@pytest.mark.parametrize("path", sorted(ALL), ids=" ".join)
def test_help_names_values_and_shows_the_examples(path):
    r = CliRunner().invoke(app, [*path, "--help"])
    assert r.exit_code == 0, r.output
    out = r.output
    for bad in ("<str>", "<bool>", "<int>", "<float>", "<path>", "list["):
        assert bad not in out.split("Examples:")[0], (path, bad)
    usage = next(x for x in out.splitlines() if "Usage:" in x)
    assert "{" not in usage, usage  # DATA, not {data}
    assert "Examples:" in out
    words = " ".join(out.split("Examples:")[1].split())  # the help wraps a long example at a space
    for line in EXAMPLES[" ".join(path)]:
        assert line in words, line
    for param in ALL[path].params:  # a flag shows no value, an option a named one
        if param.param_type_name == "option":
            assert (param.metavar == "") == bool(param.is_flag), (path, param.opts)
            assert param.metavar == "" or param.metavar == param.metavar.strip() and not param.metavar.startswith("<")


@pytest.mark.parametrize("name,line", [(n, x) for n, lines in EXAMPLES.items() for x in lines])
def test_every_example_parses_with_its_commands_options(name, line):
    words = shlex.split(line)[1:]
    path = tuple(name.split())
    cmd, args = ALL[path], words[len(path):]
    parent = ROOT.make_context("inscal", list(path), resilient_parsing=True)
    ctx = cmd.make_context(path[-1], args, parent=parent)  # unknown options, bad values, missing required: raise
    assert not ctx.args, (line, ctx.args)


def test_the_database_examples_run(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("INSCAL_DB", raising=False)
    runner = CliRunner()
    for line in (EXAMPLES["db init"][0], EXAMPLES["db add"][0], EXAMPLES["db list"][1], EXAMPLES["montecarlo"][0]):
        r = runner.invoke(app, shlex.split(line)[1:])
        assert r.exit_code == 0, (line, r.output)
    r = runner.invoke(app, ["db", "list", "--db", "lab.sqlite", "--json"])
    assert '"serial": "FOG-0042"' in r.output
