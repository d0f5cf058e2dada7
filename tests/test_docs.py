"""The documentation: a warning-free Sphinx build, the guide's doctests, and four pages
rendered in headless Chromium.

Needs the ``docs`` extra (``pip install -e ".[docs]"``) and, for the browser test,
Debian's ``chromium`` and ``chromium-driver``. Without them these tests skip with the
reason, except in CI (environment variable ``CI`` set), where they fail.

The HTML goes to ``docs/_build/html`` (the README's build command writes there too) and
the screenshots to ``docs/_build/screenshots``: build artefacts, ignored by git.
"""

import functools
import http.server
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import threading
import urllib.parse
import urllib.request
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
BUILD = DOCS / "_build"
DOCS_EXTRA = ("sphinx", "numpydoc", "pydata_sphinx_theme", "matplotlib", "scipy", "mpmath")


def _unavailable(reason):
    """Skip outside CI; in CI a missing tool is a failure, not a silent skip."""
    if os.environ.get("CI"):
        pytest.fail(f"{reason} (CI is set, so the documentation checks must run)", pytrace=False)
    pytest.skip(reason)


def _docs_extra():
    missing = [m for m in DOCS_EXTRA if importlib.util.find_spec(m) is None]
    if missing:
        _unavailable(f"the docs extra is not installed (missing {', '.join(missing)}): "
                     f'pip install -e ".[docs]"')


def _sphinx(builder, outdir):
    """Run a builder; the doctrees are where the README's command keeps them, so that a
    later ``python -m sphinx -W -b html docs docs/_build/html`` is incremental."""
    cmd = [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", builder,
           "-d", str(BUILD / "html" / ".doctrees"), str(DOCS), str(outdir)]
    if builder == "html":
        cmd.insert(3, "-E")        # a fresh environment: every page read, every warning seen
    return subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=900)


@pytest.fixture(scope="module")
def html():
    _docs_extra()
    out = BUILD / "html"
    run = _sphinx("html", out)
    assert run.returncode == 0, f"sphinx-build -W failed:\n{run.stdout}\n{run.stderr}"
    return out


def test_build_is_warning_free(html):
    for page in ("index.html", "guide/interpolation.html", "api/index.html",
                 "api/generated/quatarray.Rotation.html", "api/generated/quatarray.QuatArray.html"):
        assert (html / page).is_file(), page


def test_api_reference_lists_every_public_name(html):
    import quatarray
    text = "".join(p.read_text(encoding="utf-8") for p in (html / "api").glob("*.html"))
    names = [n for n in quatarray.__all__ if not isinstance(getattr(quatarray, n), type(quatarray))]
    missing = [n for n in names if f"quatarray.{n}.html" not in text]
    assert not missing, f"public names without a reference page: {missing}"


def test_quatarray_page_has_our_members_not_ndarrays(html):
    text = (html / "api" / "generated" / "quatarray.QuatArray.html").read_text(encoding="utf-8")
    assert 'id="quatarray.QuatArray.rotate"' in text
    assert 'id="quatarray.QuatArray.normalized"' in text
    for inherited in ("argmax", "tobytes", "cumsum", "searchsorted"):
        assert f'id="quatarray.QuatArray.{inherited}"' not in text, inherited


def test_guide_doctests(html):
    run = _sphinx("doctest", BUILD / "doctest")
    assert run.returncode == 0, f"doctests of the guide failed:\n{run.stdout}\n{run.stderr}"
    report = (BUILD / "doctest" / "output.txt").read_text(encoding="utf-8")
    assert "0 failures in tests" in report
    tested = [line for line in report.splitlines() if line.startswith("Document: guide/")]
    assert len(tested) >= 5, report


# ---- the README's links and figures (no Sphinx needed) --------------------------------

README = ROOT / "README.md"


def test_guide_and_readme_use_public_modules_only():
    """The guide's doctests imported quatarray._zarr.resample_zarr and quatarray._gltf.resample_gltf:
    the README and the guide name public modules only (quatarray.formats, ...)."""
    import re
    private = re.compile(r"\bquatarray\._\w+|\bfrom \._\w+ import")
    found = []
    for path in [ROOT / "README.md", *sorted((DOCS / "guide").glob("*.rst")), *sorted(DOCS.glob("*.rst"))]:
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if private.search(line):
                found.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert not found, "\n".join(found)
    assert private.search(">>> from quatarray._zarr import resample_zarr")      # the scan can fail


def test_readme_links_into_every_guide_page():
    """The README links the guide by source path (so the links work on GitHub too)."""
    links = [t for t in re.findall(r"\]\(([^)#\s]+)", README.read_text(encoding="utf-8"))
             if "://" not in t]
    assert [t for t in links if not (ROOT / t).is_file()] == []
    pages = {p.relative_to(ROOT).as_posix() for p in (DOCS / "guide").glob("*.rst")} - {"docs/guide/index.rst"}
    assert sorted(pages - set(links)) == []


def _readme_table(section):
    text = README.read_text(encoding="utf-8")
    start = text.index(f"\n## {section}\n")
    ends = [i for i in (text.find("\n## ", start + 1), text.find("\n### ", start + 1)) if i >= 0]
    end = min(ends, default=-1)   # up to the next heading (the size sweep has its own table)
    rows = [[c.strip() for c in line.strip("|").split("|")]
            for line in text[start:end if end >= 0 else None].splitlines() if line.startswith("|")]
    return text[start:end], rows[0], rows[2:]


def test_readme_benchmark_table_is_the_guides_run():
    """The README's compact table is the run in docs/guide/benchmark_table.txt: the same
    machine, one row per operation (N = 10⁶ float64) with every peer's ratio."""
    spec = importlib.util.spec_from_file_location("_benchtable", DOCS / "_benchtable.py")
    benchtable = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(benchtable)
    header, rows = benchtable.read(DOCS / "guide" / "benchmark_table.txt")
    section, names, table = _readme_table("Benchmarks")
    for fact in (r"NumPy SIMD (\S+)", r"\d{4}-\d\d-\d\d"):       # the SIMD level, the date
        assert re.search(fact, " ".join(header))[0].split()[-1] in section, fact
    big = {r["operation"]: r for r in rows if r["dtype"] == "float64" and r["N"] in (1_000_000, None)}
    one = {r["operation"]: r for r in rows if r["dtype"] == "float64" and r["N"] == 1}
    columns = {"÷ np.add": (big, "qa/add"), "scipy": (big, "scipy /qa"),
               "numpy-quaternion": (big, "numpy-quat /qa"), "quaternionic": (big, "quaternion /qa"),
               "N = 1: scipy": (one, "scipy /qa")}

    def shown(value):
        return "–" if value is None else f"{value:.2f}"

    readme_ops = set()
    for cells in table:
        op = cells[0].replace("10⁴", "10000")
        readme_ops.add(op)
        for name, cell in zip(names[1:], cells[1:]):
            if name in columns:
                source, key = columns[name]
                expected = shown(source[op][key]) if op in source else "–"
                assert cell == expected, f"{op}, {name}: README {cell}, guide's run {expected}"
    stems = {op.split(",")[0] for op in big}
    assert sorted(stems - {op.split(",")[0] for op in readme_ops}) == []


# ---- the browser --------------------------------------------------------------------

CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                  "--no-first-run", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync", "--window-size=1280,1000",
                  "--hide-scrollbars")

PAGES = {  # page: minimum number of plots (images of at least 300 x 150 CSS pixels)
    "index.html": 1,
    "api/generated/quatarray.Rotation.html": 0,
    "guide/interpolation.html": 3,
    "api/generated/quatarray.QuatArray.html": 0,
}


@pytest.fixture(scope="module")
def server(html):
    handler = functools.partial(_QuietHandler, directory=str(html))
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{httpd.server_address[1]}/"
    httpd.shutdown()
    httpd.server_close()


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):
        pass


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    if importlib.util.find_spec("selenium") is None:
        _unavailable('selenium is not installed: pip install -e ".[docs]"')
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    driver_path = shutil.which("chromedriver")
    if not (chromium and driver_path):
        _unavailable("Chromium is not installed: apt-get install chromium chromium-driver")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for flag in CHROMIUM_FLAGS:
        options.add_argument(flag)
    options.add_argument(f"--user-data-dir={tmp_path_factory.mktemp('chromium-profile')}")
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(driver_path), options=options)
    driver.set_page_load_timeout(60)
    yield driver
    driver.quit()


def _screenshot(driver, name):
    """A full-page PNG in docs/_build/screenshots (a build artefact)."""
    import base64
    folder = BUILD / "screenshots"
    folder.mkdir(parents=True, exist_ok=True)
    width, height = driver.execute_script(
        "return [document.documentElement.scrollWidth, document.documentElement.scrollHeight]")
    shot = driver.execute_cdp_cmd("Page.captureScreenshot", {
        "format": "png", "captureBeyondViewport": True,
        "clip": {"x": 0, "y": 0, "width": width, "height": min(height, 16000), "scale": 1}})
    path = folder / (name.replace("/", "_").replace(".html", "") + ".png")
    path.write_bytes(base64.b64decode(shot["data"]))
    return path


@pytest.mark.parametrize("page", list(PAGES))
def test_page_in_chromium(browser, server, page):
    url = urllib.parse.urljoin(server, page)
    browser.get_log("browser")                                   # drop earlier pages' entries
    browser.get(url)
    assert browser.execute_script("return document.readyState") == "complete"
    assert "quatarray" in browser.title

    # no console errors (a failed resource, a script error, ...)
    errors = [e for e in browser.get_log("browser") if e["level"] in ("SEVERE", "ERROR")]
    assert not errors, errors

    # the navigation links resolve: header, sidebars, tables of contents, previous/next
    links = browser.execute_script("""
        const sel = 'nav a[href], .bd-sidebar-primary a[href], .toctree-wrapper a[href], '
                  + '.prev-next-area a[href]';
        return Array.from(document.querySelectorAll(sel), a => a.href);""")
    internal = sorted({h for h in links if h.startswith(server)})
    assert len(internal) >= 5, links
    for href in internal:
        target, _, fragment = href.partition("#")
        with urllib.request.urlopen(target) as response:
            assert response.status == 200, href
            body = response.read().decode("utf-8")
        if fragment:
            assert f'id="{urllib.parse.unquote(fragment)}"' in body, href

    # every image loaded; the plots are there at a readable size
    images = browser.execute_script("""
        return Array.from(document.images, i => [i.currentSrc, i.complete, i.naturalWidth,
                                                  i.naturalHeight, i.width, i.height]);""")
    broken = [i for i in images if not i[1] or i[2] == 0]
    assert not broken, broken
    plots = [i for i in images if "/_images/" in i[0] and i[4] >= 300 and i[5] >= 150]
    assert len(plots) >= PAGES[page], images

    # reST markup rendered, not shown: no double backticks left in the text (numpydoc turned the
    # QuatArray docstring's "Operators: ``p * q`` ..." paragraph into Methods rows that showed them)
    text = browser.execute_script("return document.querySelector('main').innerText")
    assert "``" not in text, text[max(0, text.find("``") - 200):text.find("``") + 200]
    if page.endswith("QuatArray.html"):
        rows = browser.execute_script("""
            return Array.from(document.querySelectorAll('table tr td:first-child'), td => td.innerText);""")
        assert not [r for r in rows if r.startswith("Operators")], rows
        assert "Operators: p * q (Hamilton product)" in text

    # display formulas are whole: none starts left of its box, where no scrolling reaches it
    cut = browser.execute_script("""
        return Array.from(document.querySelectorAll('div.math'), d => {
            const box = d.getBoundingClientRect();
            return Array.from(d.querySelectorAll('math'), m => m.getBoundingClientRect().left - box.left);
        }).flat().filter(x => x < -0.5);""")
    assert not cut, cut

    path = _screenshot(browser, page)
    assert path.stat().st_size > 10_000
