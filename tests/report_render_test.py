#!/usr/bin/python3
"""CTest driver: decomposes MODEL quickly (with molds), then opens its report.html in headless
Chromium from disk: the page must say it is ready and log nothing (a console message, an error
among them, fails), every part's colour must appear in a screenshot of its unlit exploded view,
and `dhfcast report --png` must draw preview.png and molds.png. Exits 77 (skipped) when the model,
Chromium or python3-pil is missing.

    tests/report_render_test.py DHFCAST MODEL SCALE
"""
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

SKIP = 77


def skip(why):
    print(f"report_render_test: skipped: {why}")
    sys.exit(SKIP)


def fail(why):
    print(f"report_render_test: FAILED: {why}")
    sys.exit(1)


def chromium(page, work, *extra):
    """Runs headless Chromium on the file `page`; returns its stdout and its console lines."""
    profile = tempfile.mkdtemp(dir=work)
    args = ["chromium", "--headless", "--disable-gpu", "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader", "--disable-quic", "--no-first-run",
            "--disable-background-networking", "--disable-component-update", "--disable-sync",
            "--hide-scrollbars", f"--user-data-dir={profile}", "--window-size=1000,700",
            "--virtual-time-budget=30000", "--enable-logging=stderr", "--v=0", *extra,
            "file://" + page]
    if os.geteuid() == 0:
        args.insert(1, "--no-sandbox")
    r = subprocess.run(args, capture_output=True, text=True, timeout=180)
    # The software GL driver's performance notes, and the messages of Chromium's own pages
    # (chrome://), are the browser's, not the page's.
    console = [line for line in r.stderr.splitlines()
               if ":CONSOLE" in line and "GL Driver Message" not in line
               and "source: chrome://" not in line]
    if r.returncode != 0:
        fail(f"chromium exited with {r.returncode}: {r.stderr[-2000:]}")
    return r.stdout, console


def main():
    dhfcast, model, scale = sys.argv[1], sys.argv[2], sys.argv[3]
    if not os.path.isfile(model):
        skip(f"{model} absent (install libcgal-demo)")
    if not shutil.which("chromium"):
        skip("chromium absent (scripts/install-deps.sh installs it)")
    try:
        from PIL import Image
    except ImportError:
        skip("python3-pil absent (scripts/install-deps.sh installs it)")

    work = tempfile.mkdtemp(prefix="dhfcast-report-test-")
    try:
        out = os.path.join(work, "out")
        subprocess.run([dhfcast, "decompose", model, "-o", out, "--scale", scale, "--tets", "3000",
                        "--directions", "64", "--restarts", "2", "--quiet"], check=True)
        page = os.path.join(out, "report.html")
        if not os.path.isfile(page):
            fail("decompose wrote no report.html")
        with open(page, encoding="utf-8") as f:
            html = f.read()
        data = json.loads(re.search(
            r'<script type="application/json" id="report-data">(.*?)</script>', html, re.S)
            .group(1))
        colors = [p["color"] for p in data["parts"]]
        print(f"report.html: {len(html)} bytes, {len(colors)} parts")
        if len(colors) < 2:
            fail(f"{model} gave {len(colors)} part: the test needs several")

        # The page, opened from disk with the network unused: ready, and not a console line.
        dom, console = chromium(page, work, "--dump-dom")
        status = re.search(r'<body[^>]*data-status="([^"]*)"', dom)
        if not status or status.group(1) != "ready":
            fail(f"the page is not ready: status {status and status.group(1)}; "
                 f"console: {console}")
        if console:
            fail("the page logged to its console:\n" + "\n".join(console))

        # Unlit colours, parts far apart: each part's colour appears as it is, in many pixels.
        shot = os.path.join(work, "flat.png")
        _, console = chromium(page + "#shot=parts&flat&explode=1", work, f"--screenshot={shot}")
        if console:
            fail("the page logged to its console:\n" + "\n".join(console))
        counts = Image.open(shot).convert("RGB").getcolors(maxcolors=1 << 24)
        seen = {"#%02x%02x%02x" % rgb: n for n, rgb in counts}
        for part, color in enumerate(colors):
            pixels = seen.get(color, 0)
            print(f"part {part}: colour {color}, {pixels} pixels")
            if pixels < 30:
                fail(f"part {part}'s colour {color} is not in the screenshot ({pixels} pixels)")

        # The previews: `dhfcast report --png` writes them, and the page again.
        os.remove(page)
        subprocess.run([dhfcast, "report", out, "--png", "--quiet"], check=True)
        with open(page, encoding="utf-8") as f:
            if f.read() != html:
                fail("dhfcast report wrote another report.html than decompose for the same folder")
        for name in ("preview.png", "molds.png"):
            image = Image.open(os.path.join(out, name)).convert("RGB")
            distinct = len(image.getcolors(maxcolors=1 << 24))
            print(f"{name}: {image.size[0]}x{image.size[1]}, {distinct} colours")
            if distinct < 50:
                fail(f"{name} looks empty ({distinct} colours)")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print("report_render_test: passed")


if __name__ == "__main__":
    main()
