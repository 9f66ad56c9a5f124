"""Login against a real ``hrtls serve``: nothing is visible without an accepted token."""

from __future__ import annotations

from .conftest import login


def _status_in_page(page, path: str) -> int:
    return page.evaluate("async (p) => (await fetch(p)).status", f"/api/v1{path}")


def test_nothing_visible_without_a_token(page, page_log, service, screenshot):
    page.goto(service.url + "/")
    page.wait_for_selector("body[data-ready='1']")
    assert page.is_visible("#login-form")
    assert page.is_hidden("#app")
    assert page.text_content("#login-error") == ""
    # the page holds no session: the API refuses it too
    assert _status_in_page(page, "/auth/whoami") == 401
    assert _status_in_page(page, "/missions") == 401
    screenshot(page, "login")
    page_log.assert_clean()


def test_wrong_token_is_refused(page, page_log, service, screenshot):
    page.goto(service.url + "/")
    page.wait_for_selector("body[data-ready='1']")
    page.fill("#login-token", "not-a-token-" + "x" * 30)
    page.click("#login-submit")
    page.wait_for_selector("#login-error:not([hidden])")
    assert page.text_content("#login-error").startswith("Refused")
    assert page.is_hidden("#app")
    assert _status_in_page(page, "/missions") == 401
    screenshot(page, "login_refused")
    page_log.assert_clean()


def test_agent_token_cannot_sign_in(page, service):
    status, mission = service.api("POST", "/missions", {"name": "login test"})
    assert status == 201
    status, created = service.api("POST", f"/missions/{mission['id']}/agents",
                                  {"name": "R1", "kind": "rescuer"})
    assert status == 201
    page.goto(service.url + "/")
    page.wait_for_selector("body[data-ready='1']")
    page.fill("#login-token", created["token"])
    page.click("#login-submit")
    page.wait_for_selector("#login-error:not([hidden])")
    assert page.text_content("#login-error").startswith("Refused")
    assert page.is_hidden("#app")


def test_commander_signs_in_keeps_session_and_signs_out(page, page_log, service):
    login(page, service)
    assert "(commander)" in page.text_content("#role")
    assert page.is_visible("#orders-panel")
    assert _status_in_page(page, "/auth/whoami") == 200
    page.reload()
    page.wait_for_selector("#app:not([hidden])")
    page.click("#logout")
    page.wait_for_selector("#login-form")
    page.wait_for_function("() => !document.getElementById('login').hidden")
    assert page.is_hidden("#app")
    assert _status_in_page(page, "/auth/whoami") == 401
    page_log.assert_clean()


def test_viewer_sees_no_orders(page, service):
    status, created = service.api("POST", "/tokens", {"role": "viewer", "label": "ops desk"})
    assert status == 201
    login(page, service, created["token"])
    assert "ops desk (viewer)" in page.text_content("#role")
    assert page.is_hidden("#orders-panel")
