"""``hrtls demo``, the live job: a new user opens the printed URL with the printed token."""

from __future__ import annotations

import re
import subprocess
import time

import pytest

from .conftest import _free_port, hrtls_command

pytestmark = pytest.mark.slow


def test_demo_serves_the_dashboard_with_a_live_team(page, page_log, tmp_path, screenshot):
    port = _free_port()
    proc = subprocess.Popen([*hrtls_command(), "demo", "--speed", "16", "--port", str(port),
                             "--duration-s", "40", "-o", str(tmp_path / "demo")],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert proc.stdout is not None
    url = token = None
    lines = []
    deadline = time.monotonic() + 240
    while token is None and time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        lines.append(line)
        if m := re.search(r"dashboard\s+(http://\S+)", line):
            url = m.group(1)
        if m := re.search(r"commander token \(sign in with it\)\s+(\S+)", line):
            token = m.group(1)
    try:
        assert url and token, "".join(lines)
        assert url.startswith(f"http://127.0.0.1:{port}/")
        page.goto(url)
        page.wait_for_selector("body[data-ready='1']")
        assert page.is_hidden("#app")
        page.fill("#login-token", token)
        page.click("#login-submit")
        page.wait_for_selector("#app:not([hidden])")
        page.wait_for_function("() => document.querySelectorAll('path.agent-dot').length >= 2",
                               timeout=60_000)
        page.wait_for_timeout(3000)
        screenshot(page, "demo")
        page_log.assert_clean()
    finally:
        rest, _ = proc.communicate(timeout=120)
    assert proc.returncode == 0, "".join(lines) + rest
