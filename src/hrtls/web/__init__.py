"""The incident commander's dashboard: static assets served by ``hrtls serve`` at ``/``.

Plain ES modules and CSS, with Leaflet vendored under ``vendor/leaflet`` (docs/dashboard.md says
how to rebuild it); nothing is fetched from the internet.
"""

from __future__ import annotations

from pathlib import Path

LEAFLET_VERSION = "1.9.4"


def asset_root() -> Path:
    """Folder of the dashboard's static files (``index.html`` at its top)."""
    return Path(__file__).resolve().parent
