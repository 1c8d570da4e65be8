"""Did a request come from this host?  Loopback interfaces and trusted reverse proxies.

In ``RSF_AUTH=auto`` without any key, the API serves requests without a key only when
they come from this host (:func:`service.auth.guard`).  A request that reached a
loopback interface came from this host, unless a reverse proxy on this host (nginx
adding TLS, say) forwarded it for someone else: then it carries forwarding headers
(``Forwarded`` RFC 7239, ``X-Forwarded-For``, ``X-Real-IP``).  Such a request counts as
local only when

* the peer that sent it to us is a configured trusted proxy (``RSF_TRUSTED_PROXIES``,
  :attr:`rsfapp.config.Settings.trusted_proxies`), and
* the original client named by every forwarding header present is loopback: in a
  chain (``X-Forwarded-For: client, proxy1, proxy2``, or several ``for=`` elements)
  the original client is the rightmost address that is not a trusted proxy (addresses
  on the left were written by whoever sent the request, so a client cannot pose as
  loopback by sending its own ``X-Forwarded-For: 127.0.0.1``).

Anything that cannot be read (``for=unknown``, an obfuscated node, a malformed address,
no peer address) does not count as loopback: the answer is then 401, never admin.
"""

from __future__ import annotations

import ipaddress
from collections.abc import Iterable, Sequence

from starlette.types import Scope

from rsfapp.config import IPNetwork

__all__ = ["FORWARDING_HEADERS", "IPAddress", "from_this_host", "original_client", "parse_address"]

#: An IPv4 or IPv6 address.
IPAddress = ipaddress.IPv4Address | ipaddress.IPv6Address
#: Request headers that say a proxy forwarded the request (lower case, as in ASGI).
FORWARDING_HEADERS = (b"forwarded", b"x-forwarded-for", b"x-real-ip")


def parse_address(token: str) -> IPAddress | None:
    """The IP address in a forwarding-header node (``203.0.113.9``, ``"[2001:db8::1]:4711"``,
    ``192.0.2.4:8080``, ``fe80::1%eth0``), None if it names none (``unknown``,
    ``_hidden``, garbage).  An IPv4-mapped IPv6 address is its IPv4 address."""
    s = token.strip().strip('"').strip()
    if s.startswith("["):
        end = s.find("]")
        if end < 0:
            return None
        s = s[1:end]
    elif s.count(":") == 1:  # IPv4 with a port (an IPv6 address has two colons or more)
        s = s.partition(":")[0]
    s = s.partition("%")[0]
    try:
        addr = ipaddress.ip_address(s)
    except ValueError:
        return None
    if isinstance(addr, ipaddress.IPv6Address) and addr.ipv4_mapped is not None:
        return addr.ipv4_mapped
    return addr


def _trusted(addr: IPAddress | None, trusted: Sequence[IPNetwork]) -> bool:
    return addr is not None and any(addr in net for net in trusted)


def original_client(
    chain: Sequence[IPAddress | None], trusted: Sequence[IPNetwork]
) -> IPAddress | None:
    """The original client of a forwarding chain (oldest hop first): the rightmost node
    that is not a trusted proxy (the leftmost if all are); None if that node is not an
    address or the chain is empty."""
    for addr in reversed(chain):
        if not _trusted(addr, trusted):
            return addr
    return chain[0] if chain else None


def _forwarded_for(value: str) -> list[IPAddress | None]:
    """The ``for=`` node of each element of a ``Forwarded`` header (None: element without
    one, or not an address)."""
    out: list[IPAddress | None] = []
    for element in value.split(","):
        node: IPAddress | None = None
        for pair in element.split(";"):
            name, eq, v = pair.partition("=")
            if eq and name.strip().lower() == "for":
                node = parse_address(v)
        out.append(node)
    return out


def _chains(headers: Iterable[tuple[bytes, bytes]]) -> list[list[IPAddress | None]]:
    """One chain per forwarding header present (repeated header lines joined in order)."""
    by_name: dict[bytes, list[str]] = {}
    for k, v in headers:
        name = k.lower()
        if name in FORWARDING_HEADERS:
            by_name.setdefault(name, []).append(v.decode("latin-1"))
    chains: list[list[IPAddress | None]] = []
    for name, values in by_name.items():
        text = ",".join(values)
        if name == b"forwarded":
            chains.append(_forwarded_for(text))
        else:
            chains.append([parse_address(t) for t in text.split(",")])
    return chains


def from_this_host(scope: Scope, trusted: Sequence[IPNetwork]) -> bool:
    """True if the request of ``scope`` came from this host: it reached a loopback
    interface (or a unix socket, or an in-process transport without an IP address) and,
    if it carries forwarding headers, its peer is one of the ``trusted`` proxies and the
    original client every such header names is loopback (module docstring)."""
    server = scope.get("server")
    if server:
        here = parse_address(str(server[0]))
        if here is not None and not here.is_loopback:
            return False
    chains = _chains(scope.get("headers") or ())
    if not chains:
        return True
    client = scope.get("client")
    peer = parse_address(str(client[0])) if client else None
    if not _trusted(peer, trusted):
        return False
    for chain in chains:
        orig = original_client(chain, trusted)
        if orig is None or not orig.is_loopback:
            return False
    return True
