"""The installed software's version, recorded in every result (``software_version``)."""
from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

try:
    SOFTWARE_VERSION = version("tunnel-contact")
except PackageNotFoundError:  # pragma: no cover - source tree without install
    SOFTWARE_VERSION = "0+unknown"
