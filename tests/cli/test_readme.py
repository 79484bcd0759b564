"""The README lists every built-in scenario and every subcommand, and its command block is run whole (in
the parts of tests/cli/test_readme_block_<k>.py)."""

from pathlib import Path

import readme_block

README = readme_block.README
command_block = readme_block.command_block


def test_readme_lists_every_scenario_and_subcommand():
    from inscal.sim import scenarios
    from inscal.cli.app import app
    from typer.main import get_command

    for name in scenarios.BUILTIN:
        assert f"`{name}`" in README, f"built-in scenario {name} is not in the README"
    names = set(get_command(app).commands)
    sub = README[README.index("Subcommands:"):][:400]
    for name in names:
        assert f"`{name}`" in sub, f"subcommand {name} is not listed in the README"
    block = " ".join(command_block())
    for name in names:
        assert f"inscal {name} " in block + " ", f"the README's command block never runs `inscal {name}`"


def test_the_parts_run_the_whole_block_and_every_check():
    """The README block runs in parts (tests/cli/test_readme_block_<k>.py): every line in exactly one part,
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
