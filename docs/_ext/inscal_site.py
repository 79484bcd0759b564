"""Sphinx extension of the inscal site: equations typeset offline, and the check that they are.

- MathJax 3 is served from the site itself (``_static/mathjax/``, the copy the PyPI package
  ``sphinx-mathjax-offline`` ships), with its SVG output, which needs no web font: the site opened from
  disk, with no network, shows typeset equations.
- When the HTML is written and Chromium is installed, every theory page is opened from disk in headless
  Chromium with every network request refused, and the build fails if an equation is left as TeX
  (:func:`typeset_equations`; ``tests/docs/test_math_offline.py`` runs the same check on a built site).
"""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

from sphinx.errors import ExtensionError
from sphinx.util.fileutil import copy_asset

#: the MathJax component loaded by every page with math (TeX input, SVG output: no font files)
MATHJAX = "mathjax/tex-svg.js"
#: Chromium's flags for a page opened from disk with every network request refused
CHROMIUM_FLAGS = ("--headless=new", "--disable-gpu", "--no-sandbox", "--no-first-run", "--hide-scrollbars",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--disable-quic", "--proxy-server=127.0.0.1:9", "--host-resolver-rules=MAP * ~NOTFOUND")
#: an equation Sphinx wrote for MathJax: ``<span class="math ...">`` or ``<div class="math ...">``
MATH_ELEMENT = re.compile(r'<(span|div) class="math notranslate nohighlight"[^>]*>(.*?)</\1>', re.S)


def mathjax_dir() -> Path:
    """The MathJax 3 distribution of the ``sphinx-mathjax-offline`` package."""
    spec = importlib.util.find_spec("sphinx-mathjax-offline")
    if spec is None or spec.origin is None:
        raise ExtensionError("the docs need the package sphinx-mathjax-offline (pip install -e '.[docs]')")
    return Path(spec.origin).parent / "static" / "mathjax"


def chromium() -> str | None:
    """Headless Chromium on PATH (or ``$INSCAL_CHROMIUM``), None if not installed."""
    given = os.environ.get("INSCAL_CHROMIUM")
    if given:
        return shutil.which(given)
    return next((p for n in ("chromium", "chromium-browser", "google-chrome") if (p := shutil.which(n))), None)


def typeset_equations(page: Path, browser: str, timeout: float = 120.0) -> tuple[int, list[str]]:
    """``(typeset, raw)`` of ``page`` opened from disk in headless Chromium with the network refused: the
    number of its equations MathJax typeset (an SVG inside), and the TeX of those it left as text."""
    with tempfile.TemporaryDirectory() as profile:
        r = subprocess.run([browser, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", "--virtual-time-budget=30000",
                            "--dump-dom", page.resolve().as_uri()], capture_output=True, text=True, timeout=timeout,
                           env={**os.environ, "LANG": "C"})
    if r.returncode != 0:
        raise RuntimeError(f"chromium failed on {page}: {r.stderr[-500:]}")
    typeset, raw = 0, []
    for m in MATH_ELEMENT.finditer(r.stdout):
        if "<mjx-container" in m.group(2) and "<svg" in m.group(2):
            typeset += 1
        else:
            raw.append(re.sub(r"\s+", " ", m.group(2))[:80])
    return typeset, raw


def _use_local_mathjax(app, config) -> None:
    config.mathjax_path = MATHJAX


def _copy_mathjax(app, exception) -> None:
    if exception is None and app.builder.format == "html":
        copy_asset(str(mathjax_dir()), str(Path(app.outdir) / "_static" / "mathjax"))


def check_theory_math(app, exception) -> None:
    """Fail the build when a theory page, opened from disk offline in Chromium, shows an equation as TeX."""
    if exception is not None or app.builder.format != "html":
        return
    browser = chromium()
    if browser is None:
        return  # no browser: nothing to open the pages with (CI installs Chromium)
    bad = []
    for page in sorted((Path(app.outdir) / "theory").glob("*.html")):
        if not MATH_ELEMENT.search(page.read_text(encoding="utf-8")):
            continue
        typeset, raw = typeset_equations(page, browser)
        if raw or not typeset:
            bad.append(f"{page.name}: {typeset} typeset, {len(raw)} left as TeX ({raw[:2]})")
    if bad:
        raise ExtensionError("equations not typeset offline: " + "; ".join(bad))


def setup(app):
    app.setup_extension("sphinx.ext.mathjax")
    app.connect("config-inited", _use_local_mathjax)
    app.connect("build-finished", _copy_mathjax, priority=400)
    app.connect("build-finished", check_theory_math, priority=600)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
