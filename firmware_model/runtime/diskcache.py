"""Content-keyed pickles in the user's cache folder (:func:`cache_dir`, ``$FWEMU_CACHE_DIR``).

One job: read and write a cached object by a path whose name is the content key of everything the object was
computed from (the caller's responsibility: :func:`firmware_model.firmware.assemble.build_key` for assembled builds,
:func:`firmware_model.vectors.flight_cases.flight_cases_key` for the flight vector cases,
:func:`firmware_model.vectors.generate` for build constants; :func:`source_digest` is the part that covers this
package's code; :func:`memo` is the load-or-compute-and-store the last two use). Writes are atomic (a temporary file in
the same folder, then ``os.replace``): concurrent writers of one key write the same bytes and
readers never see a partial file; a failed write (read-only or full disk) only costs the cache, and an unreadable
or foreign file reads as a miss (it is recomputed and overwritten).
"""

from __future__ import annotations

import functools
import hashlib
import os
import pickle
import sys
from pathlib import Path
from typing import Any, Callable

from isa.codecache import write_atomic


def cache_dir() -> Path | None:
    """Where results are cached on disk (assembled builds, compiled block code, flight cases, build constants):
    ``$FWEMU_CACHE_DIR`` if set (empty or ``off``: no disk cache), else ``$XDG_CACHE_HOME/fwemu`` or
    ``~/.cache/fwemu``."""
    env = os.environ.get("FWEMU_CACHE_DIR")
    if env is not None:
        return None if env.strip() in ("", "off", "0") else Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "fwemu"


def load(path: Path, accept: Callable[[Any], bool]) -> Any | None:
    """The object pickled at ``path`` if ``accept(obj)``, else None (also when the file is missing or damaged)."""
    try:
        with open(path, "rb") as fh:
            obj = pickle.load(fh)  # our own cache file, content-keyed, in the user's cache dir
    except Exception:  # noqa: BLE001 - missing, truncated or foreign: a miss
        return None
    return obj if accept(obj) else None


def memo(sub: str, key: Callable[[], str], accept: Callable[[Any], bool], compute: Callable[[], Any]) -> Any:
    """``compute()``, kept in the cache folder (:func:`cache_dir`) as ``<sub>/<key()>.pickle``:
    loaded from there when present and ``accept``-ed, else computed and stored. ``key`` is called only when the
    cache is on (``$FWEMU_CACHE_DIR`` not ``off``)."""
    folder = cache_dir()
    path = folder / sub / f"{key()}.pickle" if folder is not None else None
    if path is not None:
        obj = load(path, accept)
        if obj is not None:
            return obj
    obj = compute()
    if path is not None:
        store(path, obj)
    return obj


def store(path: Path, obj: Any) -> None:
    """Pickle ``obj`` to ``path`` atomically (:func:`isa.codecache.write_atomic`); failures (read-only disk, ...)
    only cost the cache."""
    write_atomic(path, lambda fh: pickle.dump(obj, fh, protocol=pickle.HIGHEST_PROTOCOL), (pickle.PicklingError,))


@functools.lru_cache(maxsize=1)
def source_digest() -> str:
    """SHA-256 over every source file of ``firmware_model`` and its data files (motors, drag), with the Python
    version and the versions of the libraries the designs, fits and simulations run on: a key part for results
    computed by this package's code, so that any change to the code invalidates them."""
    from importlib import metadata

    root = Path(__file__).resolve().parents[1]
    h = hashlib.sha256()
    files = sorted(root.rglob("*.py")) + sorted(p for p in (root / "flights" / "data").rglob("*") if p.is_file())
    for path in files:
        h.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes() + b"\0")
    versions: list[tuple[str, str | None]] = []
    for dist in ("numpy", "scipy", "numba", "rocketpy"):
        try:
            versions.append((dist, metadata.version(dist)))
        except metadata.PackageNotFoundError:
            versions.append((dist, None))
    h.update(repr((sys.version_info[:3], versions)).encode())
    return h.hexdigest()
