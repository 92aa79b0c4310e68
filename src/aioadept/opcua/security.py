"""How ``aioadept opcua`` secures its endpoint: the security modes it offers and the server's certificate.

Three modes, each a SecurityPolicy and a MessageSecurityMode of OPC UA Part 2/4: ``none`` (SecurityPolicy None: no
signature, no encryption; loopback only unless ``--insecure``), ``sign`` and ``sign-and-encrypt`` (Basic256Sha256,
every message signed, or signed and encrypted). A signed mode needs the server's application instance certificate
and its private key: given (``--certificate``/``--private-key``), or made once, self-signed, into the user's folder
(:func:`server_certificate`) and kept, so clients that trusted it keep trusting it. Which clients the server trusts:
with a trust list (``--trust DIR``, :func:`trust_list`), only those whose application certificate it holds
(:func:`client_validator`); users may present a certificate instead of a password (``--user-certificates DIR``, an
X509 identity token, :class:`UserCertificate`). docs/opcua.md, "Security".
"""

from __future__ import annotations

import os
import socket
from collections.abc import Iterable
from pathlib import Path
from typing import Any

__all__ = ["APPLICATION_URI", "MODES", "ENCRYPTED", "UserCertificate", "certificate_folder", "check_modes", "check_trust_folder",
           "client_validator", "common_name", "mark_user_certificates", "server_certificate", "trust_list"]

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


class UserCertificate(bytes):
    """A user certificate (DER) that came in an X509 identity token and whose signature the server checked: told
    apart from the secure channel's application certificate, which asyncua hands the user manager the same way."""


def mark_user_certificates(iserver: Any) -> None:
    """Make asyncua's check of an X509 identity token answer a :class:`UserCertificate`."""
    verify = iserver.verify_x509_token

    def verified(isession: Any, token: Any, signature: Any) -> UserCertificate:
        return UserCertificate(verify(isession, token, signature))

    iserver.verify_x509_token = verified


def check_trust_folder(folder: Path, option: str = "--trust") -> list[Path]:
    """The certificate files of the trust-list folder ``folder`` (``*.der``, ``*.pem``); ValueError naming ``option``
    and the folder when it is missing or holds none, or the file that is not a certificate (a private key, say)."""
    from cryptography import x509

    if not folder.is_dir():
        raise ValueError(f"{option} {folder}: no such folder")
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in (".der", ".pem"))
    if not files:
        raise ValueError(f"{option} {folder}: no certificate (.der or .pem) in it")
    for f in files:
        data = f.read_bytes()
        try:
            (x509.load_pem_x509_certificate if data.lstrip().startswith(b"-----") else x509.load_der_x509_certificate)(
                data)
        except ValueError:
            raise ValueError(f"{option} {folder}: {f.name} is not a certificate (keep keys elsewhere)") from None
    return files


async def trust_list(folder: Path, option: str = "--trust") -> Any:
    """The certificates of ``folder`` (DER or PEM: each trusted itself, a CA's trusts what it signed) as asyncua's
    TrustStore; ValueError as :func:`check_trust_folder`."""
    from asyncua.crypto.truststore import TrustStore

    check_trust_folder(folder, option)
    store = TrustStore([folder], [])
    await store.load()
    return store


def client_validator(store: Any) -> Any:
    """asyncua's check of a client's application certificate at CreateSession: valid now, for the ApplicationUri the
    client gives, for a client, and in ``store``; else the session is refused (BadCertificateUntrusted for a
    certificate the store does not hold)."""
    from asyncua.crypto.validator import CertificateValidator, CertificateValidatorOptions as O

    return CertificateValidator(O.TIME_RANGE | O.URI | O.TRUSTED | O.PEER_CLIENT, store)


def common_name(der: bytes) -> str:
    """The certificate's subject common name (its user's name), or its SHA-256 fingerprint when it has none."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes

    cert = x509.load_der_x509_certificate(der)
    names = cert.subject.get_attributes_for_oid(x509.NameOID.COMMON_NAME)
    return str(names[0].value) if names else cert.fingerprint(hashes.SHA256()).hex()
