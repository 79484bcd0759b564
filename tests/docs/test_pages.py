"""The site's pages against the code and the repository: every console block either runs in the tests or is
marked as not run; every file, folder and page a page names exists; the formats reference lists every mapping
key, import and export format the code accepts; the budget page's station file is a complete station.

A block runs when the line before its fence is ``% run: TEST`` (a test file that reads the page and runs the
block), or when each of its command lines is a line of such a block (the same command, run there); it is
marked ``% not run: REASON`` otherwise.  A block that shows printed output (a line starting with ``#``) is
compared by its test (tests/cli/test_site_pages.py compares line by line), or says in its reason when and how
its output was last checked."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
GENERATED = {"theory/equation-index.md"}
FENCE = re.compile(r"(?:^(%[^\n]*)\n)?^```(\{?[\w-]*\}?)[^\n]*\n(.*?)^```", re.S | re.M)  # a directive ({image}) too
COMMAND = re.compile(r"^\s*(?:\$ )?(inscal|make|cmp|export|source|\.venv/bin/inscal)\b")


def pages() -> list[Path]:
    """The site's Markdown pages (not the generated ones) and the README."""
    out = [p for p in sorted(DOCS.rglob("*.md"))
           if not {"_build", "auto_examples", "generated"} & set(p.parts)
           and p.relative_to(DOCS).as_posix() not in GENERATED]
    return out + [ROOT / "README.md"]


def command_blocks():
    """``(page, line number, marker or None, lines)`` of every fenced shell block with a command in it (the
    README's are lines of the command-line session: tests/cli/test_readme.py checks them)."""
    for page in pages()[:-1]:
        text = page.read_text(encoding="utf-8")
        for m in FENCE.finditer(text):
            if m.group(2) not in ("", "bash", "console", "text", "sh", "shell"):
                continue
            lines = m.group(3).splitlines()
            if any(COMMAND.match(ln) for ln in lines):
                yield page, text[:m.start(2)].count("\n") + 1, m.group(1), lines


def commands(lines: list[str]) -> list[str]:
    return [" ".join(ln.split(" #")[0].split()) for ln in lines if COMMAND.match(ln)]


def test_every_console_block_runs_or_is_marked_not_run():
    blocks = list(command_blocks())
    run_lines: set[str] = set()
    for page, _, marker, lines in blocks:
        if marker and marker.startswith("% run: "):
            test = ROOT / marker.removeprefix("% run: ").strip()
            assert test.is_file(), f"{page}: {marker}: no such test"
            assert page.name in test.read_text(encoding="utf-8"), f"{test.name} does not read {page.name}"
            run_lines |= set(commands(lines))
    bad = []
    counts = {"run": 0, "same lines": 0, "not run": 0}
    for page, line, marker, lines in blocks:
        where = f"{page.relative_to(ROOT)}:{line}"
        shows_output = any(ln.startswith("#") for ln in lines)
        if marker and marker.startswith("% run: "):
            counts["run"] += 1
        elif marker and marker.startswith("% not run: ") and len(marker) > 20:
            counts["not run"] += 1
            if shows_output and not re.search(r"checked|compared", marker):
                bad.append(f"{where}: shows output but is not run, and does not say when it was checked")
        elif set(commands(lines)) <= run_lines and not shows_output:
            counts["same lines"] += 1
        else:
            missing = sorted(set(commands(lines)) - run_lines)[:2]
            bad.append(f"{where}: neither run nor marked (% not run: REASON); not run elsewhere: {missing}")
    assert not bad, "\n".join(bad)
    assert counts["run"] >= 10 and counts["not run"] >= 1, counts
    print(counts)


#: a path a page names: under a folder of the repository, or a module of the package
PATH = re.compile(r"`((?:src|tests|bench|docs|\.ci)/[\w./*-]+|inscal/[\w/]+\.py)`")


def test_every_file_and_link_a_page_names_exists():
    bad = []
    for page in pages():
        text = page.read_text(encoding="utf-8")
        for name in PATH.findall(text):
            target = ROOT / ("src/" + name if name.startswith("inscal/") else name)
            if "*" in name:
                ok = any(target.parent.glob(target.name))
            else:
                ok = (target.exists() or (target.parent.name == "reference" and target.suffix == ".md")
                      or "_build" in target.parts)  # the site's own build output (make docs)
            if not ok:
                bad.append(f"{page.relative_to(ROOT)}: `{name}` does not exist")
        for link in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text):
            if re.match(r"\w+://", link):
                continue
            if not (page.parent / link).exists():
                bad.append(f"{page.relative_to(ROOT)}: link {link} does not exist")
        for doc in re.findall(r"\{doc\}`(?:[^`<]*<)?([^`>]+)>?`", text):
            base = page.parent if not doc.startswith("/") else DOCS
            target = (base / doc.lstrip("/"))
            if "auto_examples" in target.parts:
                target = DOCS / "examples" / target.name
                ok = target.with_suffix(".py").is_file() or target.name == "index"
            elif "api" in target.parts or target.name in ("cli", "equation-index"):
                ok = True  # generated at build time (docs/_ext/inscal_docs.py)
            else:
                ok = any(target.with_suffix(s).is_file() for s in (".md", ".rst"))
            if not ok:
                bad.append(f"{page.relative_to(ROOT)}: {{doc}} {doc} does not exist")
        for image in re.findall(r"```\{image\} /auto_examples/images/sphx_glr_(\w+?)_\d{3}\.png", text):
            if not (DOCS / "examples" / f"{image}.py").is_file():
                bad.append(f"{page.relative_to(ROOT)}: no example {image}.py for its figure")
    assert not bad, "\n".join(bad)


def formats_page() -> str:
    return (DOCS / "reference" / "formats.md").read_text(encoding="utf-8")


def allowed_keys(doc: dict) -> list[str]:
    """The keys the mapping reader allows where ``doc`` puts an unknown one (read from its refusal)."""
    from inscal.io.mapping import ImportFileError, parse_mapping

    with pytest.raises(ImportFileError) as exc:
        parse_mapping(doc, "csv")
    return re.findall(r"'(\w+)'", str(exc.value).split("allowed:")[1])


def test_the_formats_reference_lists_every_mapping_key_and_format():
    from inscal.io.exports.calibration import CALIBRATION_FORMATS, NOISE_FORMATS
    from inscal.io.mapping import EXPORT_FORMATS, FORMATS, KINDS

    page = formats_page()
    sec = page[page.index("## The mapping of a CSV"):page.index("## Other tools' formats")]
    block = re.search(r"```toml\n(.*?)```", sec, re.S).group(1)
    columns = {"time": 0, "gx": 1, "gy": 2, "gz": 3, "ax": 4, "ay": 5, "az": 6}
    top = allowed_keys({"bogus": 1, "columns": columns})
    cols = allowed_keys({"columns": {**columns, "bogus": 7}})
    unit = allowed_keys({"columns": columns, "units": {"bogus": "s"}})
    site = allowed_keys({"site": {"bogus": 1.0}, "columns": columns})
    assert {"kind", "max_gap_s", "columns", "units"} <= set(top) and "gyro_bits" in unit and "gx" in cols, (top, unit)
    written = set(re.findall(r"^#?\s*(\w+)\s*=", block, re.M)) | set(re.findall(r"^\[(\w+)\]", block, re.M))
    missing = [k for k in top + cols + unit + site if k not in written]
    assert not missing, f"formats.md's mapping lacks {missing}"
    for kind in KINDS:
        assert f'"{kind}"' in block, kind
    table = page[page.index("## Other tools' formats"):]
    for fmt in FORMATS:
        assert f"`{fmt}`" in table, f"import format {fmt} is not in formats.md"
    for fmt in list(EXPORT_FORMATS) + list(CALIBRATION_FORMATS) + list(NOISE_FORMATS):
        assert f"`{fmt}`" in table, f"export format {fmt} is not in formats.md"
    assert "schema v2" not in page and "{{ db_schema }}" in page  # the version comes from the code (conf.py)


def test_the_budget_pages_station_file_is_the_complete_station(tmp_path):
    import tomllib

    from inscal.uncertainty.station import INPUTS, read_station

    page = (DOCS / "guide" / "uncertainty-budget.md").read_text(encoding="utf-8")
    block = re.search(r"```toml\n(# station\.toml\n.*?)```", page, re.S).group(1)
    (tmp_path / "station.toml").write_text(block)
    station = read_station(tmp_path / "station.toml")  # as inscal reads it: every input there, every field valid
    doc = tomllib.loads(block)
    assert set(doc["inputs"]) == set(INPUTS), sorted(set(INPUTS) ^ set(doc["inputs"]))
    assert doc == tomllib.loads((ROOT / "tests" / "data" / "station.toml").read_text())
    assert station.name == "T-2, lab 3"
