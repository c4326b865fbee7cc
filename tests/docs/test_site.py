"""The documentation site in a real headless browser: every page loads, every image loads, no link is broken.

The site is the one ``scripts/test.sh`` built (``BLUESKY_GYM_SITE_DIR``) or, without it, built
here with ``mkdocs build --strict``. It is served on localhost and every page is opened in
Chromium (Debian's ``chromium``, driven by Playwright; ``BLUESKY_GYM_CHROMIUM`` names another
binary).
"""

from __future__ import annotations

import functools
import http.server
import os
import subprocess
import sys
import threading
import types
import urllib.error
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import urldefrag, urlsplit

import pytest

ROOT = Path(__file__).resolve().parents[2]
CHROMIUM = Path(os.environ.get("BLUESKY_GYM_CHROMIUM", "/usr/bin/chromium"))


@pytest.fixture(scope="module")
def sync_api() -> types.ModuleType:
    """Playwright's synchronous API, once the site can be built and opened (skips with the reason otherwise)."""
    pytest.importorskip("mkdocs", reason="the documentation site needs the 'docs' extra")
    api = pytest.importorskip("playwright.sync_api", reason="the browser check needs Playwright (the 'docs' extra)")
    if not CHROMIUM.is_file():
        pytest.skip(f"no Chromium at {CHROMIUM} (apt-get install chromium); the site is not opened in a browser")
    return api


@pytest.fixture(scope="module")
def site_dir(sync_api: types.ModuleType, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The built site: the build of scripts/test.sh, or a fresh strict build."""
    given = os.environ.get("BLUESKY_GYM_SITE_DIR")
    if given:
        site = Path(given)
        assert (site / "index.html").is_file(), f"BLUESKY_GYM_SITE_DIR={given} holds no built site"
        return site
    site = tmp_path_factory.mktemp("site")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "NO_MKDOCS_2_WARNING": "1"}
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site)], cwd=ROOT, env=env, capture_output=True, text=True
    )
    assert proc.returncode == 0, f"mkdocs build --strict failed:\n{proc.stderr[-4000:]}"
    return site


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, format: str, *args: object) -> None:  # noqa: A002 - the base class's name
        pass


@pytest.fixture(scope="module")
def base_url(site_dir: Path) -> Iterator[str]:
    """The site served on a free localhost port."""
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(_QuietHandler, directory=str(site_dir)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()


def page_urls(site: Path, base: str) -> list[str]:
    """The URL of every HTML page of the site (directory URLs for index pages)."""
    urls = []
    for path in sorted(site.rglob("*.html")):
        rel = path.relative_to(site).as_posix()
        if rel == "404.html":
            continue
        urls.append(base + (rel[: -len("index.html")] if rel.endswith("index.html") else rel))
    return urls


def http_status(url: str) -> int:
    try:
        with urllib.request.urlopen(url, timeout=10) as response:
            return int(response.status)
    except urllib.error.HTTPError as exc:
        return int(exc.code)


@pytest.mark.slow
def test_every_page_loads_with_its_images_and_links(sync_api: types.ModuleType, site_dir: Path, base_url: str) -> None:
    urls = page_urls(site_dir, base_url)
    expected = {"", "installation/", "environments/", "environments/DescentEnv-v0/", "cli/", "tutorials/train-ppo/", "api/envs/"}
    assert expected <= {u[len(base_url) :] for u in urls}, "pages missing from the site"
    problems: list[str] = []
    ids: dict[str, set[str]] = {}
    links: set[tuple[str, str]] = set()
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), headless=True)
        try:
            page = browser.new_page()
            errors: list[str] = []
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))

            def visit(url: str, via: str = "") -> set[str]:
                """Open a page; record its problems; return its element ids (the anchors it has)."""
                errors.clear()
                response = page.goto(url, wait_until="load")
                if response is None or response.status != 200:
                    problems.append(f"{via}{url}: HTTP {None if response is None else response.status}")
                    return set()
                broken = page.evaluate("Array.from(document.images).filter(i => !(i.complete && i.naturalWidth > 0)).map(i => i.src)")
                problems.extend(f"{url}: image does not load: {src}" for src in broken)
                problems.extend(f"{url}: console error: {e}" for e in errors)
                for href in page.evaluate("Array.from(document.querySelectorAll('a[href]')).map(a => a.href)"):
                    if href.startswith(base_url):
                        links.add((url, href))
                found: set[str] = set(page.evaluate("Array.from(document.querySelectorAll('[id], a[name]')).map(e => e.id || e.name)"))
                return found

            for url in urls:
                ids[url] = visit(url)
            for source, href in sorted(links):
                target, fragment = urldefrag(href)
                if target not in ids:
                    path = urlsplit(target).path
                    if path.endswith("/") or path.endswith(".html"):
                        ids[target] = visit(target, via=f"{source}: link to ")
                    else:
                        status = http_status(target)
                        if status != 200:
                            problems.append(f"{source}: link to {href}: HTTP {status}")
                        continue
                if fragment and fragment not in ids[target]:
                    problems.append(f"{source}: link to {href}: no anchor #{fragment}")
        finally:
            browser.close()
    assert len(links) > 50
    assert not problems, "\n".join(problems)
