"""The demo's ``report.html`` renders in a real browser (headless Chromium): every ``<img>`` loads
(non-zero natural size, not blank), no console or script errors, and every embedded PNG decodes
to a picture (not a single colour).  Skipped where Chromium is not installed."""

from __future__ import annotations

import base64
import io as _io
import json
import os
import re
import shutil
import subprocess

import numpy as np
import pytest
from typer.testing import CliRunner

from inscal.cli.app import app

CHROMIUM = next((shutil.which(n) for n in ("chromium", "chromium-browser") if shutil.which(n)), None)

#: appended to a copy of the report: after the load event, writes one JSON line per image (its
#: size, whether it decoded, and whether its pixels vary) and the errors seen into <pre id=result>
PROBE = """
<script>
window.__errors = [];
window.addEventListener('error', function (e) { window.__errors.push('error: ' + (e.message || e.type)); }, true);
var _ce = console.error;
console.error = function () { window.__errors.push('console.error: ' + Array.from(arguments).join(' ')); _ce.apply(console, arguments); };
function __varies(img) {
  try {
    var c = document.createElement('canvas');
    c.width = Math.min(img.naturalWidth, 400); c.height = Math.min(img.naturalHeight, 400);
    var g = c.getContext('2d');
    g.drawImage(img, 0, 0, c.width, c.height);
    var d = g.getImageData(0, 0, c.width, c.height).data;
    var lo = 255, hi = 0;
    for (var i = 0; i < d.length; i += 4) { var v = d[i] + d[i + 1] + d[i + 2]; if (v < lo) lo = v; if (v > hi) hi = v; }
    return hi - lo;
  } catch (e) { return -1; }
}
window.addEventListener('load', function () {
  var out = Array.from(document.images).map(function (img) {
    return {alt: img.alt, src_len: img.src.length, complete: img.complete, naturalWidth: img.naturalWidth,
            naturalHeight: img.naturalHeight, range: __varies(img)};
  });
  var pre = document.createElement('pre');
  pre.id = 'result';
  pre.textContent = JSON.stringify({images: out, errors: window.__errors});
  document.body.appendChild(pre);
});
</script>
"""


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo") / "d"
    r = CliRunner().invoke(app, ["demo", "--out", str(out), "--quick"])
    assert r.exit_code == 0, r.output
    return out


def chromium(*args, timeout=120):
    if CHROMIUM is None:
        pytest.skip("chromium not installed: apt-get install chromium (Debian) to run the browser check")
    cmd = [CHROMIUM, "--headless=new", "--disable-gpu", "--no-sandbox", "--no-first-run", "--hide-scrollbars",
           "--enable-logging=stderr", "--v=0", *map(str, args)]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env={**os.environ, "LANG": "C"})


def test_report_files(demo):
    html = (demo / "report.html").read_text(encoding="utf-8")
    summary = json.loads((demo / "summary.json").read_text(encoding="utf-8"))
    assert summary["steps"]["calibrate"]["n25"]["gimbal_nonorthogonality"]["unit"] == "arcsec"
    assert set(summary["report"]["figures"]) >= {"allan", "s16-table2", "nav-comparison", "nav-uncalibrated",
                                                 "nav-six-position", "nav-n25", "nav-joint"}
    for f in summary["report"]["figures"].values():
        assert (demo / os.path.basename(f)).stat().st_size > 10_000
    for name in ("params-n25.toml", "params-six-position.toml", "params-joint.toml", "params-systematic51.toml"):
        assert (demo / name).exists()
    # self-contained: every image embedded, nothing fetched
    srcs = re.findall(r"<img[^>]*\ssrc='([^']*)'", html)
    assert len(srcs) == len(summary["report"]["figures"])
    assert all(s.startswith("data:image/png;base64,") for s in srcs)
    assert not re.search(r"(?:src|href)=['\"](?:https?:|//|file:)", html)
    # readable units: the mount yaw (~20 deg) in degrees, small angles in arcsec, field units
    for unit in ("° (errors in arcsec)", "arcsec", "ppm", "µg", "°/h", "µg/g²", "cm", "S16 Table 2", "error/σ"):
        assert unit in html, unit
    for img in srcs:
        import matplotlib.image as mpimg

        a = mpimg.imread(_io.BytesIO(base64.b64decode(img.split(",", 1)[1])), format="png")
        assert a.ndim == 3 and a.shape[0] > 200 and a.shape[1] > 400
        rgb = a[..., :3].reshape(-1, 3)
        assert np.ptp(rgb) > 0.5 and len(np.unique(rgb[:: max(1, len(rgb) // 20000)], axis=0)) > 20  # not one colour


def test_report_renders_in_chromium(demo, tmp_path):
    page = tmp_path / "probe.html"
    html = (demo / "report.html").read_text(encoding="utf-8")
    page.write_text(html.replace("</body>", PROBE + "</body>"), encoding="utf-8")
    r = chromium(f"--user-data-dir={tmp_path / 'profile'}", "--virtual-time-budget=10000", "--dump-dom",
                 page.as_uri())
    assert r.returncode == 0, r.stderr[-2000:]
    m = re.search(r"<pre id=\"result\">(.*?)</pre>", r.stdout, re.S)
    assert m, "the probe did not run: " + r.stdout[-500:]
    import html as _html

    res = json.loads(_html.unescape(m.group(1)))
    assert res["errors"] == []
    console = [line for line in r.stderr.splitlines() if ":CONSOLE" in line]
    assert console == [], console
    imgs = res["images"]
    assert len(imgs) == html.count("<img ")
    for im in imgs:
        assert im["complete"] and im["src_len"] > 10_000, im
        assert im["naturalWidth"] > 400 and im["naturalHeight"] > 200, im
        assert im["range"] > 300, im  # pixel values vary: not blank (-1: the canvas check failed)
    # a screenshot of the whole page, kept next to the report for a person to look at
    shot = demo / "report-screenshot.png"
    r = chromium(f"--user-data-dir={tmp_path / 'profile2'}", f"--screenshot={shot}", "--window-size=1300,9000",
                 (demo / "report.html").as_uri())
    assert r.returncode == 0 and shot.exists(), r.stderr[-2000:]
    import matplotlib.image as mpimg

    a = mpimg.imread(shot)
    assert np.ptp(a[..., :3]) > 0.5
