"""Floor plan images: upload, placement, download by readers, and every refusal."""

from __future__ import annotations

import io

import httpx
from PIL import Image

from hrtls.service.floor_image import MAX_SIDE_PX

from .conftest import Live, new_mission

API = "/api/v1"


def _image(fmt: str, size: tuple[int, int] = (40, 20)) -> bytes:
    buf = io.BytesIO()
    Image.new("RGB", size, (200, 30, 30)).save(buf, format=fmt)
    return buf.getvalue()


def test_floor_image_round_trip(live: Live, commander: httpx.Client) -> None:
    m = new_mission(commander, floors=[{"index": 0, "name": "Ground", "height_m": 0.0}])
    mid = m["id"]
    assert m["floors"][0]["image"] is None
    png = _image("PNG")
    r = commander.put(f"{API}/missions/{mid}/floors/0/image",
                      params={"origin_x_m": -5.0, "origin_y_m": 2.5, "m_per_px": 0.25},
                      content=png, headers={"Content-Type": "image/png"})
    assert r.status_code == 200, r.text
    image = r.json()["image"]
    assert image == {"media_type": "image/png", "width_px": 40, "height_px": 20,
                     "origin_x_m": -5.0, "origin_y_m": 2.5, "m_per_px": 0.25,
                     "url": f"{API}/missions/{mid}/floors/0/image"}
    assert commander.get(f"{API}/missions/{mid}").json()["floors"][0]["image"] == image
    viewer_secret = commander.post(f"{API}/tokens",
                                   json={"role": "viewer", "label": "v"}).json()["token"]
    with live.client(viewer_secret) as viewer:
        got = viewer.get(image["url"])
        assert got.status_code == 200 and got.content == png
        assert got.headers["content-type"] == "image/png"
        r = viewer.put(image["url"], params={"origin_x_m": 0, "origin_y_m": 0, "m_per_px": 1},
                       content=png, headers={"Content-Type": "image/png"})
        assert r.status_code == 403
        assert viewer.delete(image["url"]).status_code == 403
    with live.client() as anonymous:
        assert anonymous.get(image["url"]).status_code == 401
    jpeg = _image("JPEG", (16, 16))
    r = commander.put(image["url"], params={"origin_x_m": 0, "origin_y_m": 0, "m_per_px": 1},
                      content=jpeg, headers={"Content-Type": "image/jpeg"})
    assert r.status_code == 200 and r.json()["image"]["width_px"] == 16
    assert commander.get(image["url"]).content == jpeg
    assert commander.delete(image["url"]).status_code == 204
    assert commander.get(image["url"]).status_code == 404
    assert commander.get(f"{API}/missions/{mid}").json()["floors"][0]["image"] is None


def test_floor_image_refusals(commander: httpx.Client) -> None:
    mid = new_mission(commander, floors=[{"index": 0, "name": "Ground", "height_m": 0.0}])["id"]
    url = f"{API}/missions/{mid}/floors/0/image"
    place = {"origin_x_m": 0.0, "origin_y_m": 0.0, "m_per_px": 0.1}
    png = _image("PNG")

    def put(content: bytes, media_type: str | None, params: dict | None = None,
            path: str = url) -> httpx.Response:
        headers = {} if media_type is None else {"Content-Type": media_type}
        return commander.put(path, params=place if params is None else params,
                             content=content, headers=headers)

    r = put(png, "image/gif")
    assert r.status_code == 415 and "image/png" in r.json()["detail"]
    assert put(png, None).status_code == 415
    r = put(png, "image/jpeg")
    assert r.status_code == 422 and "PNG" in r.json()["detail"]
    assert put(b"", "image/png").status_code == 422
    r = put(png[: len(png) // 2], "image/png")
    assert r.status_code == 422 and "not a readable" in r.json()["detail"]
    r = put(b"<svg xmlns='http://www.w3.org/2000/svg'/>", "image/png")
    assert r.status_code == 422
    r = put(_image("PNG", (MAX_SIDE_PX + 1, 1)), "image/png")
    assert r.status_code == 422 and str(MAX_SIDE_PX) in r.json()["detail"]
    for bad in ({"origin_x_m": 0, "origin_y_m": 0, "m_per_px": 0},
                {"origin_x_m": 0, "origin_y_m": 0, "m_per_px": "nan"},
                {"origin_x_m": 0, "origin_y_m": 0},
                {"origin_x_m": "inf", "origin_y_m": 0, "m_per_px": 1}):
        assert put(png, "image/png", bad).status_code == 422, bad
    assert put(png, "image/png", path=f"{API}/missions/{mid}/floors/3/image").status_code == 404
    assert put(png, "image/png", path=f"{API}/missions/999/floors/0/image").status_code == 404
    assert commander.get(url).status_code == 404


def test_cli_uploads_a_floor_image(live: Live, commander: httpx.Client, tmp_path) -> None:
    from typer.testing import CliRunner

    from hrtls.cli.app import app

    mid = new_mission(commander, floors=[{"index": 2, "name": "Second", "height_m": 6.0}])["id"]
    path = tmp_path / "plan.png"
    path.write_bytes(_image("PNG", (30, 10)))
    args = ["mission", "floor-image", str(mid), "2", str(path), "--server", live.url,
            "--token", live.commander, "--origin-m", "1", "-2", "--m-per-px", "0.5"]
    r = CliRunner().invoke(app, args)
    assert r.exit_code == 0, r.output
    assert "30 x 10 px, 15.0 x 5.0 m from (1, -2) m" in r.output
    image = commander.get(f"{API}/missions/{mid}").json()["floors"][0]["image"]
    assert (image["origin_x_m"], image["origin_y_m"], image["m_per_px"]) == (1.0, -2.0, 0.5)
    r = CliRunner().invoke(app, [*args[:3], "7", *args[4:]])
    assert r.exit_code == 2 and "HTTP 404" in r.output and "floor 7 not found" in r.output
    (tmp_path / "plan.gif").write_bytes(b"GIF89a")
    r = CliRunner().invoke(app, [*args[:4], str(tmp_path / "plan.gif"), *args[5:]])
    assert r.exit_code == 2 and "a .png, .jpg or .jpeg file" in r.output
