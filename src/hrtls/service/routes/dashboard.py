"""Deployment settings the dashboard reads (the base map's tile source)."""

from __future__ import annotations

from fastapi import APIRouter

from hrtls.service import schemas
from hrtls.service.deps import Reader, ServicesDep

router = APIRouter(tags=["dashboard"])


@router.get("/dashboard/config", response_model=schemas.DashboardConfigOut)
def dashboard_config(who: Reader, services: ServicesDep) -> schemas.DashboardConfigOut:
    """The base map (None when the service has none: the map stays in local metres)."""
    s = services.settings
    basemap = None if s.basemap_url is None else schemas.BasemapOut(
        url=s.basemap_url, max_zoom=s.basemap_max_zoom, attribution=s.basemap_attribution)
    return schemas.DashboardConfigOut(basemap=basemap)
