"""The README is a landing page: at most 200 lines, ``make demo`` and ``make test`` first, every page it links
exists, and every ``inscal`` line it shows is a line of a block the tests run (the command-line session page,
run whole in the parts of tests/cli/test_readme_block_<k>.py).  That page runs every subcommand; the guide's
simulating page lists every built-in scenario."""

import re
from pathlib import Path

import readme_block

ROOT = readme_block.ROOT
README = (ROOT / "README.md").read_text(encoding="utf-8")
command_block = readme_block.command_block


def test_readme_is_a_landing_page():
    lines = README.splitlines()
    assert len(lines) <= 200, len(lines)
    first = re.search(r"```\n(.*?)```", README, re.DOTALL).group(1).splitlines()
    assert [ln.split()[:2] for ln in first] == [["make", "demo"], ["make", "test"]], first
    assert README.index("calibrates high-accuracy IMUs") < README.index("```")  # what it is, before anything else
    for target in re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", README):
        if target.startswith("docs/_build/"):  # the site `make docs` builds: its source page must exist
            target = "docs/" + target.removeprefix("docs/_build/html/").removesuffix(".html") + ".md"
        assert (ROOT / target).is_file(), f"the README links {target}, which does not exist"
    for path in re.findall(r"`((?:src|tests|bench|docs)/[\w/.-]+)`", README):
        if path.startswith("docs/_build/html/"):  # the site `make docs` builds: its source page must exist
            path = "docs/" + path.removeprefix("docs/_build/html/").removesuffix(".html") + ".md"
        assert (ROOT / path).exists(), path


def test_every_readme_command_runs_in_the_tests():
    block = set(command_block())
    shown = [ln.strip() for b in re.findall(r"```\n(.*?)```", README, re.DOTALL) for ln in b.splitlines()
             if ln.strip().startswith("inscal ")]
    assert len(shown) >= 8
    for line in shown:
        assert line in block, f"README line not run by the tests: {line}"


def test_the_session_runs_every_subcommand_and_the_guide_lists_every_scenario():
    from typer.main import get_command

    from inscal.cli.app import app
    from inscal.sim import scenarios

    simulating = (ROOT / "docs" / "guide" / "simulating.md").read_text(encoding="utf-8")
    for name in scenarios.BUILTIN:
        assert f"`{name}`" in simulating, f"built-in scenario {name} is not in docs/guide/simulating.md"
    names = set(get_command(app).commands)
    sub = readme_block.TEXT[readme_block.TEXT.index("Subcommands:"):][:400]
    for name in names:
        assert f"`{name}`" in sub, f"subcommand {name} is not listed on the command-line page"
    block = " ".join(command_block())
    for name in names:
        assert f"inscal {name} " in block + " ", f"the session block never runs `inscal {name}`"


def test_the_parts_run_the_whole_block_and_every_check():
    """The block runs in parts (tests/cli/test_readme_block_<k>.py): every line in exactly one part,
    a line's inputs written in its own part, every check and every expected file in a part that runs it."""
    lines = command_block()
    ps = readme_block.parts(lines)
    assert sorted(i for p in ps for i in p) == list(range(len(lines)))
    assert len(ps) == readme_block.PARTS == len(list(Path(__file__).parent.glob("test_readme_block_*.py")))
    for p in ps:
        for i in p:
            for j in range(len(lines)):
                if readme_block.files_of(lines[i]) & readme_block.files_of(lines[j]):
                    assert j in p, (lines[i], lines[j])
    for needs, check in readme_block.CHECKS:
        assert any(needs(ln) for ln in lines), check.__name__
    for f in readme_block.FILES:
        assert any(readme_block.writes(ln, f) for ln in lines), f
    assert readme_block.files_of("inscal calibrate s16.h5 --out p.toml --plots plots/") == {"s16.h5", "p.toml", "plots/"}
