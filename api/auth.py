"""API keys and who owns a job (docs/guides/service-operations.md "API keys").

* ``RIS_PLANNER_API_KEY`` – the admin key (plain text, as before): sees, streams, cancels and
  removes every job;
* ``RIS_PLANNER_API_KEYS`` (``name:sha256hex,...``) and ``RIS_PLANNER_API_KEYS_FILE`` (one
  ``name:sha256hex`` a line, ``#`` comments) – further keys, stored only as the SHA-256 of the
  key (hex); a job belongs to the key that created it, and another key's job answers 404.

Without any key, the service is open and every job is visible to every client.
"""

from __future__ import annotations

import hashlib
import hmac
import re
from dataclasses import dataclass

from api.settings import Settings

ADMIN = "admin"
"""The owner name of the admin key (``RIS_PLANNER_API_KEY``)."""

_ENTRY = re.compile(r"^([A-Za-z0-9_.@-]{1,64}):([0-9a-fA-F]{64})$")


@dataclass(frozen=True)
class Principal:
    """Who sent a request: the key's name and whether it is the admin key."""

    name: str
    admin: bool

    @property
    def owner_filter(self) -> str | None:
        """The owner whose jobs this key sees (None: all)."""
        return None if self.admin else self.name

    def may_see(self, owner: str | None) -> bool:
        return self.admin or owner == self.name


ANONYMOUS = Principal(name="", admin=True)
"""The principal of every request on a server without keys (sees all jobs; owner None)."""


def key_digest(key: str | bytes) -> str:
    """The stored form of a key: SHA-256, hex (``ris-planner`` docs show how to make one)."""
    data = key.encode("utf-8") if isinstance(key, str) else key
    return hashlib.sha256(data).hexdigest()


def _parse_entries(text: str, what: str) -> dict[str, str]:
    out: dict[str, str] = {}
    for number, raw in enumerate(text.replace(",", "\n").splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        match = _ENTRY.match(line)
        if match is None:
            raise ValueError(
                f"{what}: entry {number} is not 'name:sha256hex' (a name of letters, digits,"
                " '_.@-' and the 64 hex digits of the key's SHA-256)"
            )
        name, digest = match.groups()
        if name == ADMIN:
            raise ValueError(f"{what}: the name {ADMIN!r} is the admin key's (RIS_PLANNER_API_KEY)")
        out[digest.lower()] = name
    return out


class KeyRing:
    """The configured keys: SHA-256 digest → principal."""

    def __init__(self, settings: Settings) -> None:
        self._keys: dict[bytes, Principal] = {}
        if settings.api_key is not None:
            admin = key_digest(settings.api_key.get_secret_value())
            self._keys[admin.encode()] = Principal(ADMIN, admin=True)
        entries: dict[str, str] = {}
        if settings.api_keys:
            entries |= _parse_entries(settings.api_keys, "RIS_PLANNER_API_KEYS")
        if settings.api_keys_file is not None:
            try:
                text = settings.api_keys_file.read_text(encoding="utf-8")
            except OSError as exc:
                raise ValueError(
                    f"RIS_PLANNER_API_KEYS_FILE: cannot read ({exc.strerror or exc})"
                ) from None
            entries |= _parse_entries(text, "RIS_PLANNER_API_KEYS_FILE")
        for digest, name in entries.items():
            self._keys.setdefault(digest.encode(), Principal(name, admin=False))

    @property
    def enabled(self) -> bool:
        """Whether /v1 needs a key."""
        return bool(self._keys)

    def lookup(self, key: bytes | None) -> Principal | None:
        """The principal of a key as sent (None: unknown); every stored digest is compared in
        constant time, so the answer's timing does not tell which digest came close."""
        if key is None:
            return None
        digest = key_digest(key).encode()
        found = None
        for stored, principal in self._keys.items():
            if hmac.compare_digest(stored, digest):
                found = principal
        return found
