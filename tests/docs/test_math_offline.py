"""The site's equations are typeset offline: a theory page of the built site (``make docs``), opened from disk in
headless Chromium with every network request refused, shows every equation typeset by the MathJax copy the site
ships (an SVG in each), none left as TeX.  ``make docs`` runs the same check on every theory page as it builds
(docs/_ext/inscal_site.py); here it runs when the site has been built and Chromium is installed, and is skipped,
with the reason, otherwise.  The page itself must load MathJax from the site, not from a network address."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[2] / "docs"
SITE = DOCS / "_build" / "html"
sys.path.insert(0, str(DOCS / "_ext"))
inscal_site = pytest.importorskip("inscal_site", reason="the docs extra (Sphinx) is not installed")


def test_a_theory_page_loads_mathjax_from_the_site():
    page = SITE / "theory" / "noise.html"
    if not page.is_file():
        pytest.skip("the site is not built (make docs)")
    text = page.read_text(encoding="utf-8")
    scripts = re.findall(r'<script[^>]+src="([^"]*mathjax[^"]*)"', text, re.I)
    assert scripts and not any("://" in s for s in scripts), scripts
    assert all((page.parent / s.split("?")[0]).is_file() for s in scripts), scripts


def test_a_theory_page_is_typeset_offline_in_chromium():
    page = SITE / "theory" / "noise.html"
    if not page.is_file():
        pytest.skip("the site is not built (make docs)")
    browser = inscal_site.chromium()
    if browser is None:
        pytest.skip("chromium not installed: apt-get install chromium (Debian) to run the browser check")
    n = len(inscal_site.MATH_ELEMENT.findall(page.read_text(encoding="utf-8")))
    typeset, raw = inscal_site.typeset_equations(page, browser)
    assert n >= 5 and not raw and typeset == n, (n, typeset, raw[:3])
