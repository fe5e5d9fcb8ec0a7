"""The HTML reports of `chunkc audit` and `chunkc analyze` as a person sees them, in headless
Chromium (scripts/setup.sh installs Debian's `chromium`): every chart is laid out at a readable
size and has marks in it, the verdict table holds the verdicts, and the screenshot shows the
charts' colours (the verdict colours of the audit's episodes, the analyze curves)."""

import json
import shutil
import subprocess
import tempfile

import numpy as np
import pytest
from PIL import Image

from conftest import run_chunkc, write_spec
from test_audit import EXPECTED, write_audit_spec, write_faulty_source

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
# What a page reports about itself once laid out: each chart's size and number of marks, and
# the text of every table.
PROBE = """<script>
(() => {
  const svgs = [...document.querySelectorAll('svg')].map(s => {
    const r = s.getBoundingClientRect();
    return {w: r.width, h: r.height, marks: s.querySelectorAll('path, polyline, polygon, rect, circle, line').length};
  });
  const tables = [...document.querySelectorAll('table')].map(t =>
    [...t.querySelectorAll('tr')].map(row => [...row.cells].map(c => c.innerText.trim())));
  const pre = document.createElement('pre');
  pre.id = 'chunkc-probe';
  pre.textContent = JSON.stringify({svgs, tables});
  document.body.appendChild(pre);
})();
</script>"""
# The verdict colours of src/report/plot.rs (ok, interpolate, resample).
VERDICT_RGB = {"ok": (46, 139, 62), "interpolate": (230, 149, 0), "resample": (31, 111, 180)}


def chromium(*args):
    if CHROMIUM is None:
        pytest.fail("headless Chromium is not installed: scripts/setup.sh installs Debian's `chromium`")
    profile = tempfile.mkdtemp()
    try:
        return subprocess.run(
            [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             "--hide-scrollbars", f"--user-data-dir={profile}", "--enable-logging=stderr", "--v=0", *args],
            capture_output=True, text=True, timeout=180,
        )
    finally:
        shutil.rmtree(profile, ignore_errors=True)


def look(page, tmp_path):
    """(probe, screenshot pixels, console errors) of an HTML report."""
    probed = tmp_path / (page.stem + "-probed.html")
    html = page.read_text()
    assert "</body>" in html
    probed.write_text(html.replace("</body>", PROBE + "</body>"))
    dom = chromium("--dump-dom", probed.as_uri())
    assert dom.returncode == 0, dom.stderr
    errors = [l for l in dom.stderr.splitlines() if "CONSOLE" in l or "net::ERR" in l]
    probe = json.loads(dom.stdout.split('<pre id="chunkc-probe">')[1].split("</pre>")[0]
                       .replace("&quot;", '"').replace("&amp;", "&").replace("&lt;", "<").replace("&gt;", ">"))
    shot = tmp_path / (page.stem + ".png")
    proc = chromium(f"--screenshot={shot}", "--window-size=1280,6000", page.as_uri())
    assert proc.returncode == 0 and shot.exists(), proc.stderr
    pixels = np.asarray(Image.open(shot).convert("RGB")).astype(np.int32)
    return probe, pixels, errors


def near(pixels, rgb, tol=12):
    return int((np.abs(pixels - np.asarray(rgb)).max(axis=-1) <= tol).sum())


def test_audit_report_shows_charts_and_verdicts(tmp_path):
    source = tmp_path / "faulty.hdf5"
    write_faulty_source(source)
    run_chunkc("audit", write_audit_spec(tmp_path, source))
    probe, pixels, errors = look(tmp_path / "out" / "audit" / "report.html", tmp_path)
    assert errors == []
    assert probe["svgs"], "no chart on the page"
    for svg in probe["svgs"]:
        assert svg["w"] >= 300 and svg["h"] >= 100 and svg["marks"] >= 5, svg
    # The verdict table: one row per verdict with its count, as the audit decided.
    verdicts = next(t for t in probe["tables"] if t and t[0][:2] == ["verdict", "episodes"])
    counts = {row[0]: int(row[1]) for row in verdicts[1:]}
    for verdict in set(EXPECTED.values()):
        assert counts[verdict] == list(EXPECTED.values()).count(verdict), counts
    # The charts are drawn in the verdicts' colours: visible, not only present in the markup.
    for verdict in set(EXPECTED.values()):
        assert near(pixels, VERDICT_RGB[verdict]) >= 50, verdict
    assert (pixels.sum(axis=-1) < 600).mean() > 0.01  # text and marks on the white page


def test_analyze_report_shows_the_autocorrelation_chart(tmp_path):
    run_chunkc("analyze", write_spec(tmp_path, '[profiles.dp]\npreset = "diffusion_policy"\n'
                                     '[profiles.act]\npreset = "act"\nfps = 10\nchunk = 20\n'))
    probe, pixels, errors = look(tmp_path / "out" / "audit" / "analyze.html", tmp_path)
    assert errors == []
    assert len(probe["svgs"]) == 1
    svg = probe["svgs"][0]
    assert svg["w"] >= 300 and svg["h"] >= 150 and svg["marks"] >= 5, svg
    # A table checks each profile's K.
    text = json.dumps(probe["tables"])
    assert "dp" in text and "act" in text
    # Drawn, in the chart's colours: the dashed 0.3 threshold (red), a profile's K (orange), the
    # per-dimension curves (blue, thin and anti-aliased) and the thick mean curve.
    assert near(pixels, (200, 50, 45), tol=40) >= 100
    assert near(pixels, (230, 120, 20), tol=40) >= 50
    assert near(pixels, (31, 111, 180), tol=60) >= 20
    assert near(pixels, (0, 0, 0), tol=30) >= 500
