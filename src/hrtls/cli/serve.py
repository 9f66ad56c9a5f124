"""``hrtls serve``: the supervisor service (FastAPI and uvicorn are imported only here)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal, cast

import typer

from hrtls.cli.errors import reports_errors
from hrtls.service.settings import Settings

_FLAGS = {"cors_origins": "--cors-origin", "rate_per_agent_hz": "--rate-per-agent",
          "rate_burst": "--rate-per-agent", "token_cache_ttl_s": "--token-cache-ttl"}
_D = {name: f.default for name, f in Settings.model_fields.items()}


@reports_errors
def serve(
    db: Annotated[str, typer.Option(
        "--db", help="SQLite file (WAL mode) or postgresql://user:pass@host/dbname.")
    ] = _D["db"],
    host: Annotated[str, typer.Option("--host", help="Interface to listen on.")] = _D["host"],
    port: Annotated[int, typer.Option("--port", help="TCP port.")] = _D["port"],
    publish_hz: Annotated[float, typer.Option(
        "--publish-hz", help="Estimates published per agent and second.")] = _D["publish_hz"],
    max_body_kib: Annotated[int, typer.Option(
        "--max-body-kib", help="Largest request body, KiB.")] = _D["max_body_kib"],
    rate_per_agent: Annotated[float, typer.Option(
        "--rate-per-agent", help="Ingest requests per second and agent (burst 2x).")
    ] = _D["rate_per_agent_hz"],
    queue_batches: Annotated[int, typer.Option(
        "--queue-batches", help="Batches queued per agent before 429.")] = _D["queue_batches"],
    session_hours: Annotated[float, typer.Option(
        "--session-hours", help="Lifetime of a browser session.")] = _D["session_hours"],
    token_cache_ttl: Annotated[float, typer.Option(
        "--token-cache-ttl", help="Seconds a verified token is trusted without reading the "
        "database (0: every request reads it); revocations through this service act at once.")
    ] = _D["token_cache_ttl_s"],
    cors_origin: Annotated[list[str] | None, typer.Option(
        "--cors-origin", help="Allow this origin cross-site (repeatable; closed by default).")
    ] = None,
    ssl_certfile: Annotated[Path | None, typer.Option(
        "--ssl-certfile", help="TLS certificate (PEM) for https/wss.")] = None,
    ssl_keyfile: Annotated[Path | None, typer.Option(
        "--ssl-keyfile", help="TLS private key (PEM).")] = None,
    engine: Annotated[str, typer.Option(
        "--engine", help="Where the agents' trackers run: local (this process), processes "
        "(local worker processes) or ray (shard actors; pip install 'hrtls[ray]').")
    ] = _D["engine"],
    process_shards: Annotated[int, typer.Option(
        "--process-shards", help="Worker processes the agents are hashed onto "
        "(--engine processes).")] = _D["process_shards"],
    ray_address: Annotated[str | None, typer.Option(
        "--ray-address", help="Join this Ray cluster (auto, ray://head:10001); "
        "default: start a local Ray.")] = None,
    ray_shards: Annotated[int, typer.Option(
        "--ray-shards", help="Shard actors the agents are hashed onto (--engine ray).")
    ] = _D["ray_shards"],
    basemap_url: Annotated[str | None, typer.Option(
        "--basemap-url", help="Tile URL template ({z}/{x}/{y}) of a web-mercator base map "
        "under georeferenced missions, e.g. the command post's tile server.")] = None,
    new_commander_token: Annotated[bool, typer.Option(
        "--new-commander-token", help="Create and print another commander token.")] = False,
) -> None:
    """Run the supervisor: live tracking of the team, REST + WebSocket API and dashboard."""
    from hrtls.errors import InputError

    if (ssl_certfile is None) != (ssl_keyfile is None):
        raise InputError("only one of --ssl-certfile / --ssl-keyfile", where="hrtls serve",
                         expected="both (TLS) or neither (plain HTTP on loopback)")
    settings = _settings(db=db, host=host, port=port, publish_hz=publish_hz,
                         max_body_kib=max_body_kib, rate_per_agent_hz=rate_per_agent,
                         rate_burst=2.0 * rate_per_agent, queue_batches=queue_batches,
                         session_hours=session_hours, token_cache_ttl_s=token_cache_ttl,
                         cors_origins=tuple(cors_origin or ()), tls=ssl_certfile is not None,
                         engine=cast("Literal['local', 'processes', 'ray']", engine),
                         process_shards=process_shards, ray_address=ray_address,
                         ray_shards=ray_shards,
                         basemap_url=basemap_url)
    _run(settings, ssl_certfile=ssl_certfile, ssl_keyfile=ssl_keyfile,
         new_commander_token=new_commander_token)


def _settings(**fields: Any) -> Settings:
    """The service settings; an invalid value raises an error naming its command-line flag."""
    from pydantic import ValidationError

    from hrtls.errors import InputError

    try:
        return Settings(**fields)
    except ValidationError as exc:
        first = exc.errors()[0]
        name = str(first["loc"][0]) if first["loc"] else "option"
        flag = _FLAGS.get(name, "--" + name.replace("_", "-"))
        raise InputError(str(first["msg"]), where=flag, expected="see hrtls serve --help"
                         ) from None


def _run(settings: Settings, *, ssl_certfile: Path | None, ssl_keyfile: Path | None,
         new_commander_token: bool) -> None:
    """Prepare the database, print the addresses (and a new token), then serve until stopped."""
    import uvicorn

    from hrtls.service.app import bootstrap, create_app
    from hrtls.service.gcpolicy import collect_for_service

    host, port = settings.host, settings.port
    secret = bootstrap(settings, new_commander=new_commander_token)
    scheme = "https" if settings.tls else "http"
    typer.echo(f"hrtls supervisor: dashboard {scheme}://{host}:{port}/  "
               f"(API {scheme}://{host}:{port}/api/v1, database {settings.backend})")
    if secret is not None:
        typer.echo(f"commander token (shown once, keep it): {secret}")
    app = create_app(settings)
    collect_for_service(settings.gc_young_objects)
    uvicorn.run(app, host=host, port=port, log_level="warning",
                ssl_certfile=None if ssl_certfile is None else str(ssl_certfile),
                ssl_keyfile=None if ssl_keyfile is None else str(ssl_keyfile),
                ws_max_size=settings.max_body_bytes)
