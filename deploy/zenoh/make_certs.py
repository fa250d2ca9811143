#!/usr/bin/env python3
"""Make a test CA and the leaf certificates of a railtwin deployment with ``openssl``.

    python deploy/zenoh/make_certs.py OUT_DIR [--site km12] [--days 365]

writes, into ``OUT_DIR`` (created if missing):

- ``ca.pem`` / ``ca.key``: a self-signed certificate authority (every peer trusts it);
- ``<name>.pem`` / ``<name>.key`` for each peer, signed by that CA, with the common name
  (CN) that the access-control policies match and
  ``subjectAltName = DNS:localhost, IP:127.0.0.1`` (the TLS endpoints are
  ``tls/localhost:PORT``):

  | file            | CN            | who                                            |
  |-----------------|---------------|------------------------------------------------|
  | ``twin``        | ``twin``      | ``railtwin serve``                             |
  | ``site-<site>`` | ``site-<site>`` | the site's wayside publisher               |
  | ``consumer``    | ``consumer``  | a client that reads the twin's outputs        |
  | ``intruder``    | ``intruder``  | same CA, another CN (for the tests)            |
  | ``router``      | ``router``    | ``railtwin router`` (a region's router)        |
  | ``fleet``       | ``fleet``     | ``railtwin fleet serve`` (the fleet service)   |

Nothing is downloaded; only the ``openssl`` command is needed. This is for tests and
for trying the setup: a real site keeps the CA key offline and issues one certificate
per device (see ``deploy/zenoh/README.md``).
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

SAN = "subjectAltName=DNS:localhost,IP:127.0.0.1"


def peer_names(site: str) -> list[str]:
    """The common names of the leaf certificates made for ``site``."""
    return ["twin", f"site-{site}", "consumer", "intruder", "router", "fleet"]


def _openssl(*args: str) -> None:
    openssl = shutil.which("openssl")
    if openssl is None:
        raise RuntimeError("openssl is not installed")
    done = subprocess.run([openssl, *args], capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"openssl {args[0]} failed: {done.stderr.strip()}")


def make_ca(out: Path, days: int = 365) -> tuple[Path, Path]:
    """``out/ca.pem`` and ``out/ca.key``: a self-signed CA (EC P-256)."""
    cert, key = out / "ca.pem", out / "ca.key"
    _openssl(
        "req",
        "-x509",
        "-newkey",
        "ec",
        "-pkeyopt",
        "ec_paramgen_curve:prime256v1",
        "-nodes",
        "-keyout",
        str(key),
        "-out",
        str(cert),
        "-days",
        str(days),
        "-subj",
        "/CN=railtwin-test-ca",
        "-addext",
        "basicConstraints=critical,CA:TRUE",
        "-addext",
        "keyUsage=critical,keyCertSign,cRLSign",
    )
    return cert, key


def make_leaf(out: Path, name: str, ca: tuple[Path, Path], days: int = 365) -> tuple[Path, Path]:
    """``out/<name>.pem`` and ``out/<name>.key``: CN ``name``, signed by ``ca``, for TLS
    servers and clients alike (a Zenoh peer both listens and connects)."""
    cert, key, csr = out / f"{name}.pem", out / f"{name}.key", out / f"{name}.csr"
    _openssl(
        "req",
        "-new",
        "-newkey",
        "ec",
        "-pkeyopt",
        "ec_paramgen_curve:prime256v1",
        "-nodes",
        "-keyout",
        str(key),
        "-out",
        str(csr),
        "-subj",
        f"/CN={name}",
    )
    with tempfile.NamedTemporaryFile("w", suffix=".ext", dir=out, delete=False) as ext:
        ext.write(
            f"{SAN}\nbasicConstraints=CA:FALSE\n"
            "keyUsage=critical,digitalSignature,keyEncipherment\n"
            "extendedKeyUsage=serverAuth,clientAuth\n"
        )
    try:
        _openssl(
            "x509",
            "-req",
            "-in",
            str(csr),
            "-CA",
            str(ca[0]),
            "-CAkey",
            str(ca[1]),
            "-CAcreateserial",
            "-out",
            str(cert),
            "-days",
            str(days),
            "-extfile",
            ext.name,
        )
    finally:
        Path(ext.name).unlink()
        csr.unlink()
    return cert, key


def make_certs(out: Path, site: str = "km12", days: int = 365) -> dict[str, tuple[Path, Path]]:
    """A CA and a leaf per name of ``peer_names(site)``; returns ``{name: (cert, key)}``
    (the CA under ``"ca"``)."""
    out.mkdir(parents=True, exist_ok=True)
    ca = make_ca(out, days)
    made = {"ca": ca}
    for name in peer_names(site):
        made[name] = make_leaf(out, name, ca, days)
    for _, key in made.values():
        key.chmod(0o600)
    return made


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("out", type=Path, help="directory to write the certificates into")
    p.add_argument("--site", default="km12", help="site id: the publisher's CN is site-<site>")
    p.add_argument("--days", type=int, default=365, help="validity (default 365 days)")
    args = p.parse_args(argv)
    try:
        made = make_certs(args.out, args.site, args.days)
    except RuntimeError as exc:
        print(f"make_certs: {exc}", file=sys.stderr)
        return 1
    for name, (cert, _) in made.items():
        print(f"{name:<16} {cert}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
