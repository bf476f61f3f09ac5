"""The ``-o`` argument of ``planarcal run`` read as a destination: ``tcp://HOST:PORT``,
``udp://HOST:PORT`` and ``tcp-listen://HOST:PORT`` become (scheme, host, port), anything else
is a file path.

A malformed network spec raises ``OutputError`` here, at start-up, so that a typo
(``tcp:host:5000``, ``tcp://host``, ``ftp://...``) fails at once instead of writing a file
named after it or streaming nowhere for hours. ``tcp-listen`` (planarcal as the server) takes
port 0 (any free port; the server reports the one it got) and needs a host to listen on
(``0.0.0.0`` or ``[::]`` for every interface, ``127.0.0.1`` for this machine only).
"""

from __future__ import annotations

import re

from planarcal.errors import OutputError

__all__ = ["SPEC_HELP", "check_port", "netloc", "parse_network_spec"]

SPEC_HELP = (
    "expected '-' (stdout), tcp://HOST:PORT, udp://HOST:PORT, tcp-listen://HOST:PORT or a file path"
)
"""What an ``-o`` spec may be, for the end of an error message."""

_NETWORK_SCHEMES = ("tcp", "udp", "tcp-listen")


def parse_network_spec(spec: str) -> tuple[str, str, int] | None:
    """(scheme, host, port) for tcp://, udp:// and tcp-listen:// specs (the scheme in lower
    case), None for a file path. Raises OutputError for an empty spec, an unknown scheme, or a
    network spec that is malformed."""
    if not spec.strip():
        raise OutputError(f"empty output: {SPEC_HELP}")
    match = re.fullmatch(r"([A-Za-z][A-Za-z0-9+.-]*)://(.*)", spec, flags=re.DOTALL)
    if match is None:
        _refuse_scheme_without_slashes(spec)
        return None
    scheme, rest = match.group(1).lower(), match.group(2)
    if scheme not in _NETWORK_SCHEMES:
        raise OutputError(f"output {spec!r}: unknown scheme {scheme!r}; {SPEC_HELP}")
    host, port_text = _host_and_port_text(spec, scheme, rest.removesuffix("/"))
    return scheme, host, _port(spec, scheme, port_text)


def _refuse_scheme_without_slashes(spec: str) -> None:
    """Raises for ``tcp:host:5000``: a typo for a network output far more often than a file
    name (which can still be written ``./tcp:host:5000``)."""
    lowered = spec.lower()
    for scheme in _NETWORK_SCHEMES:
        if lowered.startswith(scheme + ":"):
            what = "to listen for controllers" if scheme == "tcp-listen" else "for a peer"
            raise OutputError(
                f"output {spec!r}: write {scheme}://HOST:PORT {what} "
                f"(for a file of that name, write ./{spec})"
            )


def _host_and_port_text(spec: str, scheme: str, rest: str) -> tuple[str, str]:
    """The host and the (unchecked) port text of what follows ``scheme://``."""
    if not rest:
        raise OutputError(f"output {spec!r}: no host and port; write {scheme}://HOST:PORT")
    if any(c in rest for c in "/?#@ "):
        raise OutputError(
            f"output {spec!r}: only a host and a port may follow {scheme}://, as in "
            f"{_example(scheme)}"
        )
    if rest.startswith("["):
        host, port_text = _bracketed_host_and_port_text(spec, rest)
    elif rest.count(":") > 1:
        raise OutputError(
            f"output {spec!r}: an IPv6 address goes in brackets, as in {scheme}://[::1]:5000"
        )
    else:
        host, _, port_text = rest.partition(":")
    if not host and scheme == "tcp-listen":
        raise OutputError(
            f"output {spec!r}: no host to listen on; write tcp-listen://0.0.0.0:PORT for every "
            "interface or tcp-listen://127.0.0.1:PORT for this machine only"
        )
    if not host:
        raise OutputError(f"output {spec!r}: no host; write {scheme}://HOST:PORT")
    return host, port_text


def _bracketed_host_and_port_text(spec: str, rest: str) -> tuple[str, str]:
    """``[IPv6]:PORT`` split into the address (without brackets) and the port text."""
    end = rest.find("]")
    if end < 0:
        raise OutputError(f"output {spec!r}: unclosed '[' around an IPv6 address")
    host, after = rest[1:end], rest[end + 1 :]
    if after and not after.startswith(":"):
        raise OutputError(f"output {spec!r}: expected ':PORT' after the ']'")
    return host, after[1:]


def _port(spec: str, scheme: str, port_text: str) -> int:
    """The port number of a spec, 1-65535."""
    if not port_text:
        raise OutputError(
            f"output {spec!r}: no port; write {scheme}://HOST:PORT, as in {_example(scheme)}"
        )
    if not re.fullmatch(r"[0-9]+", port_text):
        raise OutputError(f"output {spec!r}: the port {port_text!r} is not a number")
    port = int(port_text)
    lowest = 0 if scheme == "tcp-listen" else 1  # a listener may let the system choose
    if not lowest <= port <= 65535:
        raise OutputError(f"output {spec!r}: port {port} is out of range {lowest}-65535")
    return port


def _example(scheme: str) -> str:
    return f"{scheme}://192.168.0.10:5000"


def netloc(host: str, port: int) -> str:
    """``host:port``, with an IPv6 address in brackets (``[::1]:5000``)."""
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def check_port(port: int, *, lowest: int = 1) -> None:
    """Raises OutputError unless ``port`` is an int (not a bool) in `lowest`-65535 (a
    listener may take 0: any free port)."""
    if not isinstance(port, int) or isinstance(port, bool) or not lowest <= port <= 65535:
        raise OutputError(f"port {port!r} is out of range {lowest}-65535")
