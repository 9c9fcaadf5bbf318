"""Atomic file writing: an interrupted write never leaves a file under its final name."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def _temp_beside(path: Path) -> Path:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    return Path(tmp)


def atomic_to_netcdf(ds, path, **kwargs) -> None:
    """Write an xarray Dataset to ``path`` through a temp file in the same directory, then rename."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _temp_beside(path)
    try:
        ds.to_netcdf(tmp, engine="netcdf4", **kwargs)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def atomic_write_text(text: str, path) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _temp_beside(path)
    try:
        tmp.write_text(text)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def safe_load_unique(stream):
    """yaml.safe_load that rejects a mapping with a repeated key (PyYAML silently keeps the last one, so a
    parameter given twice would change a run without a word). Raises yaml.YAMLError naming the keys."""
    import yaml

    class _UniqueKeys(yaml.SafeLoader):
        pass

    def mapping(loader, node, deep=False):
        keys = [loader.construct_object(k, deep=deep) for k, _ in node.value]
        dup = sorted({str(k) for k in keys if keys.count(k) > 1})
        if dup:
            raise yaml.constructor.ConstructorError(None, None, f"duplicate keys {dup}", node.start_mark)
        return yaml.SafeLoader.construct_mapping(loader, node, deep)

    _UniqueKeys.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, mapping)
    return yaml.load(stream, Loader=_UniqueKeys)


#: the lock file of a run directory (held while ``vesicle run`` writes it)
RUN_LOCK = "run.lock"


def hold_run_lock(outdir):
    """Take an exclusive lock on ``outdir`` for this process, or raise ConfigError when another process holds it: two
    runs writing one directory interleave their frames and checkpoints (seen when a chain of runs was started twice).
    Returns the open lock file; closing it (or the process ending, however it ends) releases the lock. The file
    stays behind and is harmless. Where the platform has no fcntl (Windows) nothing is locked."""
    from .errors import ConfigError

    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        return open(os.devnull, "w")
    f = open(Path(outdir) / RUN_LOCK, "a+")
    try:
        fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        f.seek(0)
        holder = f.read().strip() or "?"
        f.close()
        raise ConfigError(f"{outdir} is being written by another vesicle run (pid {holder}); wait for it to end, or "
                          "stop it, before running into the same directory") from None
    f.seek(0)
    f.truncate()
    f.write(str(os.getpid()))
    f.flush()
    return f
