"""The demo (the main job on built-in defaults), run once for the test session: its results make sense (its
``summary.json``, the document ``--json`` prints), what it says on stdout matches them, and its ``report.html``
renders in a real browser (headless Chromium): every ``<img>`` loads (non-zero natural size, not blank), no
console or script errors, and every embedded PNG decodes to a picture (not a single colour).  The browser checks
are skipped where Chromium is not installed.  The run is the README block's ``inscal demo --quick`` (part 0,
tests/cli/test_readme_block_0.py) where that part ran first in this session, else the same command here (see
demo_share)."""

from __future__ import annotations

import base64
import io as _io
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import demo_share
import pytest
from typer.testing import CliRunner

import inscal.cli.demo as demo_cli
from inscal.cli.app import app
from inscal.io.jsonfile import to_jsonable
from inscal.io.paramfile import load_params

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
def demo_run(tmp_path_factory):
    """``(folder, stdout)`` of ``inscal demo --quick`` (``--out`` its default, ``demo-output``), the folder a
    copy of this module's own: the README block's run (:mod:`demo_share`) where it is done, else a run here."""
    base = tmp_path_factory.mktemp("demo")
    shared = demo_share.shared_dir(tmp_path_factory)
    with demo_share.locked(shared):  # waits while the README's part runs its demo on another worker
        stdout = demo_share.published(shared)
        if stdout is not None:
            shutil.copytree(shared / demo_share.FOLDER, base / demo_share.FOLDER)
    if stdout is None:
        r = CliRunner().invoke(app, ["demo", "--out", str(base / demo_share.FOLDER), "--quick"])
        assert r.exit_code == 0, r.output
        stdout = r.stdout
    return base / demo_share.FOLDER, stdout


@pytest.fixture(scope="module")
def demo(demo_run):
    return demo_run[0]


def test_demo_quick_json(demo_run):
    folder, stdout = demo_run
    base = folder.parent  # the paths in the document: relative to the command's folder (the README's run)
    res = json.loads((folder / "summary.json").read_text(encoding="utf-8"))
    steps = res["steps"]
    assert steps["simulate_s16"]["samples"] == 386100
    cal = steps["calibrate"]
    # the proposed method estimates the 20" non-orthogonality within a few tenths of an arcsecond
    assert abs(cal["n25"]["gimbal_nonorthogonality"]["error"][0]) < 1.0
    # the six-position scheme's z accelerometer bias error is the eq. 21 leveling/non-orthogonality term
    assert abs(cal["six-position"]["accel_bias"]["error"][2]) > 100 * abs(cal["n25"]["accel_bias"]["error"][2])
    # S16: the 51-state systematic filter reaches the S16 Table 2 figures for the quadratic terms and the
    # lever arm; the 30-state filter leaves them (and, through them, the linear terms) uncompensated
    sysc = steps["systematic_s16"]
    g51, g30 = sysc["systematic51"]["groups"], sysc["systematic30"]["groups"]
    assert g51["accel_nonlinearity"]["mean_abs_error"] < g51["accel_nonlinearity"]["s16"] == 1.3
    assert g51["accel_cross_coupling"]["mean_abs_error"] < g51["accel_cross_coupling"]["s16"] == 1.5
    assert g51["accel_lever_arm"]["mean_abs_error"] < 0.03  # cm (S16: 0.01; sigma ~0.008 here)
    assert g51["gyro_g_sensitivity"]["mean_abs_error"] < 0.005 and g51["gyro_g_sensitivity"]["estimated"]
    for g, before in (("gyro_g_sensitivity", 0.001), ("accel_nonlinearity", 300.0), ("accel_cross_coupling", 300.0),
                      ("accel_lever_arm", 2.0)):
        assert not g30[g]["estimated"] and g30[g]["mean_abs_error"] == pytest.approx(before, rel=1e-6)
    assert g30["accel_bias"]["mean_abs_error"] > 100 * g51["accel_bias"]["mean_abs_error"]
    assert 4.0 < sysc["systematic51"]["nis_mean"] < 8.0 < sysc["systematic30"]["nis_mean"]
    for m in ("systematic51", "systematic30"):
        _, _, meta = load_params(base / sysc[m]["out"])
        assert meta["method"] == m and meta["metadata"]["states"] == m[-2:]
    nav = steps["navigate"]
    assert nav["n25"]["max_position_error_m"] < nav["six-position"]["max_position_error_m"] < nav["uncalibrated"]["max_position_error_m"]
    # the report: self-contained HTML, the figures as PNG files, summary.json where the document says
    rep = res["report"]
    html = (base / rep["html"]).read_text(encoding="utf-8")
    assert html.count("<img ") == len(rep["figures"]) == 7 and "data:image/png;base64," in html
    assert all((base / f).stat().st_size > 10_000 for f in rep["figures"].values())
    assert (base / rep["summary"]).resolve() == (folder / "summary.json").resolve()
    # stdout: the steps as they ran, the same figures, and the last line says where the report is
    assert f"simulated s16: {steps['simulate_s16']['samples']} samples" in stdout
    assert f"report: {rep['html']} ({len(rep['figures'])} figures" in stdout
    assert stdout.rstrip().splitlines()[-1] == (f"demo finished in {res['elapsed_s']:.1f} s; files in {res['out']}/; "
                                                f"open {rep['html']}")
    assert nav["n25"]["final_attitude_deg"]["heading"] == pytest.approx(
        (90.0 - nav["n25"]["final_attitude_deg"]["yaw"]) % 360.0)
    # a second run refuses to overwrite without --force
    r = CliRunner().invoke(app, ["demo", "--out", str(folder), "--quick"])
    assert r.exit_code != 0 and "exists" in r.stderr


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


def test_demo_json_prints_the_summary_quietly(monkeypatch, tmp_path):
    """``--json``: stdout is the result dict exactly as ``summary.json`` holds it (one JSON document, nothing
    else), the run told to stay quiet and draw no progress (the full run is checked above through its file)."""
    seen = {}
    res = {"steps": {"x": np.float64(1.5), "n": np.int64(3), "bad": float("nan")}, "elapsed_s": 0.25,
           "out": "d", "report": {"html": "d/report.html"}}

    def fake(out, force, seed, quick, show, log):
        seen.update(out=out, quick=quick, show=show)
        log("a progress line that --json must not print")
        return res

    monkeypatch.setattr(demo_cli, "run_demo", fake)
    r = CliRunner().invoke(app, ["demo", "--out", str(tmp_path / "d"), "--quick", "--json"])
    assert r.exit_code == 0, r.output
    assert r.stdout == json.dumps(to_jsonable(res), indent=2) + "\n"  # the bytes summary.json gets
    assert json.loads(r.stdout)["steps"] == {"x": 1.5, "n": 3, "bad": None}
    assert seen == {"out": tmp_path / "d", "quick": True, "show": False}
