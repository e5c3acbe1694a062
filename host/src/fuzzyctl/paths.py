"""Where the shared definitions (``common/``) and the firmware binary are.

``common/`` holds what the firmware and the host both read: the FIS definition
(``common/fis/fis.toml``), the config schema and defaults (``common/config/``) and the comparison
tolerances (``common/compare/tolerances.toml``). It is found, in order:

1. the environment variable ``FUZZYSTEREO_COMMON``;
2. ``<repo>/common`` relative to this package's source in a repository checkout
   (``<repo>/host/src/fuzzyctl/paths.py``).
"""

from __future__ import annotations

import os
from pathlib import Path

from .errors import FatalError

ENV_COMMON = "FUZZYSTEREO_COMMON"
ENV_BIN = "FUZZYSTEREO_BIN"
ENV_DATASETS = "FUZZYSTEREO_DATASETS"

#: <repo>/host/src/fuzzyctl/paths.py -> parents[3] == <repo>
_REPO_FROM_SOURCE = Path(__file__).resolve().parents[3]


def repo_root() -> Path | None:
    """The repository checkout this package runs from, or None when installed elsewhere."""
    if (_REPO_FROM_SOURCE / "common").is_dir() and (_REPO_FROM_SOURCE / "host").is_dir():
        return _REPO_FROM_SOURCE
    return None


def common_dir() -> Path:
    """The ``common/`` directory; FatalError when it cannot be found."""
    env = os.environ.get(ENV_COMMON)
    if env:
        path = Path(env)
        if not path.is_dir():
            raise FatalError(f"{ENV_COMMON}={env} is not a directory")
        return path
    root = repo_root()
    if root is None:
        raise FatalError(
            "cannot find the shared definitions (common/): set "
            f"{ENV_COMMON} to the common/ folder of a fuzzystereo checkout"
        )
    return root / "common"


def common_file(*parts: str) -> Path:
    """A file under ``common/``; FatalError naming it when it is missing."""
    path = common_dir().joinpath(*parts)
    if not path.is_file():
        raise FatalError(f"missing shared definition file {path}")
    return path


def fis_file() -> Path:
    return common_file("fis", "fis.toml")


def schema_file() -> Path:
    return common_file("config", "schema.toml")


def default_config_file() -> Path:
    return common_file("config", "default.toml")


def tolerances_file() -> Path:
    return common_file("compare", "tolerances.toml")


def default_firmware_binary() -> Path:
    """``$FUZZYSTEREO_BIN``, else ``<repo>/build/default/fuzzystereo`` (not checked to exist)."""
    env = os.environ.get(ENV_BIN)
    if env:
        return Path(env)
    root = repo_root() or Path.cwd()
    return root / "build" / "default" / "fuzzystereo"


def default_datasets_dir() -> Path:
    """``$FUZZYSTEREO_DATASETS``, else ``<repo>/../shared/datasets`` (not checked to exist)."""
    env = os.environ.get(ENV_DATASETS)
    if env:
        return Path(env)
    root = repo_root() or Path.cwd()
    return root.parent / "shared" / "datasets"
