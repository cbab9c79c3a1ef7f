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
import re
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
    """The CA of ``directory``: its certificate and its private key (UsageError in one line, naming the
    file, where one is not a PEM certificate or key, or the key is not the certificate's)."""
    x509, _, serialization, _, _, _ = _crypto()
    cert, key = directory / "ca.pem", directory / "ca.key"
    try:
        ca = x509.load_pem_x509_certificate(cert.read_bytes())
    except (OSError, ValueError) as exc:
        raise UsageError(f"{cert} is not a readable PEM certificate ({getattr(exc, 'strerror', None) or 'corrupt'}): "
                         f"restore it, or make a new CA with zswarm certs {directory} --force") from None
    try:
        ca_key = serialization.load_pem_private_key(key.read_bytes(), password=None)
    except (OSError, ValueError, TypeError) as exc:
        raise UsageError(f"{key} is not a readable PEM private key ({getattr(exc, 'strerror', None) or 'corrupt'}): "
                         f"restore it, or make a new CA with zswarm certs {directory} --force") from None
    if not _same_key(ca.public_key(), ca_key.public_key()):
        raise UsageError(f"{key} is not the key of {cert}: restore the pair, or make a new CA with zswarm certs "
                         f"{directory} --force")
    return ca, ca_key


def _same_key(a, b) -> bool:
    """Whether two public keys are one (compared as their DER, whatever their kind)."""
    _, _, serialization, _, _, _ = _crypto()
    der = serialization.Encoding.DER, serialization.PublicFormat.SubjectPublicKeyInfo
    return a.public_bytes(*der) == b.public_bytes(*der)


#: A DNS name a certificate may carry: dot-separated labels of letters, digits and inner hyphens.
HOST_NAME = re.compile(r"^(?=.{1,253}$)([A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?)(\.[A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?)*$")


def check_hosts(hosts: Sequence[str]) -> tuple[str, ...]:
    """``hosts`` as given, each an IP address or a DNS name (UsageError in one line naming the first that
    is neither)."""
    for host in hosts:
        try:
            ipaddress.ip_address(host)
        except ValueError:
            if not HOST_NAME.match(host) or host.replace(".", "").isdigit():
                raise UsageError(f"--hosts: {host!r} is neither an IP address nor a host name (letters, digits "
                                 "and hyphens, in dot-separated labels)") from None
    if not hosts:
        raise UsageError("--hosts names no host: give the names and addresses the router is reached by")
    return tuple(hosts)


def write_bundle(directory: Path, out: Path, patterns: Sequence[str]) -> list[str]:
    """Into ``out`` (made private), what another machine needs of ``directory``: the CA's certificate and,
    for each identity whose name matches one of ``patterns`` (shell patterns: ``agent-*``), its key,
    certificate and config; never the CA's key. The identities copied, by name."""
    import fnmatch
    import shutil

    directory = Path(directory)
    if not (directory / "ca.pem").is_file():
        raise UsageError(f"{directory} holds no CA (ca.pem): make it first with zswarm certs {directory}")
    names = sorted(p.stem for p in directory.glob("*.json5")
                   if any(fnmatch.fnmatchcase(p.stem, pat) for pat in patterns))
    if not names:
        have = ", ".join(sorted(p.stem for p in directory.glob("*.json5"))) or "none"
        raise UsageError(f"--names {','.join(patterns)} matches no identity of {directory} (it has: {have})")
    if Path(out).resolve() == directory.resolve():
        raise UsageError("--bundle must be another folder than DIR")
    out = private_dir(out)
    shutil.copyfile(directory / "ca.pem", out / "ca.pem")
    for name in names:
        paths = CertPaths(directory, name)
        if not paths.key.is_file():
            raise UsageError(f"{directory} has no {paths.key.name}: {name}'s key was made on another machine")
        _write_key(out / paths.key.name, paths.key.read_bytes())
        for src in (paths.cert, directory / f"{name}.json5"):
            shutil.copyfile(src, out / src.name)
        check_config_files(out / f"{name}.json5", out)
    return names


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


def check_config_files(config: Path, folder: Path | None = None) -> None:
    """The TLS files a Zenoh config names (:func:`zswarm.net.config.tls_files`), checked before anything
    starts: each there and readable, inside ``folder`` when one is given (a ``--secure`` folder uses its
    own files), and, where ``cryptography`` is installed, each certificate and key one, each key its
    certificate's, each certificate signed by the config's CA. UsageError in one line naming the file
    otherwise (Zenoh itself says only that a session could not open)."""
    import zenoh

    from zswarm.net.config import tls_files

    files = tls_files(zenoh.Config.from_file(str(config)), Path(config).resolve().parent)
    data = {}
    for key, path in files.items():
        what = "private key" if key.endswith("_key") else "certificate"
        if folder is not None and path.resolve().parent != Path(folder).resolve():
            raise UsageError(f"{config} names {path}, outside {folder}: its configs were written by an older "
                             f"zswarm; write them anew with: zswarm certs {folder}")
        try:
            data[key] = path.read_bytes()
        except OSError as exc:
            raise UsageError(f"{config} names {path} as its {what}: {exc.strerror} (a copy of the folder needs "
                             "the files beside the config)") from None
    try:
        x509, _, serialization, _, _, _ = _crypto()
    except UsageError:  # without the tls extra: Zenoh checks the rest when it opens
        return
    loaded = {}
    for key, pem in data.items():
        try:
            loaded[key] = (serialization.load_pem_private_key(pem, password=None) if key.endswith("_key")
                           else x509.load_pem_x509_certificate(pem))
        except (ValueError, TypeError):
            what = "private key" if key.endswith("_key") else "certificate"
            raise UsageError(f"{files[key]} is not a PEM {what} ({config} names it): make it again with "
                             "zswarm certs") from None

    ca = loaded.get("root_ca_certificate")
    for side in ("connect", "listen"):
        key, cert = loaded.get(f"{side}_private_key"), loaded.get(f"{side}_certificate")
        if key is not None and cert is not None and not _same_key(key.public_key(), cert.public_key()):
            raise UsageError(f"{files[f'{side}_private_key']} is not the key of {files[f'{side}_certificate']} "
                             f"({config} names both): copy the pair that was made together")
        if ca is not None and cert is not None:
            try:
                cert.verify_directly_issued_by(ca)
            except Exception:  # noqa: BLE001 (InvalidSignature, or a CA of another kind of key)
                raise UsageError(f"{files[f'{side}_certificate']} is not signed by the CA "
                                 f"{files['root_ca_certificate']} ({config} names both): copy the CA and the "
                                 "certificates it signed") from None
