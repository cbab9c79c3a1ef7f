"""A private certificate authority for a swarm: one CA, one certificate per role.

Zenoh's TLS link authenticates both ends (mTLS) against the CA, and its access control matches a
connected session by the common name (CN) of the certificate it presented. So the CN *is* the role:
``router``, ``world``, ``agent``, and anything else (``guest``) is a session that may connect but has
no rights. Made with the ``cryptography`` package (ECDSA P-256, valid ``days`` days).
"""

from __future__ import annotations

import datetime as dt
import ipaddress
from dataclasses import dataclass
from pathlib import Path

from zswarm.errors import UsageError
from zswarm.ports import LOOPBACK

ROLES = ("router", "world", "agent")


@dataclass(frozen=True)
class CertPaths:
    """Where one role's certificate and key live in a certificate directory."""

    directory: Path
    name: str

    @property
    def cert(self) -> Path:
        return self.directory / f"{self.name}.pem"

    @property
    def key(self) -> Path:
        return self.directory / f"{self.name}.key"

    @property
    def ca(self) -> Path:
        return self.directory / "ca.pem"


def _crypto():
    try:
        from cryptography import x509
        from cryptography.hazmat.primitives import hashes, serialization
        from cryptography.hazmat.primitives.asymmetric import ec
        from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID
    except ImportError:
        raise UsageError("making certificates needs the 'cryptography' package: "
                         "pip install 'zswarm[tls]' (or make them with openssl)") from None
    return x509, hashes, serialization, ec, ExtendedKeyUsageOID, NameOID


def make_certs(directory: Path, names: tuple[str, ...] = ROLES, hosts: tuple[str, ...] = ("localhost", LOOPBACK),
               days: int = 30) -> dict[str, CertPaths]:
    """Write ``ca.pem``/``ca.key`` and ``NAME.pem``/``NAME.key`` for every name into ``directory``.

    Every leaf carries ``hosts`` as subject alternative names (the router's address is checked
    against them when ``verify_name_on_connect`` is on) and is both a TLS server and client.
    """
    x509, hashes, serialization, ec, eku, oid = _crypto()
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    now = dt.datetime.now(dt.timezone.utc)
    valid_from, valid_to = now - dt.timedelta(minutes=5), now + dt.timedelta(days=days)

    def key_pem(key) -> bytes:
        return key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                 serialization.NoEncryption())

    def cert_pem(cert) -> bytes:
        return cert.public_bytes(serialization.Encoding.PEM)

    ca_key = ec.generate_private_key(ec.SECP256R1())
    ca_name = x509.Name([x509.NameAttribute(oid.COMMON_NAME, "zswarm-ca")])
    ca = (x509.CertificateBuilder().subject_name(ca_name).issuer_name(ca_name)
          .public_key(ca_key.public_key()).serial_number(x509.random_serial_number())
          .not_valid_before(valid_from).not_valid_after(valid_to)
          .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
          .add_extension(x509.KeyUsage(digital_signature=True, key_cert_sign=True, crl_sign=True,
                                       content_commitment=False, key_encipherment=False,
                                       data_encipherment=False, key_agreement=False,
                                       encipher_only=False, decipher_only=False), critical=True)
          .sign(ca_key, hashes.SHA256()))
    (directory / "ca.pem").write_bytes(cert_pem(ca))
    (directory / "ca.key").write_bytes(key_pem(ca_key))
    (directory / "ca.key").chmod(0o600)

    sans: list = []
    for host in hosts:
        try:
            sans.append(x509.IPAddress(ipaddress.ip_address(host)))
        except ValueError:
            sans.append(x509.DNSName(host))
    out = {}
    for name in names:
        key = ec.generate_private_key(ec.SECP256R1())
        cert = (x509.CertificateBuilder()
                .subject_name(x509.Name([x509.NameAttribute(oid.COMMON_NAME, name)]))
                .issuer_name(ca_name).public_key(key.public_key())
                .serial_number(x509.random_serial_number())
                .not_valid_before(valid_from).not_valid_after(valid_to)
                .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
                .add_extension(x509.SubjectAlternativeName(sans), critical=False)
                .add_extension(x509.ExtendedKeyUsage([eku.SERVER_AUTH, eku.CLIENT_AUTH]), critical=False)
                .sign(ca_key, hashes.SHA256()))
        paths = CertPaths(directory, name)
        paths.cert.write_bytes(cert_pem(cert))
        paths.key.write_bytes(key_pem(key))
        paths.key.chmod(0o600)
        out[name] = paths
    return out
