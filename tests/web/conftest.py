"""Browser fixtures: Playwright driving Debian's chromium, with the internet blocked.

Every page runs with requests to anything but loopback aborted and recorded, so each test also
checks that the dashboard works offline. Screenshots go to ``build/web-artifacts`` (or
``$HRTLS_ARTIFACTS``).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import socket
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import urlsplit

import pytest

REPO_ROOT = Path(__file__).resolve().parents[2]
LOOPBACK = {"127.0.0.1", "localhost", "[::1]", "::1"}


def chromium_executable() -> str | None:
    """Path of the system chromium ($HRTLS_CHROMIUM overrides), or None."""
    env = os.environ.get("HRTLS_CHROMIUM")
    if env:
        return env
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    return None


def artifacts_dir() -> Path:
    path = Path(os.environ.get("HRTLS_ARTIFACTS", REPO_ROOT / "build" / "web-artifacts"))
    path.mkdir(parents=True, exist_ok=True)
    return path


@pytest.fixture(scope="session")
def browser():
    executable = chromium_executable()
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        if os.environ.get("CI"):
            raise
        pytest.skip("playwright is not installed (pip install -e '.[test]')")
    if executable is None:
        if os.environ.get("CI"):
            pytest.fail("chromium is missing: .ci/run installs it with apt-get")
        pytest.skip("chromium is not installed (apt-get install chromium)")
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=executable,
                              args=["--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"])
        yield b
        b.close()


@dataclass
class PageLog:
    """What a page did besides rendering: blocked external requests, errors, failed loads."""

    external: list[str] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)

    def assert_clean(self) -> None:
        assert not self.external, f"the page tried to reach the internet: {self.external}"
        assert not self.errors, f"JavaScript errors: {self.errors}"
        assert not self.failed, f"failed loads: {self.failed}"


@pytest.fixture
def page_log() -> PageLog:
    return PageLog()


@pytest.fixture
def page(browser, page_log: PageLog):
    context = browser.new_context(viewport={"width": 1400, "height": 900})

    def route(r):
        host = urlsplit(r.request.url).hostname or ""
        if r.request.url.startswith(("http://", "https://", "ws://", "wss://")) and \
                host not in LOOPBACK:
            page_log.external.append(r.request.url)
            r.abort()
        else:
            r.continue_()

    context.route("**/*", route)
    pg = context.new_page()
    pg.on("pageerror", lambda exc: page_log.errors.append(str(exc)))
    # HTTP refusals show as console errors too; the tests check statuses themselves
    pg.on("console", lambda m: page_log.errors.append(m.text) if m.type == "error"
          and not m.text.startswith("Failed to load resource: the server responded") else None)
    # ERR_ABORTED: a request cut short by a navigation (reload, sign-out), not a failed load
    pg.on("requestfailed", lambda r: page_log.failed.append(f"{r.url} {r.failure}")
          if urlsplit(r.url).hostname in LOOPBACK and "ERR_ABORTED" not in (r.failure or "")
          else None)
    yield pg
    context.close()


@pytest.fixture
def screenshot():
    """Save a screenshot of a page as a test artifact: ``screenshot(page, name)`` -> path."""

    def save(pg, name: str) -> Path:
        path = artifacts_dir() / f"{name}.png"
        pg.screenshot(path=str(path))
        return path

    return save


@dataclass
class Service:
    """A real ``hrtls serve`` on loopback with its own SQLite database."""

    url: str
    token: str
    db: Path
    process: subprocess.Popen[str]
    log: Path

    def api(self, method: str, path: str, body: object | None = None,
            token: str | None = None) -> tuple[int, object]:
        """Call the API as a plain HTTP client; returns (status, parsed JSON or None)."""
        data = None if body is None else json.dumps(body).encode()
        req = urllib.request.Request(f"{self.url}/api/v1{path}", data=data, method=method)
        req.add_header("Authorization", f"Bearer {token or self.token}")
        if data is not None:
            req.add_header("Content-Type", "application/json")
        try:
            with urllib.request.urlopen(req, timeout=30) as resp:
                raw = resp.read()
                return resp.status, (json.loads(raw) if raw else None)
        except urllib.error.HTTPError as err:
            raw = err.read()
            return err.code, (json.loads(raw) if raw else None)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def hrtls_command() -> list[str]:
    """The ``hrtls`` console script of this interpreter's environment."""
    script = Path(sys.executable).with_name("hrtls")
    return [str(script)] if script.exists() else [sys.executable, "-m", "hrtls.cli.app"]


TOKEN_LINE = re.compile(r"commander token[^:]*:\s*(\S+)")


def start_service(folder: Path, *extra: str) -> Service:
    """Start ``hrtls serve`` on a free loopback port; wait until it answers."""
    port = _free_port()
    db = folder / "hrtls.db"
    log = folder / "serve.log"
    out = log.open("w")
    proc = subprocess.Popen([*hrtls_command(), "serve", "--db", str(db), "--host", "127.0.0.1",
                             "--port", str(port), *extra],
                            stdout=subprocess.PIPE, stderr=out, text=True)
    assert proc.stdout is not None
    token = None
    deadline = time.monotonic() + 60
    while token is None and time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        out.write(line)
        out.flush()
        match = TOKEN_LINE.search(line)
        if match:
            token = match.group(1)
    if token is None:
        proc.kill()
        raise RuntimeError(f"hrtls serve printed no commander token: {log.read_text()}")
    url = f"http://127.0.0.1:{port}"
    while time.monotonic() < deadline:
        try:
            with urllib.request.urlopen(f"{url}/api/v1/health", timeout=2):
                break
        except OSError:
            time.sleep(0.2)
    threading.Thread(target=lambda: [out.write(x) for x in proc.stdout or []],
                     daemon=True).start()
    return Service(url=url, token=token, db=db, process=proc, log=log)


def stop_service(service: Service) -> None:
    service.process.terminate()
    try:
        service.process.wait(timeout=15)
    except subprocess.TimeoutExpired:
        service.process.kill()
        service.process.wait()


@pytest.fixture(scope="module")
def service(tmp_path_factory) -> Iterator[Service]:
    svc = start_service(tmp_path_factory.mktemp("serve"))
    yield svc
    stop_service(svc)


def login(page, service: Service, token: str | None = None) -> None:
    """Open the dashboard and sign in with a token (the commander's by default)."""
    page.goto(service.url + "/")
    page.wait_for_selector("body[data-ready='1']")
    page.fill("#login-token", token or service.token)
    page.click("#login-submit")
    page.wait_for_selector("#app:not([hidden])")


@pytest.fixture
def geometry(page, service):
    """The dashboard page loaded (not logged in), to call its ES modules (js/geometry.js)."""
    page.goto(service.url + "/")
    page.wait_for_selector("body[data-ready='1']")
    return page
