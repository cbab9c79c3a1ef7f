"""A private certificate authority for a swarm: one CA, one certificate per role.

Zenoh's TLS link authenticates both ends (mTLS) against the CA, and its access control matches a
connected session by the common name (CN) of the certificate it presented. So the CN *is* the role:
``router``, ``world``, ``agent``, and anything else (``guest``) is a session that may connect but has
no rights. Made with the ``cryptography`` package (ECDSA P-256, valid ``days`` days).
"""

from __future__ import annotations

import datetime as dt
import ipaddress
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

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


def _pem(serialization, key=None, cert=None) -> bytes:
    if key is not None:
        return key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                 serialization.NoEncryption())
    return cert.public_bytes(serialization.Encoding.PEM)


def _write_key(path: Path, pem: bytes) -> None:
    """A private key, readable by its owner alone from the moment it exists."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "wb") as f:
        f.write(pem)
    path.chmod(0o600)


def private_dir(directory: Path) -> Path:
    """``directory``, made if missing, readable by its owner alone, with a ``.gitignore`` that keeps its
    keys out of any repository it sits in (``git add .`` adds none of them)."""
    directory = Path(directory)
    directory.mkdir(mode=0o700, parents=True, exist_ok=True)
    directory.chmod(0o700)
    ignore = directory / ".gitignore"
    if not ignore.exists():
        ignore.write_text("# private keys and certificates: never to be committed\n*\n")
    return directory


def _validity(days: int) -> tuple[dt.datetime, dt.datetime]:
    now = dt.datetime.now(dt.timezone.utc)
    return now - dt.timedelta(minutes=5), now + dt.timedelta(days=days)


def _leaf(name: str, public_key, ca_cert, ca_key, hosts: tuple[str, ...], days: int):
    """A certificate for ``name`` (its CN) over ``public_key``, signed by the CA: ``hosts`` as subject
    alternative names, both a TLS server and client."""
    x509, hashes, _, _, eku, oid = _crypto()
    sans: list = []
    for host in hosts:
        try:
            sans.append(x509.IPAddress(ipaddress.ip_address(host)))
        except ValueError:
            sans.append(x509.DNSName(host))
    valid_from, valid_to = _validity(days)
    return (x509.CertificateBuilder()
            .subject_name(x509.Name([x509.NameAttribute(oid.COMMON_NAME, name)]))
            .issuer_name(ca_cert.subject).public_key(public_key)
            .serial_number(x509.random_serial_number())
            .not_valid_before(valid_from).not_valid_after(valid_to)
            .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
            .add_extension(x509.SubjectAlternativeName(sans), critical=False)
            .add_extension(x509.ExtendedKeyUsage([eku.SERVER_AUTH, eku.CLIENT_AUTH]), critical=False)
            .sign(ca_key, hashes.SHA256()))


def make_certs(directory: Path, names: tuple[str, ...] = ROLES, hosts: tuple[str, ...] = ("localhost", LOOPBACK),
               days: int = 30) -> dict[str, CertPaths]:
    """Write ``ca.pem``/``ca.key`` and ``NAME.pem``/``NAME.key`` for every name into ``directory``.

    A CA already there (both its files) is kept and signs the new certificates, so that copies of
    its earlier ones stay valid; a name's key already there is kept too. Every leaf carries ``hosts``
    as subject alternative names (the router's address is checked against them when
    ``verify_name_on_connect`` is on) and is both a TLS server and client.
    """
    x509, hashes, serialization, ec, _, oid = _crypto()
    directory = private_dir(directory)
    if (directory / "ca.pem").is_file() and (directory / "ca.key").is_file():
        return _leaves(directory, names, *_load_ca(directory), hosts, days)
    valid_from, valid_to = _validity(days)
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
    (directory / "ca.pem").write_bytes(_pem(serialization, cert=ca))
    _write_key(directory / "ca.key", _pem(serialization, key=ca_key))
    return _leaves(directory, names, ca, ca_key, hosts, days)


def _leaves(directory: Path, names: Sequence[str], ca, ca_key, hosts: tuple[str, ...], days: int) -> dict[str, CertPaths]:
    """``NAME.pem`` signed by the CA for every name, over its key (made where there is none)."""
    _, _, serialization, _, _, _ = _crypto()
    out = {}
    for name in names:
        paths = CertPaths(directory, name)
        key = _own_key(paths.key)
        paths.cert.write_bytes(_pem(serialization, cert=_leaf(name, key.public_key(), ca, ca_key, hosts, days)))
        out[name] = paths
    return out


def _load_ca(directory: Path) -> tuple:
    """The CA of ``directory``: its certificate and its private key."""
    x509, _, serialization, _, _, _ = _crypto()
    return (x509.load_pem_x509_certificate((directory / "ca.pem").read_bytes()),
            serialization.load_pem_private_key((directory / "ca.key").read_bytes(), password=None))


def _own_key(path: Path):
    """The private key at ``path``, made there (readable by its owner alone) where there is none."""
    _, _, serialization, ec, _, _ = _crypto()
    if path.exists():
        return serialization.load_pem_private_key(path.read_bytes(), password=None)
    key = ec.generate_private_key(ec.SECP256R1())
    _write_key(path, _pem(serialization, key=key))
    return key


def make_keys(directory: Path, names: Sequence[str]) -> dict[str, str]:
    """A key pair for every name that has none yet in ``directory`` (made private to its owner): the
    private halves stay there, the public halves (PEM) are returned, to be signed by :func:`sign`
    wherever the CA is. This is how a node of a cluster gets its identities without a private key
    crossing the network."""
    _, _, serialization, _, _, _ = _crypto()
    directory = private_dir(directory)
    out = {}
    for name in names:
        key = _own_key(CertPaths(directory, name).key)
        out[name] = key.public_key().public_bytes(serialization.Encoding.PEM,
                                                  serialization.PublicFormat.SubjectPublicKeyInfo).decode()
    return out


def require_ca_key(directory: Path) -> Path:
    """``directory``, whose CA can sign certificates made elsewhere: UsageError in one line if its key
    is not there."""
    directory = Path(directory)
    if not (directory / "ca.key").is_file():
        raise UsageError(f"--secure {directory} has no ca.key: over other machines each node's own keys are "
                         "signed by the CA there (give a new directory for zswarm to make, or yours with its "
                         "CA's key)")
    return directory


def cert_hosts(path: Path) -> tuple[str, ...]:
    """The hosts (subject alternative names) a certificate is valid for."""
    x509, _, _, _, _, _ = _crypto()
    cert = x509.load_pem_x509_certificate(Path(path).read_bytes())
    sans = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    return tuple(str(v) for v in [*sans.get_values_for_type(x509.DNSName), *sans.get_values_for_type(x509.IPAddress)])


def sign(ca_directory: Path, public_keys: dict[str, str], hosts: tuple[str, ...], days: int = 30) -> dict[str, str]:
    """Certificates (PEM) for public keys made elsewhere (:func:`make_keys`), by the CA of
    ``ca_directory`` (its ``ca.pem`` and ``ca.key``), each named for its key's name and valid for
    ``hosts``."""
    _, _, serialization, _, _, _ = _crypto()
    ca_cert, ca_key = _load_ca(require_ca_key(ca_directory))
    return {name: _pem(serialization, cert=_leaf(name, serialization.load_pem_public_key(pem.encode()),
                                                 ca_cert, ca_key, hosts, days)).decode()
            for name, pem in public_keys.items()}
