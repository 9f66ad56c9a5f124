"""Settings of one service deployment (the flags of ``hrtls serve``), validated once."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

DEFAULT_DB = "hrtls-service.db"


class Settings(BaseModel):
    """Everything a running service needs to know; immutable after start.

    ``db`` is a file path (SQLite, WAL mode) or an SQLAlchemy/psycopg URL
    (``postgresql://user:pass@host/db``). ``token_cache_ttl_s`` is how long a verified token
    is trusted without reading the database (0: read it on every request); a revocation
    through this process's API takes effect at once, one made by another process after at
    most this time.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    db: str = DEFAULT_DB
    host: str = "127.0.0.1"
    port: int = Field(default=8600, ge=0, le=65535)
    max_body_kib: int = Field(default=1024, ge=1, le=65536)
    rate_per_agent_hz: float = Field(default=50.0, gt=0.0)
    rate_burst: float = Field(default=100.0, ge=1.0)
    queue_batches: int = Field(default=64, ge=1, le=100_000)
    publish_hz: float = Field(default=2.0, gt=0.0, le=50.0)
    snapshot_every_s: float = Field(default=30.0, gt=0.0)
    tracker_threads: int = Field(default=2, ge=1, le=64)
    session_hours: float = Field(default=12.0, gt=0.0)
    token_cache_ttl_s: float = Field(default=5.0, ge=0.0, le=300.0)
    token_cache_entries: int = Field(default=10_000, ge=1, le=1_000_000)
    cors_origins: tuple[str, ...] = ()
    tls: bool = False
    ws_auth_timeout_s: float = Field(default=5.0, gt=0.0)
    web_root: Path | None = None
    gc_young_objects: int = Field(default=20_000, ge=700, le=10_000_000)
    """Net allocations between young-generation collections (:mod:`hrtls.service.gcpolicy`)."""
    engine: Literal["local", "processes", "ray"] = "local"
    process_shards: int = Field(default=2, ge=1, le=64)
    ray_address: str | None = None
    ray_shards: int = Field(default=2, ge=1, le=4096)
    basemap_url: str | None = None
    """Tile URL template (``{z}``, ``{x}``, ``{y}``) of a web-mercator base map drawn under
    georeferenced missions, e.g. a tile server of the command post; None: no base map."""
    basemap_max_zoom: int = Field(default=19, ge=1, le=24)
    basemap_attribution: str = Field(default="", max_length=300)

    @field_validator("basemap_url")
    @classmethod
    def _tiles(cls, value: str | None) -> str | None:
        if value is None:
            return None
        if not value.startswith(("http://", "https://")) or not all(
                key in value for key in ("{z}", "{x}", "{y}")):
            raise ValueError(f"base map URL {value!r}: give an http(s) tile template with "
                             "{z}, {x} and {y}, e.g. http://tiles.local/{z}/{x}/{y}.png")
        return value

    @field_validator("cors_origins")
    @classmethod
    def _origins(cls, value: tuple[str, ...]) -> tuple[str, ...]:
        for origin in value:
            if origin == "*" or not origin.startswith(("http://", "https://")):
                raise ValueError(f"CORS origin {origin!r}: give a full origin like "
                                 "https://ops.example.org ('*' is not allowed)")
        return value

    @property
    def db_url(self) -> str:
        """The SQLAlchemy URL of :attr:`db` (a path becomes ``sqlite:///PATH``)."""
        if "://" in self.db:
            if self.db.startswith(("postgresql://", "postgres://")):
                return "postgresql+psycopg://" + self.db.split("://", 1)[1]
            return self.db
        return f"sqlite:///{Path(self.db).expanduser()}"

    @property
    def backend(self) -> str:
        """``sqlite`` or ``postgresql``."""
        return "sqlite" if self.db_url.startswith("sqlite") else "postgresql"

    @property
    def max_body_bytes(self) -> int:
        """Largest accepted request body, bytes."""
        return self.max_body_kib * 1024
