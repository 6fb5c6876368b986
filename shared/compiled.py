"""Where numba keeps the cell's compiled kernels: one directory per version of the code (``NUMBA_CACHE_DIR``).

numba's own cache (``cache=True``) is invalidated when the file of the cached function changes, not when a
function it calls, or a constant it froze, in another file does: a kernel of the scaling layer that calls the SSM
kernel of ``shared/safety/ssm.py`` kept the old SSM limit after that file changed (docs/measurements.md, session
78). For a safety layer that is a hazard, not a nuisance: a pulled update could run with the limit of the code
before. So the cache directory is keyed by a digest of every source file of ``shared`` (the only package that
compiles): a change anywhere starts from an empty cache, which the services' warm-up fills (tens of seconds of
compiling, once), and code never runs against another version's compiled kernels. The root is
``HRC_NUMBA_CACHE`` where set, else ``.numba-cache`` beside the package (the system's temporary folder where that
cannot be written); the oldest versions are removed, the newest KEPT kept (another checkout's processes may still
run theirs).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import sys
import tempfile
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
KEPT = 4       # versions of the compiled kernels kept under the root


def code_digest(package: Path = PACKAGE) -> str:
    """16 hex digits of a digest of every ``*.py`` under `package` (their paths and contents): 2-3 ms."""
    digest = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        digest.update(path.relative_to(package).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def cache_directory(root: Path | None = None, package: Path = PACKAGE) -> Path:
    """The directory this code's compiled kernels go in: root / code_digest()."""
    root = root or Path(os.environ.get("HRC_NUMBA_CACHE") or package.parent / ".numba-cache")
    return root / code_digest(package)


def prune(root: Path, keep: int = KEPT) -> None:
    """Remove all but the `keep` most recently used versions under root (errors ignored: another process may be
    removing them too, or the root may not be ours to write)."""
    try:
        versions = sorted((p for p in root.iterdir() if p.is_dir()), key=lambda p: p.stat().st_mtime, reverse=True)
    except OSError:
        return
    for old in versions[keep:]:
        shutil.rmtree(old, ignore_errors=True)


def use_versioned_cache() -> Path:
    """Point numba at this code's own cache directory (before any kernel is compiled or loaded); returns it. Where
    the root cannot be written (an installed, read-only tree), the same version's directory under the system's
    temporary folder."""
    directory = cache_directory()
    try:
        directory.mkdir(parents=True, exist_ok=True)
        os.utime(directory)                      # in use: the last to be pruned
    except OSError:
        directory = cache_directory(Path(tempfile.gettempdir()) / "hrc-numba-cache")
        directory.mkdir(parents=True, exist_ok=True)
    os.environ["NUMBA_CACHE_DIR"] = str(directory)
    prune(directory.parent)
    if "numba" in sys.modules:                   # imported before the package: its configuration is read again
        from numba.core import config

        config.reload_config()
    return directory
