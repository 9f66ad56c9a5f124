"""Verified tokens kept in memory for a short time, so most requests do not read the database.

Only secrets the database accepted are kept, keyed like the database by the SHA-256 of the
secret; an unknown secret is looked up every time. An entry lives until the earlier of
``ttl_s`` after its lookup and the token's own expiry, and the least recently used entries go
first when ``max_entries`` is reached. Revoking a token through this process's API calls
:meth:`TokenCache.forget` after the commit: the token and the sessions opened with it are
refused from the next request on. A change made by another process on the same database
(a second service on one PostgreSQL) is seen after at most ``ttl_s``.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass

from sqlalchemy.orm import Session, sessionmaker

from hrtls.service.security import Principal, digest, lookup


@dataclass(frozen=True, slots=True)
class _Entry:
    principal: Principal
    until_unix: float


class TokenCache:
    """Secret digest -> verified principal, bounded in age and count; thread-safe."""

    def __init__(self, *, ttl_s: float, max_entries: int) -> None:
        self.ttl_s = ttl_s
        self.max_entries = max_entries
        self._entries: OrderedDict[str, _Entry] = OrderedDict()
        self._lock = threading.Lock()
        self._generation = 0

    def __len__(self) -> int:
        with self._lock:
            return len(self._entries)

    def cached(self, secret: str, *, now_unix: float) -> Principal | None:
        """The principal of ``secret`` when a live entry holds it, else None (no database)."""
        return self._get(digest(secret), now_unix)

    def _get(self, key: str, now_unix: float) -> Principal | None:
        with self._lock:
            entry = self._entries.get(key)
            if entry is None:
                return None
            if entry.until_unix <= now_unix:
                del self._entries[key]
                return None
            self._entries.move_to_end(key)
            return entry.principal

    def principal(self, sessions: sessionmaker[Session], secret: str, *,
                  now_unix: float) -> Principal | None:
        """The principal of a valid secret (from the cache or the database), else None."""
        if not secret or len(secret) > 200:
            return None
        key = digest(secret)
        hit = self._get(key, now_unix)
        if hit is not None:
            return hit
        with self._lock:
            generation = self._generation
        with sessions() as db:
            found = lookup(db, secret, now_unix=now_unix)
        if found is None or self.ttl_s <= 0.0:
            return found
        until = now_unix + self.ttl_s
        if found.expires_at is not None:
            until = min(until, found.expires_at)
        with self._lock:
            if self._generation == generation:  # no revocation since the database was read
                self._entries[key] = _Entry(found, until)
                self._entries.move_to_end(key)
                while len(self._entries) > self.max_entries:
                    self._entries.popitem(last=False)
        return found

    def forget(self, token_id: int) -> None:
        """Drop token ``token_id`` and the sessions opened with it (call after the commit)."""
        with self._lock:
            self._generation += 1
            gone = [key for key, e in self._entries.items()
                    if token_id in (e.principal.token_id, e.principal.parent_id)]
            for key in gone:
                del self._entries[key]
