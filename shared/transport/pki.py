"""The cell's own small PKI for Zenoh over mutual TLS: one CA, and one certificate per identity (its common
name is the identity: the service name, 'operator' for the hrc tools, 'router'), each signed by the CA.

The router's access control (shared.transport.acl) matches sessions by these common names, so a certificate is a
permission: keep the CA key off the cell (`make_cell_pki` writes it as ca-key.pem; move it away after
issuing). Keys are EC P-256; certificates carry serverAuth and clientAuth, and the host names / addresses
given as subject alternative names (the router's address on the cell network; localhost for one host).
Written with the `cryptography` package (X.509 done right, instead of hand-built DER or an openssl CLI).

Files in the directory: ca.pem, ca-key.pem, <identity>.pem, <identity>-key.pem.
"""

from __future__ import annotations

import datetime
import ipaddress
from dataclasses import dataclass
from pathlib import Path

from shared.core.errors import ConfigError

DEFAULT_HOSTS = ("localhost", "127.0.0.1", "::1")
VALID_DAYS = 365


@dataclass(frozen=True)
class TlsIdentity:
    """What a session needs for mutual TLS: the cell CA and its own certificate and key (PEM files)."""

    name: str
    ca: Path
    certificate: Path
    key: Path

    @classmethod
    def from_dir(cls, directory: Path, name: str) -> "TlsIdentity":
        directory = Path(directory)
        identity = cls(name, directory / "ca.pem", directory / f"{name}.pem", directory / f"{name}-key.pem")
        missing = [str(p) for p in (identity.ca, identity.certificate, identity.key) if not p.is_file()]
        if missing:
            raise ConfigError(f"TLS identity {name!r}: missing {', '.join(missing)} (make them with `hrc certs`)")
        return identity


def _san(hosts: tuple[str, ...]):
    from cryptography import x509

    names = []
    for host in hosts:
        if not isinstance(host, str) or not host or any(c.isspace() for c in host):
            raise ConfigError(f"host {host!r}: expected a host name or an address")
        try:
            names.append(x509.IPAddress(ipaddress.ip_address(host)))
        except ValueError:
            names.append(x509.DNSName(host))
    return x509.SubjectAlternativeName(names)


def _write_key(path: Path, key) -> None:
    from cryptography.hazmat.primitives import serialization

    path.write_bytes(key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                       serialization.NoEncryption()))
    path.chmod(0o600)


def make_cell_pki(directory: Path, identities: list[str], hosts: tuple[str, ...] = DEFAULT_HOSTS) -> Path:
    """Create the CA and a certificate per identity in directory (created); returns the directory."""
    # imported here: a service that only reads certificates never loads cryptography
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

    san = _san(hosts)                          # a bad host is refused before anything is written
    for name in identities:
        if not name or "/" in name or name.startswith("."):
            raise ConfigError(f"identity {name!r}: expected a plain name (a service, operator, router)")
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    now = datetime.datetime.now(datetime.timezone.utc)
    start, end = now - datetime.timedelta(minutes=5), now + datetime.timedelta(days=VALID_DAYS)
    ca_key = ec.generate_private_key(ec.SECP256R1())
    ca_name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "hrc cell CA")])
    ca = (x509.CertificateBuilder().subject_name(ca_name).issuer_name(ca_name).public_key(ca_key.public_key())
          .serial_number(x509.random_serial_number()).not_valid_before(start).not_valid_after(end)
          .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
          .add_extension(x509.KeyUsage(digital_signature=True, key_cert_sign=True, crl_sign=True,
                                       content_commitment=False, key_encipherment=False, data_encipherment=False,
                                       key_agreement=False, encipher_only=False, decipher_only=False), critical=True)
          .sign(ca_key, hashes.SHA256()))
    (directory / "ca.pem").write_bytes(ca.public_bytes(serialization.Encoding.PEM))
    _write_key(directory / "ca-key.pem", ca_key)
    for name in identities:
        key = ec.generate_private_key(ec.SECP256R1())
        cert = (x509.CertificateBuilder().subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)]))
                .issuer_name(ca_name).public_key(key.public_key()).serial_number(x509.random_serial_number())
                .not_valid_before(start).not_valid_after(end)
                .add_extension(san, critical=False)
                .add_extension(x509.ExtendedKeyUsage([ExtendedKeyUsageOID.SERVER_AUTH,
                                                      ExtendedKeyUsageOID.CLIENT_AUTH]), critical=False)
                .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
                .sign(ca_key, hashes.SHA256()))
        (directory / f"{name}.pem").write_bytes(cert.public_bytes(serialization.Encoding.PEM))
        _write_key(directory / f"{name}-key.pem", key)
    return directory
