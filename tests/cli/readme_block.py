"""The command block of the site's "Every command in one session" page (``docs/guide/command-line.md``,
which the README's tour quotes), run as written in parts that share no file, so that the parts run beside
each other (``make test`` gives each test file to one worker): ``tests/cli/test_readme_block_<k>.py`` runs
part ``k``.

A part is a set of connected components of the block: lines are connected when they name the same file
(``s16.h5``, ``n25.toml``, ``plots/``...), so a line runs after the lines that write its inputs, in the
block's order, in the part's own empty folder.  The checks of meaningful results run in the part that
holds their lines; ``tests/cli/test_readme.py`` checks that the parts cover every line exactly once and
that every check finds its lines."""

from __future__ import annotations

import contextlib
import json
import os
import re
import sys
from pathlib import Path

import demo_share
from forkserver import Shell

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "guide" / "command-line.md"
TEXT = PAGE.read_text(encoding="utf-8")
#: how many test files run the block
PARTS = 3
#: a word of a command line that names a file or folder the line reads or writes
FILE_WORD = re.compile(r"^[\w.-]+(\.(h5|toml|csv|html|png|json|sqlite|pdf|bin|mat)|/)$")


def command_block() -> list[str]:
    """The first fenced block after '## The session': one inscal command per line."""
    sec = TEXT[TEXT.index("## The session"):]
    m = re.search(r"```\n(.*?)```", sec, re.DOTALL)
    lines = [ln.strip() for ln in m.group(1).splitlines() if ln.strip()]
    assert lines and all(ln.startswith("inscal ") for ln in lines), lines
    return lines


def files_of(line: str) -> set[str]:
    words = line.split("#")[0].split()
    out = {w for w in words[2:] if FILE_WORD.match(w)}
    for flag in ("--out", "--plots", "--plot"):  # an output folder need not look like a file
        if flag in words and words.index(flag) + 1 < len(words):
            out.add(words[words.index(flag) + 1].rstrip("/") + ("/" if flag == "--plots" else ""))
    return out


def components(lines: list[str]) -> list[list[int]]:
    """Lines (indices, in block order) connected through the files they name."""
    parent = list(range(len(lines)))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    seen: dict[str, int] = {}
    for i, line in enumerate(lines):
        for f in files_of(line):
            if f in seen:
                parent[root(i)] = root(seen[f])
            else:
                seen[f] = i
    groups: dict[int, list[int]] = {}
    for i in range(len(lines)):
        groups.setdefault(root(i), []).append(i)
    return sorted(groups.values())


def parts(lines: list[str]) -> list[list[int]]:
    """The components dealt round-robin (in order of first line) to ``PARTS`` parts."""
    out: list[list[int]] = [[] for _ in range(PARTS)]
    for k, comp in enumerate(components(lines)):
        out[k % PARTS] += comp
    return [sorted(p) for p in out]


# ------------------------------------------------------------------------------------------- checks
def _line(outputs, pred):
    return next(outputs[ln] for ln in outputs if pred(ln))


def check_navigation(outputs, folder):
    """The calibration brings navigation errors down by an order of magnitude."""
    nav = [ln for ln in outputs if ln.startswith("inscal navigate")]
    raw = float(re.search(r"position error: max ([0-9.]+) m", outputs[nav[0]].stdout).group(1))
    comp = json.loads(outputs[nav[1]].stdout)["max_position_error_m"]
    assert raw > 10 * comp, (raw, comp)
    assert (folder / "nav.png").stat().st_size > 10_000


def check_rounded(outputs, folder):
    """The rounded duration of the rotation-modulation run is said."""
    assert "rounded up" in _line(outputs, lambda ln: "n25-rotmod" in ln).stdout


def check_allan(outputs, folder):
    """Allan: the N25 noise is found (ARW 0.02 deg/sqrt(h), VRW 20 ug/sqrt(Hz))."""
    al = json.loads(_line(outputs, lambda ln: ln.startswith("inscal allan")).stdout)
    assert all(abs(a / 0.02 - 1) < 0.1 for a in al["arw_deg_rth"]), al["arw_deg_rth"]
    assert all(abs(v / 20 - 1) < 0.1 for v in al["vrw_ug_rthz"]), al["vrw_ug_rthz"]


def check_n25(outputs, folder):
    """The N25 calibration finds the gimbal non-orthogonality (20 arcsec) within its sigma budget."""
    cal = json.loads(_line(outputs, lambda ln: "--method n25" in ln).stdout)
    d = cal["parameters"]["gimbal_nonorthogonality"]
    assert abs(d["error"][0]) < 5 * d["sigma"][0] and abs(d["value"][0] - 20) < 2


def check_systematic(outputs, folder):
    """The 30-state filter's misfit is reported; the 51-state fit is consistent."""
    s30 = _line(outputs, lambda ln: "systematic30" in ln).stdout
    assert "INCONSISTENT" in s30 and "try --states 51" in s30
    assert "consistent" in _line(outputs, lambda ln: "systematic51" in ln).stdout


#: (what the check needs in a line, check): a part runs the checks whose lines it ran
CHECKS = [
    (lambda ln: ln.startswith("inscal navigate"), check_navigation),
    (lambda ln: "n25-rotmod" in ln, check_rounded),
    (lambda ln: ln.startswith("inscal allan"), check_allan),
    (lambda ln: "--method n25" in ln, check_n25),
    (lambda ln: "systematic30" in ln or "systematic51" in ln, check_systematic),
]
#: files the block must leave behind (each checked in the part that writes it)
FILES = ("s16-51.toml", "n25.html", "st.html", "n25-comp.h5", "n25-imported.h5", "path20.toml", "mc-schemes/summary.json",
         "demo-output/report.html")


def run_part(k: int, folder: Path, servers, share: Path | None = None) -> None:
    """Run part ``k`` of the block in ``folder`` (the command lines as bash would split them, in forks of one
    process that imported the package, ``servers.get()`` of the ``fork_servers`` fixture: :class:`forkserver.Shell`;
    part 0's first line through the installed ``inscal`` script in bash, so that the entry point runs once),
    then its checks.  With ``share`` (:func:`demo_share.shared_dir`), the ``inscal demo`` line runs holding the
    session's demo lock and leaves its output there for ``tests/cli/test_demo_html.py``."""
    lines = command_block()
    mine = [lines[i] for i in parts(lines)[k]]
    bindir = Path(sys.executable).parent
    env = {**os.environ, "PATH": f"{bindir}{os.pathsep}{os.environ.get('PATH', '')}", "COLUMNS": "100"}
    outputs = {}
    shell = Shell(servers.get(), folder, env, folder.parent / f"{folder.name}-logs", script=k == 0)
    for line in mine:
        demo = share is not None and line.startswith("inscal demo")
        with demo_share.locked(share) if demo else contextlib.nullcontext():
            r = shell.run(line)
            assert r.returncode == 0, f"{line}\n{r.stderr[-2000:]}"
            assert "Traceback" not in r.stderr, line
            if demo:
                demo_share.publish(share, folder, r.stdout)
        outputs[line] = r
    for needs, check in CHECKS:
        if any(needs(ln) for ln in mine):
            check(outputs, folder)
    for f in FILES:
        if any(writes(ln, f) for ln in mine):
            assert (folder / f).is_file(), f


def writes(line: str, f: str) -> bool:
    """Whether a line of the block writes the file ``f`` (or the folder it is in)."""
    top = f.split("/")[0]
    return top in files_of(line) or top + "/" in files_of(line) or (top == "demo-output" and line.startswith("inscal demo"))
