"""The dashboard's files: vendored Leaflet unmodified, every asset shipped as package data."""

from __future__ import annotations

import hashlib
import re
import tomllib
from fnmatch import fnmatch
from pathlib import Path

from hrtls.web import LEAFLET_VERSION, asset_root

REPO_ROOT = Path(__file__).resolve().parents[2]


def test_vendored_leaflet_matches_its_checksums():
    folder = asset_root() / "vendor" / "leaflet"
    lines = (folder / "SHA256SUMS").read_text().splitlines()
    assert len(lines) >= 8
    for line in lines:
        digest, name = line.split(maxsplit=1)
        assert hashlib.sha256((folder / name).read_bytes()).hexdigest() == digest, name
    assert "BSD 2-Clause" in (folder / "LICENSE").read_text()
    head = (folder / "leaflet-src.esm.js").read_text()[:400]
    assert f"Leaflet {LEAFLET_VERSION}" in head


def test_every_asset_is_package_data():
    config = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())
    patterns = config["tool"]["setuptools"]["package-data"]["hrtls"]
    package = asset_root().parent
    missing = []
    for path in asset_root().rglob("*"):
        if path.is_dir() or path.suffix == ".py" or "__pycache__" in path.parts:
            continue
        rel = path.relative_to(package).as_posix()
        if not any(fnmatch(rel, p) and rel.count("/") == p.count("/") for p in patterns):
            missing.append(rel)
    assert not missing, f"not shipped in the wheel: {missing}"


def test_no_asset_loads_from_the_internet():
    pattern = re.compile(r"""(?:src|href)\s*=\s*["']\s*(?:https?:)?//""", re.I)
    imports = re.compile(r"""(?:import|from)\s*\(?\s*["'](?:https?:)?//""")
    for path in asset_root().rglob("*"):
        if path.suffix in {".html", ".css", ".js"} and "vendor" not in path.parts:
            text = path.read_text()
            assert not pattern.search(text), path
            assert not imports.search(text), path
            assert "url(http" not in text, path
