"""``aioadept opcua --security``: the modes offered, the server certificate made at first start, and which endpoints
may listen beyond loopback (aioadept.opcua.security, aioadept.cli.opcua.check_endpoint)."""

from __future__ import annotations

import stat

import pytest

from aioadept.cli.opcua import check_endpoint, main
from aioadept.opcua.security import APPLICATION_URI, check_modes, server_certificate


async def test_a_certificate_is_made_once_for_the_server_s_uri_and_host_its_key_the_owner_s_only(tmp_path) -> None:
    from cryptography import x509

    folder = tmp_path / "aioadept" / "opcua"
    cert, key = await server_certificate("cell-7.plant", folder)
    assert stat.S_IMODE(folder.stat().st_mode) == 0o700
    assert stat.S_IMODE(key.stat().st_mode) & 0o077 == 0
    c = x509.load_der_x509_certificate(cert.read_bytes())
    names = c.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    assert names.get_values_for_type(x509.UniformResourceIdentifier) == [APPLICATION_URI]
    assert names.get_values_for_type(x509.DNSName) == ["cell-7.plant"]
    first = cert.read_bytes()
    assert await server_certificate("cell-7.plant", folder) == (cert, key) and cert.read_bytes() == first  # kept
    await server_certificate("cell-8.plant", folder)  # another host: a new certificate, same key
    assert cert.read_bytes() != first


def test_modes_are_checked_and_ordered() -> None:
    assert check_modes(["sign-and-encrypt", "none"]) == ("none", "sign-and-encrypt")
    with pytest.raises(ValueError, match="--security Basic256: expected one or more of none, sign, sign-and-encrypt"):
        check_modes(["Basic256"])
    with pytest.raises(ValueError, match=r"\(empty\)"):
        check_modes([""])


@pytest.mark.parametrize("security, refused", [
    (("sign-and-encrypt",), False),
    (("none", "sign-and-encrypt"), True),   # a client may still pick None
    (("sign",), True),                       # signed, but anyone on the way reads it
])
def test_beyond_loopback_only_encryption_for_every_client_starts_without_insecure(security, refused) -> None:
    if refused:
        with pytest.raises(ValueError, match="0.0.0.0 is not loopback"):
            check_endpoint("opc.tcp://0.0.0.0:4840", False, security)
        check_endpoint("opc.tcp://0.0.0.0:4840", True, security)   # said explicitly: it starts, with a warning
    else:
        assert check_endpoint("opc.tcp://0.0.0.0:4840", False, security) == "opc.tcp://0.0.0.0:4840"
    check_endpoint("opc.tcp://127.0.0.1:4840", False, security)


@pytest.mark.parametrize("args, says", [
    (["--security", "sign,tls"], "--security sign,tls: expected one or more of none, sign, sign-and-encrypt"),
    (["--security", "sign", "--certificate", "c.der"], "--certificate and --private-key go together"),
    (["--certificate", "c.der", "--private-key", "k.pem"], "--certificate: only for --security sign"),
    (["--security", "sign", "--certificate", "no-such.der", "--private-key", "k.pem"],
     "--certificate no-such.der: no such file"),
])
def test_a_security_mistake_is_one_line(args, says, capsys) -> None:
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("aioadept opcua: ") and says in err[0], err


async def test_a_trust_folder_holds_certificates_only_and_trusts_what_it_holds(tmp_path) -> None:
    from asyncua.crypto.uacrypto import load_certificate

    from aioadept.opcua.security import check_trust_folder, trust_list

    trusted, other = tmp_path / "trusted", tmp_path / "other"
    trusted.mkdir()
    other.mkdir()
    cert, key = await server_certificate("127.0.0.1", trusted)  # a certificate and, beside it, its key
    stranger, _ = await server_certificate("localhost", other)
    with pytest.raises(ValueError, match=r"--trust .*trusted: server-key\.pem is not a certificate \(keep keys"):
        check_trust_folder(trusted)
    key.rename(tmp_path / key.name)
    assert check_trust_folder(trusted) == [cert]
    store = await trust_list(trusted)
    assert store.is_trusted(await load_certificate(str(cert)))
    assert not store.is_trusted(await load_certificate(str(stranger)))
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match=r"--user-certificates .*empty: no certificate"):
        check_trust_folder(tmp_path / "empty", "--user-certificates")
