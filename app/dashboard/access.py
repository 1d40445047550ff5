"""Access to the dashboard off loopback: an access token, checked when a browser's websocket opens.

viser's page takes the websocket's address from its `websocket` query parameter, query string
included, so the URL printed at start-up carries the token to the server inside the websocket
request's path (`ws://HOST:PORT/?token=...`). The check runs when the websocket opens, before
viser sends anything: a client without the token is closed there and gets no data (the page
itself is viser's static client, the same for everyone). Tokens are compared with
hmac.compare_digest and never logged.
"""

from __future__ import annotations

import dataclasses
import hmac
import ipaddress
import logging
import re
import secrets
import socket
import threading
import time
from typing import TYPE_CHECKING, Literal
from urllib.parse import parse_qs, urlsplit

from hopper.config import InvalidConfig

if TYPE_CHECKING:  # config.py uses this module's checks: keep --help free of viser
    import viser
    from hopper.app.dashboard.viser_compat import Opening

log = logging.getLogger(__name__)

AUTO = "auto"  # --token auto: generate one
TOKEN_BYTES = 24  # random bytes of a generated token (32 URL-safe characters)
MIN_TOKEN_CHARS = 16
_TOKEN = re.compile(r"[A-Za-z0-9._~-]+")  # unreserved URL characters: the token goes in a URL unescaped
REFUSED_CLOSE_CODE = 1008  # websocket "policy violation"
REFUSED_LOG_S = 60.0  # s between log lines about refused connections (a refused page retries every second)

Grant = Literal["operate", "view"]


def is_loopback(host: str) -> bool:
    """Whether `host` (an IP address or 'localhost') is a loopback address."""
    if host == "localhost":
        return True
    return ipaddress.ip_address(host).is_loopback


def generate_token() -> str:
    return secrets.token_urlsafe(TOKEN_BYTES)


def check_token(token: str) -> None:
    """InvalidConfig, in one line that does not repeat the token, unless it is usable in a URL."""
    if len(token) < MIN_TOKEN_CHARS or not _TOKEN.fullmatch(token):
        raise InvalidConfig(
            f"--token must be at least {MIN_TOKEN_CHARS} characters from A-Z a-z 0-9 . _ ~ - "
            f"(or 'auto' to generate one)"
        )


def page_url(host: str, port: int, token: str | None) -> str:
    """The address to open: with a token, viser's `websocket` parameter carries it to the server.

    An unspecified bind address (0.0.0.0, ::) is shown as this machine's name.
    """
    shown = host
    if host not in ("localhost",) and ipaddress.ip_address(host).is_unspecified:
        shown = socket.gethostname()
    if ":" in shown:  # an IPv6 literal
        shown = f"[{shown}]"
    base = f"http://{shown}:{port}"
    return base if token is None else f"{base}/?websocket=ws://{shown}:{port}/?token={token}"


@dataclasses.dataclass(frozen=True)
class Access:
    """Who may connect: everyone (no token), or holders of the token (and viewers too if `public_view`)."""

    token: str | None = dataclasses.field(default=None, repr=False)
    public_view: bool = False

    def grant(self, path: str) -> Grant | None:
        """What a websocket opened on `path` (with its query string) may do; None: refuse it."""
        if self.token is None:
            return "operate"
        given = parse_qs(urlsplit(path).query).get("token", [""])[-1]
        if hmac.compare_digest(given.encode(), self.token.encode()):
            return "operate"
        return "view" if self.public_view else None


@dataclasses.dataclass(frozen=True)
class ClientInfo:
    """What the server knows of a connection when it opens."""

    address: str  # the peer's IP address
    grant: Grant


class Gatekeeper:
    """Checks every websocket of a viser server as it opens; remembers each client's address and grant.

    Installed on viser's websocket layer (viser_compat.on_connection_open), not
    `server.on_client_connect`, which viser calls only after the browser's first camera message,
    once data has already been sent.
    """

    def __init__(self, server: viser.ViserServer, access: Access) -> None:
        # Imported here, not at the top: config.py imports this module, and --help stays free of viser.
        from hopper.app.dashboard import viser_compat as compat

        self.access = access
        self.refused = 0  # connections refused, for tests and the log
        self._clients: dict[int, ClientInfo] = {}
        self._lock = threading.Lock()
        self._last_refusal_log = -REFUSED_LOG_S
        compat.on_connection_open(server, self._opened)
        compat.on_connection_close(server, self._closed)
        # The server accepted connections before this ran: close any that slipped in unchecked
        # (they reconnect at once and are checked then; nothing of the scene existed yet).
        compat.close_connections(server)

    def info(self, client_id: int) -> ClientInfo | None:
        with self._lock:
            return self._clients.get(client_id)

    async def _opened(self, opening: Opening) -> None:
        grant = self.access.grant(opening.path)
        if grant is None:
            self._log_refusal(opening.address)
            # Closed before viser's senders start: nothing of the session reaches this client.
            await opening.close(REFUSED_CLOSE_CODE, "access token required")
            return
        with self._lock:
            self._clients[opening.client_id] = ClientInfo(opening.address, grant)

    async def _closed(self, client_id: int) -> None:
        with self._lock:
            self._clients.pop(client_id, None)

    def _log_refusal(self, address: str) -> None:
        self.refused += 1
        now = time.monotonic()
        if now - self._last_refusal_log >= REFUSED_LOG_S:
            self._last_refusal_log = now
            # The address only: never the path, which may hold a wrong (or mistyped right) token.
            log.warning("refused a connection from %s without the access token (%d so far)", address, self.refused)
