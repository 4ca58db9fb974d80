"""The documentation site (``docs/``, Sphinx): it builds with warnings as errors, its links and
images resolve, and its pages render in a real browser.

* Default suite (fast, nothing built): the site's own helpers in ``docs/_ext`` reach every
  argument parser the command-line reference names, and read the generated reports' anchors and
  the pages' links to repository files as the site needs them.
* ``-m slow``: the site is built as CI builds it (``python -m sphinx -W -b html docs
  docs/_build/html``; Sphinx's build is incremental, so a build from the same run is reused and
  only checked to be current), then every internal link of every page (a local file, and its
  ``#anchor`` when it has one) and every image and stylesheet is checked from the files.
* ``-m browser``: the landing page, an API page and the command-line reference, served from
  127.0.0.1, open in headless Chromium (playwright driving the system's Chromium, as in
  ``test_browser.py``): their title and heading show, every image loads (``naturalWidth > 0``), no
  request fails, and every internal link resolves to a file and to an anchor in it. Screenshots go
  to ``$NANODISORDER_BROWSER_SHOTS`` if set, else to a pytest temporary directory.
"""

from __future__ import annotations

import contextlib
import functools
import importlib.util
import os
import re
import subprocess
import sys
import threading
from html.parser import HTMLParser
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
HTML = DOCS / "_build" / "html"
#: Seconds the whole site may take to build (about 50 s from nothing on 2 cores, 10 s when current).
BUILD_TIMEOUT = 600
#: Pages opened in the browser: the landing page, one API page, the command-line reference.
BROWSER_PAGES = ["index.html", "reference/generated/qdots.simulation.html", "reference/cli.html"]


def _extension(name: str):
    """The docs-side Sphinx extension ``docs/_ext/NAME.py``, imported without touching ``sys.path``."""
    pytest.importorskip("sphinx")
    spec = importlib.util.spec_from_file_location(f"docs_ext_{name}", DOCS / "_ext" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# -- fast: the helpers ---------------------------------------------------------------------------

def test_cli_reference_reaches_every_parser():
    clihelp = _extension("clihelp")
    page = (DOCS / "reference" / "cli.md").read_text(encoding="utf-8")
    targets = re.findall(r"```\{cli-help\} (\S+)\n(:argv:\n)?", page)
    assert [target for target, _ in targets] == ["qdots.cli.main:build_parser", "planarize.cli.main:build_parser",
                                                 "reproduce.__main__:parse", "benchmarks.__main__:main"]
    helps = {}
    for target, argv in targets:
        parser = clihelp.parser_of(target, argv=bool(argv))
        helps[parser.prog] = text = clihelp.help_text(parser)
        assert text.startswith(f"usage: {parser.prog}"), text[:200]
        assert str(ROOT) not in text  # a default inside the checkout is shown relative to it
        assert max(map(len, text.splitlines())) <= clihelp.WIDTH
    assert set(helps) == {"qdots", "planarize", "python -m reproduce", "python -m benchmarks"}
    qdots = clihelp.subcommands(clihelp.parser_of("qdots.cli.main:build_parser"))
    assert {"demo", "run", "measure", "compare", "sweep"} <= set(qdots)
    planarize = clihelp.subcommands(clihelp.parser_of("planarize.cli.main:build_parser"))
    assert {"run", "scene", "import", "sweep"} <= set(planarize)
    assert "--only ITEM" in helps["python -m reproduce"]


def test_parser_capture_runs_nothing_and_restores_argparse():
    import argparse

    clihelp = _extension("clihelp")
    ran = []

    def main(argv):
        parser = argparse.ArgumentParser(prog="tool")
        parser.add_argument("--flag", action="store_true")
        parser.parse_args(argv)
        ran.append(argv)

    module = type(sys)("docs_site_probe")
    module.main = main
    sys.modules["docs_site_probe"] = module
    try:
        parser = clihelp.parser_of("docs_site_probe:main", argv=True)
    finally:
        del sys.modules["docs_site_probe"]
    assert parser.prog == "tool" and ran == []
    assert parser.parse_args(["--flag"]).flag is True  # parse_args is argparse's own again


def test_site_reads_report_anchors_and_repository_links():
    sitepages = _extension("sitepages")
    page = ("See [the README](../README.md) and [notebook 06](../notebooks/06_micrograph.ipynb).\n\n"
            "| [Fig 2-2](#fig2-2) |\n\n"
            '<a id="fig2-2"></a>\n## Fig 2-2: free dots\n\n'
            'Inline <a id="kept"></a> anchors and [outside links](https://example.org/x.md) stay.\n')
    assert sitepages.site_text(page) == (
        "See [the README](index.md) and [notebook 06](notebooks/06_micrograph.ipynb).\n\n"
        "| [Fig 2-2](#fig2-2) |\n\n"
        "{#fig2-2}\n## Fig 2-2: free dots\n\n"
        'Inline <a id="kept"></a> anchors and [outside links](https://example.org/x.md) stay.\n')


# -- the built site ------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def site() -> Path:
    """The built site's directory, built (or brought up to date) with warnings as errors."""
    for module in ("sphinx", "myst_nb", "furo"):
        pytest.importorskip(module)
    command = [sys.executable, "-m", "sphinx", "-W", "-q", "-b", "html", "docs", str(HTML.relative_to(ROOT))]
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=BUILD_TIMEOUT)
    assert done.returncode == 0, f"the docs build failed ({done.returncode}):\n{done.stderr[-4000:]}"
    assert (HTML / "index.html").is_file()
    return HTML


class _Page(HTMLParser):
    """The ids (anchors), links (``<a>``, ``<link>``) and sources (``<img>``, ``<script>``) of an HTML file."""

    def __init__(self, path: Path):
        super().__init__()
        self.ids: set[str] = set()
        self.links: list[str] = []
        self.sources: list[str] = []
        self.feed(path.read_text(encoding="utf-8"))

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if attrs.get("id"):
            self.ids.add(attrs["id"])
        if tag == "a" and attrs.get("name"):
            self.ids.add(attrs["name"])
        if tag in ("a", "link") and attrs.get("href"):
            self.links.append(attrs["href"])
        if tag in ("img", "script") and attrs.get("src"):
            self.sources.append(attrs["src"])


@functools.cache
def _parsed(path: Path) -> _Page:
    return _Page(path)


def _broken(root: Path, page: Path, href: str) -> str | None:
    """Why ``href`` on ``page`` (a file of the site at ``root``) does not resolve; None if it does or is not local."""
    parts = urlsplit(href)
    if parts.scheme or parts.netloc or href.startswith(("mailto:", "javascript:", "data:")):
        return None
    target = page if not parts.path else (page.parent / unquote(parts.path)).resolve()
    if parts.path.endswith("/"):
        target = target / "index.html"
    if root.resolve() not in target.parents and target != root.resolve():
        return f"{href}: outside the site"
    if not target.is_file():
        return f"{href}: no file {target.relative_to(root.resolve())}"
    anchor = unquote(parts.fragment)
    if anchor and target.suffix == ".html" and anchor not in _parsed(target).ids:
        return f"{href}: no id {anchor!r} in {target.relative_to(root.resolve())}"
    return None


@pytest.mark.slow
@pytest.mark.timeout(BUILD_TIMEOUT + 120)
def test_every_internal_link_and_image_of_the_site_resolves(site):
    pages = sorted(site.rglob("*.html"))
    assert len(pages) > 100  # the guide, how-tos, reports, notebooks and one page per module
    for required in ["index.html", "guide.html", "reference/api.html", "reference/cli.html", "reproduction.html",
                     "performance.html", "howto/import-afm.html", "notebooks/06_micrograph.html",
                     "reference/generated/qdots.html", "reference/generated/planarize.html",
                     "reference/generated/labrig.sweeps.html"]:
        assert (site / required).is_file(), required
    broken = []
    for page in pages:
        parsed = _parsed(page.resolve())
        for href in parsed.links + parsed.sources:
            why = _broken(site, page.resolve(), href)
            if why:
                broken.append(f"{page.relative_to(site)}: {why}")
    assert not broken, f"{len(broken)} broken links:\n" + "\n".join(broken[:40])


# -- in the browser ------------------------------------------------------------------------------

@contextlib.contextmanager
def _served(directory: Path):
    """An HTTP server of ``directory`` on 127.0.0.1 (a free port), in a thread; yields its base URL."""
    class Quiet(SimpleHTTPRequestHandler):
        def log_message(self, *args):
            pass

    server = ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Quiet, directory=str(directory)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()
        thread.join(timeout=10)


@pytest.fixture(scope="module")
def shots(tmp_path_factory) -> Path:
    named = os.environ.get("NANODISORDER_BROWSER_SHOTS")
    directory = Path(named) if named else tmp_path_factory.mktemp("docs-shots")
    directory.mkdir(parents=True, exist_ok=True)
    return directory


#: In the page: eager images, then each image's state, the title, the first heading and every link.
_SHOW = """async () => {
    const images = [...document.images];
    images.forEach(image => { image.loading = "eager"; });
    await Promise.all(images.map(image => image.complete ? null
        : new Promise(done => { image.onload = image.onerror = done; })));
    return {
        title: document.title,
        heading: (document.querySelector("article h1, main h1, h1") || {}).textContent || "",
        images: images.map(image => [image.currentSrc || image.src, image.complete, image.naturalWidth]),
        links: [...document.querySelectorAll("a[href]")].map(a => a.href),
    };
}"""


@pytest.mark.browser
@pytest.mark.timeout(BUILD_TIMEOUT + 180)
@pytest.mark.parametrize("name", BROWSER_PAGES)
def test_page_renders_in_chromium(site, shots, tmp_path, name):
    pytest.importorskip("playwright.sync_api")
    from browser_lab import browser_context, chromium

    executable = chromium()
    if executable is None:
        pytest.skip("no Chromium: install it (Debian: apt-get install chromium) or set $CHROMIUM")
    with _served(site) as base, browser_context(executable, tmp_path / "profile") as browser:
        page = browser.new_page()
        failed, errors = [], []
        page.on("requestfailed", lambda request: failed.append(f"{request.url}: {request.failure}"))
        page.on("response", lambda response: response.status >= 400 and failed.append(
            f"{response.url}: HTTP {response.status}"))
        page.on("pageerror", lambda error: errors.append(str(error)))
        page.goto(f"{base}/{name}", wait_until="load", timeout=60_000)
        shown = page.evaluate(_SHOW)
        page.screenshot(path=str(shots / f"docs-{name.replace('/', '_').removesuffix('.html')}.png"), full_page=False)
    assert shown["title"].strip() and "nanodisorder" in shown["title"], shown["title"]
    assert shown["heading"].strip(), f"{name}: no heading"
    assert not failed and not errors, f"{name}: failed requests {failed}, page errors {errors}"
    unloaded = [src for src, complete, width in shown["images"] if not complete or width == 0]
    assert not unloaded, f"{name}: images that did not load: {unloaded}"
    if name == "index.html":
        assert shown["images"], "the landing page shows a figure"
    broken = []
    for url in shown["links"]:
        if url.startswith(base + "/"):  # this site's: resolve its path from the site's root
            why = _broken(site, (site / "index.html").resolve(), "." + url[len(base):])
            if why:
                broken.append(why)
    assert not broken, f"{name}: broken links:\n" + "\n".join(broken)
