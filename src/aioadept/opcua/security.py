"""How ``aioadept opcua`` secures its endpoint: the security modes it offers and the server's certificate.

Three modes, each a SecurityPolicy and a MessageSecurityMode of OPC UA Part 2/4: ``none`` (SecurityPolicy None: no
signature, no encryption; loopback only unless ``--insecure``), ``sign`` and ``sign-and-encrypt`` (Basic256Sha256,
every message signed, or signed and encrypted). A signed mode needs the server's application instance certificate
and its private key: given (``--certificate``/``--private-key``), or made once, self-signed, into the user's folder
(:func:`server_certificate`) and kept, so clients that trusted it keep trusting it. docs/opcua.md, "Security".
"""

from __future__ import annotations

import os
import socket
from collections.abc import Iterable
from pathlib import Path

__all__ = ["APPLICATION_URI", "MODES", "ENCRYPTED", "certificate_folder", "check_modes", "server_certificate"]

MODES = ("none", "sign", "sign-and-encrypt")
"""The modes by the names the options and the cell file use."""
ENCRYPTED = "sign-and-encrypt"
APPLICATION_URI = f"urn:{socket.gethostname()}:aioadept:opcua"
"""The server's ApplicationUri; the certificate made for it names it (OPC UA Part 6: the certificate's
subjectAltName URI is the application's)."""


def check_modes(modes: Iterable[str], option: str = "--security") -> tuple[str, ...]:
    """``modes`` as given (each once, in :data:`MODES` order); ValueError naming ``option`` for an unknown one or
    none at all."""
    given = [m.strip() for m in modes if m.strip()]
    bad = [m for m in given if m not in MODES]
    if bad or not given:
        raise ValueError(f"{option} {','.join(given) or '(empty)'}: expected one or more of {', '.join(MODES)}")
    return tuple(m for m in MODES if m in given)


def certificate_folder() -> Path:
    """Where a made certificate lives: ``$XDG_DATA_HOME/aioadept/opcua`` (``~/.local/share/aioadept/opcua``)."""
    base = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(base) / "aioadept" / "opcua"


async def server_certificate(host: str, folder: Path | None = None) -> tuple[Path, Path]:
    """The server's certificate (DER) and private key (PEM) in ``folder`` (default :func:`certificate_folder`): made
    there, self-signed for a year, for :data:`APPLICATION_URI` and ``host``, when missing, expired or made for
    another URI or host; else the ones made before. The folder is the owner's only (0700) and so is the key (0600)."""
    from asyncua.crypto.cert_gen import setup_self_signed_certificate
    from cryptography.x509.oid import ExtendedKeyUsageOID

    folder = certificate_folder() if folder is None else folder
    folder.mkdir(parents=True, exist_ok=True, mode=0o700)
    os.chmod(folder, 0o700)
    key, cert = folder / "server-key.pem", folder / "server-cert.der"
    old = os.umask(0o077)  # the key is written by asyncua: never readable by others, not even for a moment
    try:
        await setup_self_signed_certificate(key, cert, APPLICATION_URI, host,
                                            [ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH],
                                            {"commonName": "aioadept opcua", "organizationName": "aioadept"})
    finally:
        os.umask(old)
    return cert, key
