"""``aioadept opcua --trust DIR --user-certificates DIR``: a trust list of client certificates, and users who command
with a certificate instead of a password. Real processes on 127.0.0.1 (``aioadept sim``, ``aioadept opcua`` offering
Basic256Sha256 SignAndEncrypt only), asyncua's client with certificates made here."""

from __future__ import annotations

import importlib.util

import pytest

from opcuacell import opcua_cell

pytestmark = pytest.mark.skipif(importlib.util.find_spec("asyncua") is None,
                                reason="the [opcua] extra (asyncua) is not installed")

CLIENT_URI = "urn:aioadept:test:client"


async def certificate(folder, name: str, uri: str = CLIENT_URI):
    """A self-signed client certificate (DER) in ``folder``, common name ``name``, and its key (PEM) beside it."""
    from asyncua.crypto.cert_gen import setup_self_signed_certificate
    from cryptography.x509.oid import ExtendedKeyUsageOID

    folder.mkdir(exist_ok=True)
    key, cert = folder.parent / f"{name}-key.pem", folder / f"{name}.der"
    await setup_self_signed_certificate(key, cert, uri, "localhost", [ExtendedKeyUsageOID.CLIENT_AUTH],
                                        {"commonName": name})
    return cert, key


async def client(url: str, cert, key, user=None):
    """asyncua's client over Basic256Sha256 SignAndEncrypt with the application certificate ``cert``; ``user``: a
    (certificate, key) to present as an X509 identity token."""
    from asyncua import Client, ua
    from asyncua.crypto.security_policies import SecurityPolicyBasic256Sha256

    c = Client(url, timeout=20)
    c.application_uri = CLIENT_URI
    await c.set_security(SecurityPolicyBasic256Sha256, str(cert), str(key),
                         mode=ua.MessageSecurityMode.SignAndEncrypt)
    if user is not None:
        await c.load_client_certificate(str(user[0]))
        await c.load_private_key(user[1])
    return c


async def stop_method(c):
    from asyncua import ua

    idx = await c.get_namespace_index("urn:aioadept:opcua:cell")
    vidx = await c.get_namespace_index("urn:aioadept:opcua:commands")
    device = c.get_node(ua.NodeId("MotionDeviceSystem.Robot1", idx))
    return device, await device.get_child([ua.QualifiedName("Stop", vidx)])


@pytest.mark.timeout(90)
async def test_only_trusted_clients_connect_and_a_user_certificate_may_command(tmp_path) -> None:
    from asyncua import ua

    trusted, users = tmp_path / "trusted", tmp_path / "user-certs"
    app = await certificate(trusted, "plant-mes")                      # in the trust list
    stranger = await certificate(tmp_path / "elsewhere", "stranger")   # not in it
    operator = await certificate(users, "operator")                   # a user who may command
    intruder = await certificate(tmp_path / "elsewhere", "intruder")   # a user certificate nobody trusted
    passwords = tmp_path / "users"
    passwords.write_text("someone:s3cret\n")
    passwords.chmod(0o600)
    async with opcua_cell(tmp_path, "--security", "sign-and-encrypt", "--trust", str(trusted), "--allow-commands",
                          "--users", str(passwords), "--user-certificates", str(users)) as cell:
        # A client whose application certificate the trust list does not hold gets no session.
        with pytest.raises(ua.UaStatusCodeError) as refused:
            async with await client(cell.url, *stranger):
                pass
        assert refused.value.code == ua.StatusCodes.BadCertificateUntrusted

        # A trusted client reads (anonymous) and may not command; the methods take a user certificate.
        async with await client(cell.url, *app) as anonymous:
            offered = {t.TokenType for e in await anonymous.get_endpoints() for t in e.UserIdentityTokens}
            assert ua.UserTokenType.Certificate in offered and ua.UserTokenType.UserName in offered
            device, stop = await stop_method(anonymous)
            assert (await device.read_browse_name()).Name == "Robot1"
            with pytest.raises(ua.UaStatusCodeError) as denied:
                await device.call_method(stop)
            assert denied.value.code == ua.StatusCodes.BadUserAccessDenied

        async with await client(cell.url, *app, user=operator) as commander:
            device, stop = await stop_method(commander)
            ack = await device.call_method(stop)
            assert ":done:" in ack, ack

        # A user certificate outside the user certificates' folder gets no session.
        with pytest.raises(ua.UaStatusCodeError) as unknown:
            async with await client(cell.url, *app, user=intruder):
                pass
        assert unknown.value.code == ua.StatusCodes.BadUserAccessDenied


@pytest.mark.parametrize("args, says", [
    (["--trust", "."], "--trust: only with --security sign or sign-and-encrypt, none not offered"),
    (["--security", "none,sign-and-encrypt", "--trust", "."], "--trust: only with"),
    (["--security", "sign-and-encrypt", "--trust", "no-such-dir"], "--trust no-such-dir: no such folder"),
    (["--security", "sign-and-encrypt", "--trust", "src"], "--trust src: no certificate (.der or .pem) in it"),
    (["--security", "sign", "--allow-commands", "--user-certificates", "no-such-dir"],
     "--user-certificates no-such-dir: no such folder"),
    (["--security", "sign", "--user-certificates", "."], "--users is only for --allow-commands"),
])
def test_trust_list_mistakes_are_one_line(args: list[str], says: str) -> None:
    from cliinproc import run_inproc

    proc = run_inproc("opcua", *args)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("aioadept opcua: ") and says in lines[0], proc.stderr
